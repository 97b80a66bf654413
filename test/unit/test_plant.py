"""The PyBullet plant is exactly the model its parameters describe (THEORY.md §1).

One physics step of Bullet is semi-implicit Euler on B(q) q̈ + C q̇ + F q̇ + g(q) = τ:

    v₁ = v₀ + dt B(q₀)⁻¹ (τ − n(q₀, v₀)),    q₁ = q₀ + dt v₁,    n = C v₀ + F v₀ + g(q₀)

so a step computed with Pinocchio on the same URDF (same friction F and payload, given to
the model through ModelPerturbation) agrees to rounding: 1e-12 on planar_2dof and iiwa
(observed ~1e-14). On the panda the fingers are not rigidly locked but held by stiff
position servos (plant.LOCK_FORCE), which Bullet solves as constraints together with the
arm, so the agreement is only ~1e-8 rad/s: 1e-6 there.
"""

from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest

from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot
from sim_bridge.plant import Plant

FRICTION = 0.7  # [N·m·s/rad]
PAYLOAD = 2.0  # [kg]


@pytest.fixture
def make_plant():
    plants = []

    def make(robot: str = "planar_2dof", **kwargs) -> Plant:
        spec = kwargs.pop("spec", None) or resolve_robot(robot)
        joints = kwargs.pop("joints", spec.default_joints)
        plant = Plant(spec, joints, **kwargs)
        plants.append(plant)
        return plant

    yield make
    for plant in plants:
        plant.close()


@pytest.fixture(scope="module")
def perturbed_models() -> dict[str, RobotModel]:
    """Controller models with the plant's friction and payload."""
    pert = ModelPerturbation(friction=FRICTION, payload_mass=PAYLOAD)
    return {
        name: RobotModel(resolve_robot(name), perturbation=pert)
        for name in ("planar_2dof", "iiwa", "panda")
    }


def euler_step(model: RobotModel, q0, v0, tau, dt):
    """Semi-implicit Euler step of the model (the reference for Bullet's integrator)."""
    v1 = v0 + dt * np.linalg.solve(model.inertia(q0), tau - model.nonlinear_effects(q0, v0))
    return q0 + dt * v1, v1


def initial_configuration(model: RobotModel, seed: int) -> np.ndarray:
    """A random configuration well inside the joint limits."""
    lo, hi = model.position_limits
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return np.random.default_rng(seed).uniform(mid - 0.6 * half, mid + 0.6 * half)


@pytest.mark.parametrize(
    ("name", "tol"), [("planar_2dof", 1e-12), ("iiwa", 1e-12), ("panda", 1e-6)]
)
def test_one_step_is_semi_implicit_euler_of_the_model(make_plant, perturbed_models, name, tol):
    model = perturbed_models[name]
    q_init = initial_configuration(model, seed=1)
    plant = make_plant(
        name,
        friction=FRICTION,
        payload_mass=PAYLOAD,
        initial_positions=q_init,
        locked_positions=model.locked_positions,
    )
    assert plant.warnings == []
    rng = np.random.default_rng(2)
    limits = model.effort_limits
    # torques around gravity compensation keep every link's acceleration moderate
    plant.step(model.gravity(q_init) + 0.05 * rng.uniform(-1, 1, model.n) * limits, 20)
    for _ in range(3):
        s0 = plant.state()
        # moving: the Coriolis and friction terms (F q̇ ≥ 3.5e-3 N·m here) are in play
        assert np.max(np.abs(s0.dq)) > 5e-3
        tau = model.gravity(s0.q) + 0.05 * rng.uniform(-1, 1, model.n) * limits
        plant.step(tau)
        s1 = plant.state()
        q1, v1 = euler_step(model, s0.q, s0.dq, tau, plant.dt)
        assert np.max(np.abs(s1.dq - v1)) <= tol
        assert np.max(np.abs(s1.q - q1)) <= tol
        np.testing.assert_array_equal(s1.effort, tau)
        # not vacuous: the step moved the state by much more than the tolerance
        assert np.max(np.abs(s1.dq - s0.dq)) > 1e3 * tol


def test_friction_and_payload_matter_in_the_step(make_plant, perturbed_models):
    """The agreement above is sensitive: a nominal model (no F, no payload) misses by far."""
    model = perturbed_models["planar_2dof"]
    nominal = RobotModel(resolve_robot("planar_2dof"))
    plant = make_plant(friction=FRICTION, payload_mass=PAYLOAD, initial_positions=[0.3, -0.2])
    plant.step(np.array([1500.0, 600.0]), substeps=20)
    s0 = plant.state()
    tau = np.array([500.0, 100.0])
    plant.step(tau)
    s1 = plant.state()
    _, v_model = euler_step(model, s0.q, s0.dq, tau, plant.dt)
    _, v_nominal = euler_step(nominal, s0.q, s0.dq, tau, plant.dt)
    assert np.max(np.abs(s1.dq - v_model)) <= 1e-12
    assert np.max(np.abs(s1.dq - v_nominal)) > 1e-4


