"""The plant's deliberate imperfections, against the model (docs/plant.md).

- Coulomb friction and stiction (velocity motors as friction constraints): a joint whose net
  torque stays below F_s does not move; a sliding joint feels exactly −F_c sign(q̇), so one
  semi-implicit Euler step gives q̈ = B⁻¹(τ − n − F_c sign q̇) to rounding;
- the external wrench w (applied to the robot, w = −h_e) adds Jᵀw with J Pinocchio's
  world-aligned Jacobian of the link frame: with τ = g(q) − Jᵀw the arm at rest stays at rest
  (q̈ after one step ≤ 1e-12 × (1 + ‖B⁻¹Jᵀw‖∞); observed ≤ 1e-15 relative), without it
  q̈ = B⁻¹Jᵀw to the same tolerance;
- with every imperfection off, explicitly or switched on and off again, a run is
  bit-identical to the plain plant's.
"""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from sim_bridge.plant import Plant
from sim_bridge.torque_plant import STICTION_SPEED, coulomb_bounds
from sim_bridge.wrench import WrenchSchedule

FC = np.array([50.0, 30.0])  # [N·m] Coulomb
FS = np.array([80.0, 60.0])  # [N·m] stiction
Q0 = np.array([0.3, -0.5])
REL = 1e-12  # one step against the model, relative to the acceleration's scale


@pytest.fixture
def make_plant():
    plants = []

    def make(robot: str = "planar_2dof", **kwargs) -> Plant:
        spec = resolve_robot(robot)
        plant = Plant(spec, spec.default_joints, **kwargs)
        plants.append(plant)
        return plant

    yield make
    for plant in plants:
        plant.close()


@pytest.fixture(scope="module")
def models() -> dict[str, RobotModel]:
    return {name: RobotModel(resolve_robot(name)) for name in ("planar_2dof", "iiwa")}


def acceleration(plant: Plant, tau: np.ndarray, t: float = 0.0) -> np.ndarray:
    """q̈ over one physics step from the current state: (v₁ − v₀)/dt."""
    v0 = plant.state().dq
    plant.step(tau, 1, t)
    return (plant.state().dq - v0) / plant.dt


# -- Coulomb friction and stiction --------------------------------------------------------
def test_below_stiction_the_arm_does_not_move(make_plant, models):
    """Net torque (gravity compensated) above F_c but below F_s on both joints, for 1 s:
    stuck, |q − q₀| ≤ 1e-8 rad (observed ~1e-13)."""
    model = models["planar_2dof"]
    plant = make_plant(initial_positions=Q0)
    plant.set_coulomb_friction(FC, FS)
    net = np.array([70.0, -50.0])
    for _ in range(1000):
        plant.step(model.gravity(plant.state().q) + net, 1)
    state = plant.state()
    assert np.max(np.abs(state.q - Q0)) <= 1e-8
    assert np.max(np.abs(state.dq)) <= 1e-8


def test_without_stiction_the_same_torque_slides(make_plant, models):
    """The same net torque with F_s = F_c: above the bound, the arm moves."""
    model = models["planar_2dof"]
    plant = make_plant(initial_positions=Q0)
    plant.set_coulomb_friction(FC)
    for _ in range(100):
        plant.step(model.gravity(plant.state().q) + np.array([70.0, -50.0]), 1)
    assert np.all(np.abs(plant.state().dq) > STICTION_SPEED)


def test_sliding_friction_is_coulomb_exactly(make_plant, models):
    """From rest, τ = g + B a + F sign(a) gives q̈ = a (F = F_s at rest); once sliding
    (|q̇| above STICTION_SPEED) the next step is the Euler step of the model with −F_c sign q̇."""
    model = models["planar_2dof"]
    plant = make_plant(initial_positions=Q0)
    plant.set_coulomb_friction(FC, FS)
    a = np.array([0.7, -1.2])
    tau = model.gravity(Q0) + model.inertia(Q0) @ a + FS * np.sign(a)
    ddq = acceleration(plant, tau)
    np.testing.assert_allclose(ddq, a, rtol=0, atol=REL * (1 + np.abs(a).max()))
    for _ in range(5):
        plant.step(tau, 1)
    s = plant.state()
    assert np.all(np.abs(s.dq) > STICTION_SPEED)
    expected = np.linalg.solve(
        model.inertia(s.q), tau - model.nonlinear_effects(s.q, s.dq) - FC * np.sign(s.dq)
    )
    ddq = acceleration(plant, tau)
    np.testing.assert_allclose(ddq, expected, rtol=0, atol=REL * (1 + np.abs(expected).max()))


