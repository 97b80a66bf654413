"""The MuJoCo plant is the model its parameters describe, as the PyBullet plant is
(sim_bridge/mujoco_plant.py; THEORY.md §1, §2).

Identities, on the corpus (test/corpus.py) and the built-in robots: MuJoCo's mass matrix,
bias forces and inverse dynamics equal Pinocchio's crba, nonLinearEffects and rnea at random
states, to 1e-12 relative to the largest entry on every robot (observed ≤ 5e-15: both compute
the same rigid-body model from the same inertials, the welded joints as Pinocchio's reduced
model, so no robot needs more); xarm6, whose inertias are not physical, is refused. One
physics step is the semi-implicit Euler step of the model with the plant's friction and
payload, to 1e-12 (as on PyBullet, test_plant.py). The closed loop (a plain loop: Pinocchio's
torque each step, ``plant.step``): pure PD rests where g(q_e) = K_P (q_d − q_e) and PD + g(q)
at q_d, to rounding. A blown-up run is a fault, never a silent restart.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from joint_space_control.laws.gains import pd_gains_from_second_order
from joint_space_control.model.description import DescriptionError
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import RobotSpec, resolve_robot
from sim_bridge.mujoco_plant import MujocoPlant, MujocoWorld, PlantFaultError
from sim_bridge.torque_plant import STICTION_SPEED
from test.corpus import BY_NAME, CORPUS, DOUBLE_PENDULUM, PACKAGE_PATHS
from test.unit.test_plant_imperfections import acceleration, check_wrench, run

REL = 1e-12  # relative to the scale of the compared quantity
FRICTION = 0.7  # [N·m·s/rad]
PAYLOAD = 2.0  # [kg]
SETPOINTS = {
    "planar_2dof": np.array([0.5, -0.3]),
    "iiwa": np.array([0.3, 0.5, -0.2, -1.0, 0.2, 0.8, 0.1]),
}


def spec_of(name: str) -> RobotSpec:
    if name in BY_NAME:
        return resolve_robot(urdf_path=str(BY_NAME[name].path), package_paths=PACKAGE_PATHS)
    return resolve_robot(name)


@pytest.fixture
def make_plant():
    plants: list[MujocoPlant] = []

    def make(model: RobotModel, **kwargs) -> MujocoPlant:
        plant = MujocoPlant(
            model.spec,
            model.joint_names,
            locked_positions=model.locked_positions,
            effort_limits=model.effort_limits,
            **kwargs,
        )
        plants.append(plant)
        return plant

    yield make
    for plant in plants:
        plant.close()


@pytest.fixture(scope="module")
def models() -> dict[str, RobotModel]:
    return {name: RobotModel(resolve_robot(name)) for name in ("planar_2dof", "iiwa")}


# -- the same model ------------------------------------------------------------------------
def mujoco_dynamics(plant: MujocoPlant, q, dq, ddq) -> tuple[np.ndarray, ...]:
    """(B, bias, τ = ID(q, q̇, q̈)) of the plant's compiled model, in joint order, computed on
    data of their own (the plant's state is left alone)."""
    m, d = plant.model, mujoco.MjData(plant.model)
    ids = [m.joint(name).id for name in plant.joint_names]
    v = m.jnt_dofadr[ids]
    d.qpos[m.jnt_qposadr[ids]], d.qvel[v] = q, dq
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    bias = d.qfrc_bias[v].copy()
    d.qacc[v] = ddq
    mujoco.mj_inverse(m, d)
    return full[np.ix_(v, v)], bias, d.qfrc_inverse[v].copy()


IDENTITY_ROBOTS = [r.name for r in CORPUS if r.name != "xarm6"] + ["planar_2dof", "iiwa"]


@pytest.mark.parametrize("name", IDENTITY_ROBOTS)
def test_mass_matrix_bias_and_inverse_dynamics_are_pinocchio(make_plant, name):
    model = RobotModel(spec_of(name))
    plant = make_plant(model)
    assert plant.model.nv == model.n  # uncontrolled joints welded, as in the reduced model
    assert plant.model.neq == 0  # the <mimic> couplings (panda's finger) are gone
    np.testing.assert_array_equal(plant.effort_limits, model.effort_limits)
    rng = np.random.default_rng(7)
    lo, hi = model.position_limits
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    for _ in range(4):
        q = rng.uniform(lo, hi)
        dq, ddq = rng.uniform(-1.0, 1.0, (2, model.n))
        B, bias, tau = mujoco_dynamics(plant, q, dq, ddq)
        for got, expected in (
            (B, model.inertia(q)),
            (bias, model.nonlinear_effects(q, dq)),
            (tau, model.rnea(q, dq, ddq)),
        ):
            scale = np.abs(expected).max()
            assert scale > 1e-3  # not vacuous: real inertias and torques
            np.testing.assert_allclose(got, expected, rtol=0, atol=REL * scale, err_msg=name)


def test_the_urdf_is_compiled_as_documented(make_plant):
    """iiwa: the URDF's damping 0.5 is zeroed; xarm7: link_eef has no <inertial> and stays
    massless, as in Pinocchio (no mass from geometry: none is compiled, and inertiafromgeom is
    false); the options are the module's."""
    iiwa = make_plant(RobotModel(resolve_robot("iiwa")), physics_rate=500.0)
    m = iiwa.model
    assert "damping" in iiwa.spec.urdf_path.read_text()
    assert np.all(m.dof_damping == 0) and np.all(m.dof_frictionloss == 0)
    assert m.opt.timestep == iiwa.dt == 2e-3
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER
    flags = mujoco.mjtDisableBit
    for flag in (flags.mjDSBL_CONTACT, flags.mjDSBL_AUTORESET):
        assert m.opt.disableflags & flag
    xarm7 = make_plant(RobotModel(spec_of("xarm7")))
    assert "link_eef" in xarm7.link_names.values()
    assert xarm7.model.body("link_eef").mass[0] == 0.0
    assert xarm7.model.ngeom == 0  # no geometry, no mesh read


def test_unphysical_inertias_are_refused_in_one_line():
    """xarm6 (pybullet_data): link2 and link3 violate the triangle inequality. PyBullet
    replaces them with a warning; MuJoCo would have to balance them: refused, by name."""
    spec = spec_of("xarm6")
    with pytest.raises(DescriptionError, match="not physical") as info:
        MujocoPlant(spec, spec.default_joints)
    assert "'link2'" in str(info.value) and "'link3'" in str(info.value)
    assert "\n" not in str(info.value)


MASSLESS_MIDDLE = """<?xml version="1.0"?>
<robot name="massless_middle">
  <link name="base"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="middle"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="5"/>
  </joint>
  <link name="middle"/>
  <joint name="j2" type="revolute">
    <parent link="middle"/><child link="tip"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="5"/>
  </joint>
  <link name="tip">
    <inertial><origin xyz="0.5 0 0"/><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
</robot>
"""


def test_a_moving_massless_link_is_refused_by_mujoco_in_one_line():
    """Pinocchio takes a massless link between two joints; MuJoCo does not, and the plant
    does not give it mass: a DescriptionError naming the link. Welding j2 makes it legal."""
    spec = resolve_robot(robot_description=MASSLESS_MIDDLE)
    with pytest.raises(DescriptionError, match="mass and inertia .* 'middle'") as info:
        MujocoPlant(spec, ("j1", "j2"))
    assert "\n" not in str(info.value)
    plant = MujocoPlant(spec, ("j1",), locked_positions={"j2": 0.3})
    try:
        model = RobotModel(spec, ("j1",), locked_positions={"j2": 0.3})
        q = np.array([0.4])
        np.testing.assert_allclose(
            mujoco_dynamics(plant, q, [0.0], [0.0])[1], model.gravity(q), rtol=0, atol=1e-14
        )
    finally:
        plant.close()


def test_effort_limits_are_the_urdfs_unless_given_and_what_is_refused(tmp_path, monkeypatch):
    """As on PyBullet: the URDF's effort (inf where it says 0: the double pendulum's exporter
    placeholder), the controller model's when given; no GUI, no unknown joint. What MuJoCo
    says while compiling is in the plant's warnings (not in ./MUJOCO_LOG.TXT)."""
    monkeypatch.chdir(tmp_path)
    iiwa = MujocoPlant(resolve_robot("iiwa"), resolve_robot("iiwa").default_joints)
    pendulum = resolve_robot(urdf_path=str(DOUBLE_PENDULUM), package_paths=PACKAGE_PATHS)
    placeholder = MujocoPlant(pendulum, pendulum.default_joints)
    limited = MujocoPlant(pendulum, pendulum.default_joints, effort_limits=[3.0, 2.0])
    try:
        np.testing.assert_array_equal(iiwa.effort_limits, np.full(7, 300.0))
        assert np.all(np.isinf(placeholder.effort_limits))
        # its limits are placeholders too (lower = upper = 0): MuJoCo ignores them, and says so
        assert len(placeholder.warnings) == 2 and iiwa.warnings == []
        assert "'joint1' has equal lower and upper limits" in placeholder.warnings[0]
        limited.step(np.array([50.0, -50.0]))
        np.testing.assert_array_equal(limited.state().effort, [3.0, -2.0])
    finally:
        for plant in (iiwa, placeholder, limited):
            plant.close()
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    with pytest.raises(ValueError, match="effort limits must be > 0"):
        MujocoPlant(pendulum, pendulum.default_joints, effort_limits=[0.0, 1.0])
    with pytest.raises(ValueError, match="no viewer"):
        MujocoWorld(gui=True)
    with pytest.raises(ValueError, match=r"unknown joints \['joint3'\]"):
        MujocoPlant(resolve_robot("planar_2dof"), ("joint1", "joint3"))


# -- one step is the model's semi-implicit Euler step -----------------------------------------
def euler_step(model: RobotModel, q0, v0, tau, dt):
    v1 = v0 + dt * np.linalg.solve(model.inertia(q0), tau - model.nonlinear_effects(q0, v0))
    return q0 + dt * v1, v1


@pytest.mark.parametrize("name", ["planar_2dof", "iiwa", "panda"])
def test_one_step_is_semi_implicit_euler_of_the_model(make_plant, name):
    """With viscous friction and a payload in both; panda: the fingers welded exactly (on
    PyBullet they are servoed, 1e-6 there)."""
    pert = ModelPerturbation(friction=FRICTION, payload_mass=PAYLOAD)
    model = RobotModel(resolve_robot(name), perturbation=pert)
    lo, hi = model.position_limits
    q_init = np.random.default_rng(1).uniform(0.8 * lo + 0.2 * hi, 0.2 * lo + 0.8 * hi)
    plant = make_plant(model, friction=FRICTION, payload_mass=PAYLOAD, initial_positions=q_init)
    rng = np.random.default_rng(2)
    limits = model.effort_limits
    plant.step(model.gravity(q_init) + 0.05 * rng.uniform(-1, 1, model.n) * limits, 20)
    for _ in range(3):
        s0 = plant.state()
        assert np.max(np.abs(s0.dq)) > 5e-3  # moving: Coriolis and friction in play
        tau = model.gravity(s0.q) + 0.05 * rng.uniform(-1, 1, model.n) * limits
        plant.step(tau)
        s1 = plant.state()
        q1, v1 = euler_step(model, s0.q, s0.dq, tau, plant.dt)
        np.testing.assert_allclose(s1.dq, v1, rtol=0, atol=REL * (1 + np.abs(v1).max()))
        np.testing.assert_allclose(s1.q, q1, rtol=0, atol=REL * (1 + np.abs(q1).max()))
        np.testing.assert_array_equal(s1.effort, tau)
        assert np.max(np.abs(s1.dq - s0.dq)) > 1e-6  # the step moved the state
    # the agreement can see the payload: without it the model misses by far
    nominal = RobotModel(resolve_robot(name), perturbation=ModelPerturbation(friction=FRICTION))
    s0 = plant.state()
    plant.step(tau)
    assert (
        np.max(np.abs(plant.state().dq - euler_step(nominal, s0.q, s0.dq, tau, plant.dt)[1]))
        > 1e-9
    )


def test_torque_is_clamped_and_held_over_the_substeps(make_plant, models):
    plant = make_plant(models["planar_2dof"], initial_positions=[0.3, -0.2], friction=FRICTION)
    plant.step(np.array([1e6, -1e6]), substeps=5)
    saturated = plant.state()
    np.testing.assert_array_equal(saturated.effort, [2000.0, -1000.0])
    plant.reset()
    for _ in range(5):
        plant.step(np.array([2000.0, -1000.0]))
    stepped = plant.state()
    np.testing.assert_array_equal(saturated.q, stepped.q)
    np.testing.assert_array_equal(saturated.dq, stepped.dq)
    assert np.max(np.abs(stepped.q - [0.3, -0.2])) > 0


def test_vectors_are_in_the_order_of_the_joints_given(make_plant):
    """planar_2dof controlled as (joint2, joint1): the same motion, every vector reversed."""
    ordered = make_plant(RobotModel(resolve_robot("planar_2dof")), initial_positions=[0.3, -0.2])
    model = RobotModel(resolve_robot("planar_2dof"), ("joint2", "joint1"))
    swapped = make_plant(model, initial_positions=[-0.2, 0.3])
    np.testing.assert_array_equal(swapped.effort_limits, [1000.0, 2000.0])
    ordered.step(np.array([300.0, -100.0]), 5)
    swapped.step(np.array([-100.0, 300.0]), 5)
    a, b = ordered.state(), swapped.state()
    for x, y in ((a.q, b.q), (a.dq, b.dq), (a.effort, b.effort)):
        np.testing.assert_array_equal(x[::-1], y)
    assert np.max(np.abs(a.dq)) > 0


# -- the closed loop against THEORY.md §2 -----------------------------------------------------
def regulate(plant: MujocoPlant, model: RobotModel, q_d, gains, gravity: bool, steps: int):
    """A plain loop: τ = [g(q)] + K_P (q_d − q) − K_D q̇ from Pinocchio, one physics step each."""
    for _ in range(steps):
        s = plant.state()
        tau = gains.kp * (q_d - s.q) - gains.kd * s.dq
        plant.step(tau + model.gravity(s.q) if gravity else tau)
    return plant.state()


@pytest.mark.parametrize("name", ["planar_2dof", "iiwa"])
def test_pure_pd_rests_where_gravity_balances_the_spring_and_pd_g_reaches_q_d(
    make_plant, models, name
):
    """ω_n = 20 rad/s, ζ = 1 on B(q_d): after 4 s the loop is at rest to rounding. Pure PD
    rests at q_e with g(q_e) = K_P (q_d − q_e) to 1e-12 of |g| (observed 1.5e-10 N·m on
    planar_2dof, 5e-12 on the iiwa) with a visible offset; PD + g(q) rests at q_d."""
    model = models[name]
    q_d = SETPOINTS[name]
    gains = pd_gains_from_second_order(np.diag(model.inertia(q_d)), 20.0, 1.0)
    plant = make_plant(model)
    rest = regulate(plant, model, q_d, gains, gravity=False, steps=4000)
    assert np.max(np.abs(rest.dq)) < 1e-12
    assert np.max(np.abs(q_d - rest.q)) > 1e-2, "pure PD should leave a visible offset"
    g = model.gravity(rest.q)
    residual = g - gains.kp * (q_d - rest.q)
    assert np.max(np.abs(residual)) < REL * np.abs(g).max(), residual
    plant.reset()
    final = regulate(plant, model, q_d, gains, gravity=True, steps=4000)
    assert np.max(np.abs(q_d - final.q)) < 1e-12
    assert np.max(np.abs(final.dq)) < 1e-12


def test_a_blown_up_run_is_a_fault_not_a_silent_restart(models, tmp_path, monkeypatch):
    """An iiwa without effort limits (as a URDF that gives none) under uniform gains (K_D 40
    on a wrist of 1e-3 kg·m²: K_D dt / B = 40) blows up in 4 ms; MuJoCo would restart it from
    q = 0 and go on. Here: one line, and the state stays as it blew up until a reset. (With
    the URDF's 300 N·m clamp the same gains only chatter: the clamp bounds each step.)"""
    monkeypatch.chdir(tmp_path)  # where MuJoCo would write its own warning: MUJOCO_LOG.TXT
    model = models["iiwa"]
    q_d = SETPOINTS["iiwa"]
    plant = MujocoPlant(model.spec, model.joint_names, effort_limits=np.inf)
    try:
        with pytest.raises(PlantFaultError, match=r"blew up in the step from t = 0\.00") as info:
            for _ in range(100):
                s = plant.state()
                plant.step(300.0 * (q_d - s.q) - 40.0 * s.dq)
        assert "\n" not in str(info.value) and "at joint 'lbr_iiwa_joint_" in str(info.value)
        assert not (tmp_path / "MUJOCO_LOG.TXT").exists()  # said once, by the fault only
        after = plant.state()
        assert np.max(np.abs(after.q)) > 10.0  # not restarted at q = 0
        with pytest.raises(PlantFaultError):
            plant.step(np.zeros(model.n))  # it stays stopped
        plant.reset()
        plant.step(model.gravity(plant.state().q))
        assert np.max(np.abs(plant.state().dq)) < 1e-12  # a reset starts afresh
    finally:
        plant.close()


# -- imperfections ----------------------------------------------------------------------------
FC = np.array([50.0, 30.0])  # [N·m] Coulomb
FS = np.array([80.0, 60.0])  # [N·m] stiction
Q0 = np.array([0.3, -0.5])


def test_stiction_holds_and_sliding_friction_is_coulomb(make_plant, models):
    """Below F_s the arm holds, creeping < 1e-5 rad in 1 s (MuJoCo's friction is a soft
    constraint: ~7e-7 observed); with F_s = F_c the same torque slides; a sliding joint feels
    −F_c sign q̇ exactly (the constraint saturated)."""
    model = models["planar_2dof"]
    plant = make_plant(model, initial_positions=Q0)
    plant.set_coulomb_friction(FC, FS)
    net = np.array([70.0, -50.0])
    for _ in range(1000):
        plant.step(model.gravity(plant.state().q) + net)
    assert np.max(np.abs(plant.state().q - Q0)) < 1e-5
    plant.set_coulomb_friction(FC)
    plant.reset()
    for _ in range(100):
        plant.step(model.gravity(plant.state().q) + net)
    s = plant.state()
    assert np.all(np.abs(s.dq) > STICTION_SPEED)
    tau = model.gravity(s.q) + net
    expected = np.linalg.solve(
        model.inertia(s.q), tau - model.nonlinear_effects(s.q, s.dq) - FC * np.sign(s.dq)
    )
    np.testing.assert_allclose(
        acceleration(plant, tau), expected, rtol=0, atol=1e-9 * (1 + np.abs(expected).max())
    )


def test_brakes_stop_and_hold_the_arm_and_release_it(make_plant, models):
    model = models["planar_2dof"]
    plant = make_plant(model, initial_positions=Q0)
    for _ in range(100):  # 0.1 s of free fall
        plant.step(np.zeros(2))
    assert np.max(np.abs(plant.state().dq)) > 0.5
    plant.brake(substeps=500)
    held = plant.state()
    assert np.max(np.abs(held.dq)) < 1e-4
    # the brakes carry gravity: their effort is g(q), within the limits
    np.testing.assert_allclose(held.effort, model.gravity(held.q), rtol=1e-3)
    assert np.all(np.abs(held.effort) <= plant.effort_limits)
    plant.step(np.zeros(2))  # released: free motion again, the model's Euler step
    _, v1 = euler_step(model, held.q, held.dq, np.zeros(2), plant.dt)
    np.testing.assert_allclose(plant.state().dq, v1, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("robot", "link"), [("planar_2dof", "link1"), ("iiwa", "")])
def test_wrench_is_jacobian_transpose_of_pinocchio(make_plant, models, robot, link):
    """Two configurations, as on PyBullet (test_plant_imperfections.check_wrench)."""
    plant = make_plant(models[robot])
    check_wrench(plant, models[robot], link, 2)
    with pytest.raises(ValueError, match="no moving link"):
        plant.hold_wrench("no_such_link", [1.0, 0.0, 0.0], [0.0] * 3)


# -- repeatable --------------------------------------------------------------------------------
def test_the_same_run_twice_is_bit_identical(make_plant, models):
    """PD + g with every imperfection on and the brakes in the middle (test_plant_imperfections'
    run): again after a reset, and on a twin whose world steps an iiwa beside it."""
    model = models["planar_2dof"]

    def imperfect(plant: MujocoPlant) -> MujocoPlant:
        plant.set_coulomb_friction(FC * 0.1, FS * 0.1)
        plant.set_torque_rate_limit(5e4)
        plant.hold_wrench("", [0.0, 0.0, -50.0], [0.0, 5.0, 0.0])
        return plant

    plant = imperfect(make_plant(model, initial_positions=Q0, friction=0.3, payload_mass=1.0))
    first = run(plant, model)
    assert np.max(np.abs(first[:, 2:4])) > 0.1  # it moved
    plant.reset()
    np.testing.assert_array_equal(run(plant, model), first)
    world = MujocoWorld()
    iiwa = make_plant(models["iiwa"], world=world)
    twin = make_plant(model, initial_positions=Q0, friction=0.3, payload_mass=1.0, world=world)
    np.testing.assert_array_equal(run(imperfect(twin), model), first)
    assert np.max(np.abs(iiwa.state().dq)) > 0.1  # the world stepped it too