def test_iiwa_urdf_joint_damping_is_not_applied(make_plant):
    """The iiwa URDF declares <dynamics damping="0.5"/> on every joint; with F = 0 the
    plant must follow the undamped model, and the damping would be clearly visible."""
    model = RobotModel(resolve_robot("iiwa"))
    q_init = initial_configuration(model, seed=3)
    plant = make_plant("iiwa", initial_positions=q_init)
    assert np.all(plant.friction == 0)
    # get every joint moving (~1 rad/s) with a short push on top of gravity compensation
    plant.step(model.gravity(q_init) + 0.02 * model.effort_limits, substeps=5)
    s0 = plant.state()
    tau = model.gravity(s0.q)
    plant.step(tau)
    s1 = plant.state()
    q1, v1 = euler_step(model, s0.q, s0.dq, tau, plant.dt)
    np.testing.assert_allclose(s1.dq, v1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s1.q, q1, rtol=0, atol=1e-12)
    # what 0.5 N·m·s/rad (or Bullet's default 0.04 link damping) would have changed
    damping_effect = plant.dt * np.linalg.solve(model.inertia(s0.q), 0.5 * s0.dq)
    assert np.max(np.abs(damping_effect)) > 1e-6


def test_torque_is_clamped_to_effort_limits(make_plant):
    plant = make_plant(initial_positions=[0.3, -0.2])
    limits = plant.effort_limits
    np.testing.assert_array_equal(limits, [2000.0, 1000.0])
    plant.step(np.array([1e6, -1e6]), substeps=3)
    saturated = plant.state()
    np.testing.assert_array_equal(saturated.effort, [2000.0, -1000.0])
    plant.reset()
    plant.step(np.array([2000.0, -1000.0]), substeps=3)
    exact = plant.state()
    np.testing.assert_array_equal(saturated.q, exact.q)
    np.testing.assert_array_equal(saturated.dq, exact.dq)
    # and below the limit the command is applied as is
    plant.reset()
    plant.step(np.array([1999.0, -999.0]), substeps=3)
    assert not np.array_equal(plant.state().dq, exact.dq)


@pytest.mark.parametrize("friction", [0.0, FRICTION])
def test_substeps_are_a_zero_order_hold(make_plant, friction):
    """step(τ, 5) is five step(τ, 1): the torque is held, friction evaluated each sub-step."""
    tau = np.array([300.0, -100.0])
    plant = make_plant(initial_positions=[0.3, -0.2], friction=friction)
    plant.step(tau, substeps=5)
    held = plant.state()
    plant.reset()
    for _ in range(5):
        plant.step(tau, substeps=1)
    stepped = plant.state()
    np.testing.assert_array_equal(held.q, stepped.q)
    np.testing.assert_array_equal(held.dq, stepped.dq)
    np.testing.assert_array_equal(held.effort, tau)
    assert np.max(np.abs(held.q - [0.3, -0.2])) > 0  # it did move