def test_after_braking_the_motors_are_friction_again(make_plant, models):
    """Plant.brake hands the velocity motors back to the friction: below F_c the arm stays,
    above it q̈ = (τ − g − F_c sign a)/B = a."""
    model = models["planar_2dof"]
    plant = make_plant(initial_positions=Q0)
    plant.set_coulomb_friction(FC)
    plant.brake(50)
    q = plant.state().q
    plant.reset(q)
    for _ in range(200):
        plant.step(model.gravity(plant.state().q) + np.array([40.0, -20.0]), 1)
    assert np.max(np.abs(plant.state().q - q)) <= 1e-8
    q = plant.state().q
    a = np.array([-0.4, 0.9])
    plant.reset(q)
    tau = model.gravity(q) + model.inertia(q) @ a + FC * np.sign(a)
    np.testing.assert_allclose(acceleration(plant, tau), a, rtol=0, atol=REL * 2)


def test_stiction_below_coulomb_is_refused():
    fc, fs = coulomb_bounds([5.0, 3.0], [0.0, 4.0])
    np.testing.assert_array_equal(fs, [5.0, 4.0])
    with pytest.raises(ValueError, match="'static_friction'"):
        coulomb_bounds([5.0, 3.0], [4.0, 0.0])
    with pytest.raises(ValueError, match="'coulomb_friction'"):
        coulomb_bounds(-1.0, 0.0, 2)


# -- external wrench ----------------------------------------------------------------------
CASES = [
    ("planar_2dof", "link1"),
    ("planar_2dof", ""),  # the last controlled joint's child: link2
    ("iiwa", "lbr_iiwa_link_3"),
    ("iiwa", ""),  # lbr_iiwa_link_7
]


@pytest.mark.parametrize(("robot", "link"), CASES)
def test_wrench_is_jacobian_transpose_of_pinocchio(make_plant, models, robot, link):
    """Three configurations, random wrench (:func:`check_wrench`)."""
    check_wrench(make_plant(robot), models[robot], link, 3)


def check_wrench(plant, model: RobotModel, link: str, configurations: int) -> None:
    """At random configurations, a random wrench on ``link`` (any engine's plant): τ = g − Jᵀw
    holds the arm at rest, τ = g gives q̈ = B⁻¹Jᵀw (J: Pinocchio, LOCAL_WORLD_ALIGNED, at the
    URDF link frame), to REL."""
    name = link or plant.link_names[plant.link_index("")]
    rng = np.random.default_rng(14)
    lo, hi = model.position_limits
    for _ in range(configurations):
        q = rng.uniform(0.6 * lo, 0.6 * hi)
        w = np.r_[rng.normal(0.0, 30.0, 3), rng.normal(0.0, 5.0, 3)]  # [N], [N·m]
        jtw = model.link_jacobian(q, name).T @ w
        expected = np.linalg.solve(model.inertia(q), jtw)
        atol = REL * (1 + np.abs(expected).max())
        plant.hold_wrench(link, w[:3], w[3:])
        plant.reset(q)
        np.testing.assert_allclose(acceleration(plant, model.gravity(q) - jtw), 0, atol=atol)
        plant.reset(q)
        np.testing.assert_allclose(acceleration(plant, model.gravity(q)), expected, atol=atol)