def test_brake_stops_and_holds_the_arm_under_gravity(make_plant):
    plant = make_plant(initial_positions=[0.3, -0.2])
    model = RobotModel(resolve_robot("planar_2dof"))
    for _ in range(100):  # 0.1 s of free fall
        plant.step(np.zeros(2))
    assert np.max(np.abs(plant.state().dq)) > 0.5
    plant.brake(substeps=500)  # 0.5 s at 1 kHz
    stopped = plant.state()
    assert np.max(np.abs(stopped.dq)) < 1e-3
    assert np.all(np.abs(stopped.effort) <= plant.effort_limits)
    # the brakes carry gravity, so the reported effort is far from zero
    assert np.max(np.abs(stopped.effort)) > 100.0
    plant.brake(substeps=200)
    held = plant.state()
    assert np.max(np.abs(held.q - stopped.q)) < 1e-3
    assert np.all(np.abs(held.effort) <= plant.effort_limits)
    # the brakes are released afterwards: the next torque step is free motion again
    plant.step(np.zeros(2))
    q1, v1 = euler_step(model, held.q, held.dq, np.zeros(2), plant.dt)
    np.testing.assert_allclose(plant.state().dq, v1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(plant.state().q, q1, rtol=0, atol=1e-12)


def test_reset_returns_to_rest(make_plant):
    plant = make_plant(initial_positions=[0.3, -0.2])
    first = plant.state()
    np.testing.assert_array_equal(first.q, [0.3, -0.2])
    np.testing.assert_array_equal(first.dq, [0.0, 0.0])
    np.testing.assert_array_equal(first.effort, [0.0, 0.0])
    plant.step(np.array([500.0, 200.0]), substeps=50)
    assert np.max(np.abs(plant.state().dq)) > 0.1
    plant.reset()
    state = plant.state()
    np.testing.assert_array_equal(state.q, [0.3, -0.2])
    np.testing.assert_array_equal(state.dq, [0.0, 0.0])
    np.testing.assert_array_equal(state.effort, [0.0, 0.0])
    plant.reset([1.0, -0.5])
    np.testing.assert_array_equal(plant.state().q, [1.0, -0.5])
    np.testing.assert_array_equal(plant.state().dq, [0.0, 0.0])
    # a reset gives a reproducible run
    plant.reset()
    plant.step(np.array([500.0, 200.0]), substeps=10)
    a = plant.state()
    plant.reset()
    plant.step(np.array([500.0, 200.0]), substeps=10)
    np.testing.assert_array_equal(plant.state().q, a.q)


def test_locked_fingers_stay_put(make_plant):
    """Panda fingers are held at the locked positions while the arm moves."""
    plant = make_plant("panda", locked_positions={"panda_finger_joint1": 0.02})
    fingers = {
        pb.getJointInfo(plant.body, j, plant.client)[1].decode(): j
        for j in range(pb.getNumJoints(plant.body, plant.client))
    }
    plant.step(np.full(7, 5.0), substeps=200)
    q1 = pb.getJointState(plant.body, fingers["panda_finger_joint1"], plant.client)[0]
    q2 = pb.getJointState(plant.body, fingers["panda_finger_joint2"], plant.client)[0]
    assert q1 == pytest.approx(0.02, abs=1e-4)
    assert q2 == pytest.approx(0.0, abs=1e-4)
    assert np.max(np.abs(plant.state().q)) > 0.01


# -- inertia checks ------------------------------------------------------------------------

BAD_INERTIA_URDF = """<?xml version="1.0"?>
<robot name="bad_arm">
  <link name="base">
    <inertial><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="good_link"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="5"/>
  </joint>
  <link name="good_link">
    <inertial><origin xyz="0.5 0 0"/><mass value="2"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.2"/></inertial>
  </link>
  <joint name="j2" type="revolute">
    <parent link="good_link"/><child link="bad_link"/><origin xyz="1 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="5"/>
  </joint>
  <link name="bad_link">
    <inertial><origin xyz="0.5 0 0"/><mass value="2"/>
      <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"/></inertial>
  </link>
</robot>
"""


def test_unphysical_inertia_is_reported(make_plant, tmp_path):
    path = tmp_path / "bad_arm.urdf"
    path.write_text(BAD_INERTIA_URDF)
    plant = make_plant(spec=resolve_robot(urdf_path=str(path)))
    assert len(plant.warnings) == 1
    assert "'bad_link'" in plant.warnings[0]
    assert "not physical" in plant.warnings[0]
    assert "good_link" not in " ".join(plant.warnings)


@pytest.mark.parametrize("name", ["planar_2dof", "iiwa", "panda"])
@pytest.mark.parametrize("payload", [0.0, PAYLOAD])
def test_builtin_robots_have_no_inertia_warnings(make_plant, name, payload):
    plant = make_plant(name, payload_mass=payload)
    assert plant.warnings == []
    link = next(
        j
        for j in range(pb.getNumJoints(plant.body, plant.client))
        if pb.getJointInfo(plant.body, j, plant.client)[1].decode() == plant.joint_names[-1]
    )
    info = pb.getDynamicsInfo(plant.body, link, plant.client)
    before = list(info[2])
    plant.set_payload(5.0)
    after = pb.getDynamicsInfo(plant.body, link, plant.client)
    # the payload changes the mass only; the rotational inertia is preserved
    assert after[0] == pytest.approx(info[0] - payload + 5.0, abs=1e-12)
    np.testing.assert_array_equal(after[2], before)


# -- validation ----------------------------------------------------------------------------


@pytest.mark.parametrize("mass", [-0.1, math.nan, math.inf])
def test_set_payload_rejects_invalid(make_plant, mass):
    plant = make_plant()
    with pytest.raises(ValueError, match="payload_mass"):
        plant.set_payload(mass)
    assert plant.payload_mass == 0.0


@pytest.mark.parametrize("friction", [-0.1, math.nan, math.inf, [0.1, 0.2, 0.3], [0.1, -0.2]])
def test_set_friction_rejects_invalid(make_plant, friction):
    plant = make_plant(friction=0.3)
    with pytest.raises(ValueError, match="viscous_friction"):
        plant.set_friction(friction)
    np.testing.assert_array_equal(plant.friction, [0.3, 0.3])


def test_set_friction_accepts_per_joint_values(make_plant):
    plant = make_plant()
    plant.set_friction([0.1, 0.2])
    np.testing.assert_array_equal(plant.friction, [0.1, 0.2])


@pytest.mark.parametrize("rate", [0.0, -100.0, math.nan, math.inf])
def test_invalid_physics_rate(rate):
    with pytest.raises(ValueError, match="physics_rate"):
        Plant(resolve_robot("planar_2dof"), ("joint1", "joint2"), physics_rate=rate)


def test_unknown_joint(make_plant):
    with pytest.raises(ValueError, match=r"unknown joints \['joint3'\]"):
        make_plant(joints=("joint1", "joint3"))


def test_physics_rate_sets_dt(make_plant):
    plant = make_plant(physics_rate=500.0)
    assert plant.dt == pytest.approx(2e-3)
    model = RobotModel(resolve_robot("planar_2dof"))
    plant.step(np.zeros(2))
    q1, v1 = euler_step(model, np.zeros(2), np.zeros(2), np.zeros(2), 2e-3)
    np.testing.assert_allclose(plant.state().dq, v1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(plant.state().q, q1, rtol=0, atol=1e-12)