def test_wrench_sign_on_the_horizontal_planar_arm(make_plant, models):
    """w applied to the robot: 100 N downwards at link2's origin (x = 1 m, the elbow) is
    Jᵀw = (−100, 0) N·m (r × f = (0, 100, 0) N·m about the −y axis): it lowers the arm."""
    model = models["planar_2dof"]
    q = np.zeros(2)
    w = np.array([0.0, 0.0, -100.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(model.link_jacobian(q, "link2").T @ w, [-100.0, 0.0], atol=1e-12)
    plant = make_plant()
    plant.hold_wrench("link2", w[:3], w[3:])
    ddq = acceleration(plant, model.gravity(q))
    np.testing.assert_allclose(ddq, np.linalg.solve(model.inertia(q), [-100.0, 0.0]), atol=1e-12)
    assert ddq[0] < 0


def test_zero_wrench_removes_it_and_schedule_follows_simulation_time(make_plant, models):
    """A held zero wrench is no wrench; a step schedule starting at 0.5 s acts at t = 0.5 s
    (its first sub-step), not at 0.4 s, as the same wrench held would."""
    model = models["planar_2dof"]
    g = model.gravity(Q0)
    plant = make_plant(initial_positions=Q0)
    reference = acceleration(plant, g)
    np.testing.assert_allclose(reference, 0.0, atol=1e-12)
    plant.hold_wrench("", [0.0, 0.0, -100.0], [0.0, 10.0, 0.0])
    plant.reset()
    held = acceleration(plant, g)
    assert np.abs(held).max() > 1.0
    plant.hold_wrench("", [0.0] * 3, [0.0] * 3)
    assert not plant.has_wrench
    plant.set_wrench_schedule(
        WrenchSchedule([0.0, 0.0, -100.0], [0.0, 10.0, 0.0], "step", start=0.5)
    )
    plant.reset()
    np.testing.assert_array_equal(acceleration(plant, g, t=0.4), reference)
    plant.reset()
    np.testing.assert_array_equal(acceleration(plant, g, t=0.5), held)
    plant.set_wrench_schedule(WrenchSchedule([0.0] * 3, [0.0] * 3))  # zero: off
    assert not plant.has_wrench


def test_link_jacobian_takes_links_only(models):
    model = models["planar_2dof"]
    with pytest.raises(ValueError, match="no link 'joint2'"):
        model.link_jacobian(np.zeros(2), "joint2")  # a joint frame, not a link
    assert model.link_jacobian(np.zeros(2), "base_link").shape == (6, 2)


def test_bad_wrenches_are_refused(make_plant):
    plant = make_plant()
    with pytest.raises(ValueError, match="no moving link 'base_link'.*link1, link2"):
        plant.hold_wrench("base_link", [1.0, 0.0, 0.0], [0.0] * 3)
    with pytest.raises(ValueError, match="finite"):
        plant.hold_wrench("link2", [np.nan, 0.0, 0.0], [0.0] * 3)
    with pytest.raises(ValueError, match="3 components"):
        plant.hold_wrench("link2", [1.0, 0.0], [0.0] * 3)
    assert not plant.has_wrench  # nothing half-applied


# -- off means off ------------------------------------------------------------------------
def run(plant: Plant, model: RobotModel, steps: int = 300) -> np.ndarray:
    """A PD + gravity run with braking in the middle; the states, row by row."""
    rows = []
    for k in range(steps):
        s = plant.state()
        if 100 <= k < 120:
            plant.brake(2)
        else:
            tau = model.gravity(s.q) + 400.0 * (np.array([0.5, -0.3]) - s.q) - 60.0 * s.dq
            plant.step(tau, 2)
        rows.append(np.r_[s.q, s.dq, s.effort])
    return np.array(rows)


def test_imperfections_off_are_bit_identical(make_plant, models):
    model = models["planar_2dof"]
    plain = run(make_plant(initial_positions=Q0, friction=0.3), model)
    off = make_plant(initial_positions=Q0, friction=0.3)
    off.set_coulomb_friction(0.0, 0.0)
    off.hold_wrench("", [0.0] * 3, [0.0] * 3)
    off.set_wrench_schedule(WrenchSchedule([0.0] * 3, [0.0] * 3, "sinusoid", frequency=2.0))
    np.testing.assert_array_equal(run(off, model), plain)
    again = make_plant(initial_positions=Q0, friction=0.3)
    again.set_coulomb_friction(FC, FS)  # on (solver settings too) and off again
    again.set_coulomb_friction(0.0)
    np.testing.assert_array_equal(run(again, model), plain)
    on = make_plant(initial_positions=Q0, friction=0.3)
    on.set_coulomb_friction(FC)
    assert not np.array_equal(run(on, model), plain)  # the comparison can see friction
