"""Robot model: golden values, rigid-body identities and PyBullet agreement (STYLE.md §5).

The dynamics are B(q) q̈ + C(q, q̇) q̇ + F q̇ + g(q) = τ (THEORY.md §1), in the order of the
controlled joints. Tolerances:

- closed forms and identities between Pinocchio algorithms: 1e-9 relative to the size of
  the terms (the algorithms differ only by floating-point rounding, ~1e-15 relative);
- Ḃ − 2C skew-symmetry: Ḃ comes from a central difference with step h = 1e-5 along q̇;
  truncation error ~h² |∂³B| ≈ 1e-10 and rounding ~eps |B| / h ≈ 1e-11, both relative to
  |Ḃ|, so 1e-6 relative leaves four orders of margin and still fails for any real error
  (a wrong C is off by O(1) relative);
- PyBullet inverse dynamics vs Pinocchio rnea: both are exact recursive Newton-Euler on
  the same URDF, so they agree to rounding: 1e-12 N·m on iiwa and panda (torques of
  ~10–100 N·m); the planar arm (50 kg links) has torques ~1e3 N·m, so 1e-12 *relative*
  (~1e-9 N·m absolute) — an absolute 1e-12 would be below one ulp of 1e3 (~1e-13 · 1e3).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

from joint_space_control.arrays import per_joint
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import (
    actuated_joints,
    builtin_robots,
    inertia_is_physical,
    resolve_robot,
    urdf_facts,
)

ROBOTS = ("planar_2dof", "iiwa", "panda")
G0 = 9.81  # [m/s²]
# planar_2dof parameters (THEORY.md, the URDF's comment)
A1, LC, M, I = 1.0, 0.5, 50.0, 10.0


# -- fixtures --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def models() -> dict[str, RobotModel]:
    return {name: RobotModel(resolve_robot(name)) for name in ROBOTS}


@pytest.fixture(scope="module")
def friction_models() -> dict[str, RobotModel]:
    """The same robots with a viscous friction that differs per joint."""
    out = {}
    for name in ROBOTS:
        n = len(builtin_robots()[name].default_joints)
        friction = np.linspace(0.3, 2.0, n)
        out[name] = RobotModel(resolve_robot(name), perturbation=ModelPerturbation(friction))
    return out


def random_states(model: RobotModel, count: int, seed: int):
    """(q, q̇, q̈) within the position limits (finite ones), |q̇| ≤ 2, |q̈| ≤ 5."""
    rng = np.random.default_rng(seed)
    lo, hi = model.position_limits
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    for _ in range(count):
        yield (
            rng.uniform(lo, hi),
            rng.uniform(-2.0, 2.0, model.n),
            rng.uniform(-5.0, 5.0, model.n),
        )


def assert_close(actual, expected, rel: float, what: str = "") -> None:
    actual, expected = np.asarray(actual), np.asarray(expected)
    scale = max(1.0, float(np.max(np.abs(expected))))
    err = float(np.max(np.abs(actual - expected)))
    assert err <= rel * scale, f"{what}: error {err:.3e} > {rel:.0e} × {scale:.3e}"


# -- planar_2dof golden values -----------------------------------------------------------


def planar_inertia(q: np.ndarray) -> np.ndarray:
    c2 = math.cos(q[1])
    b11 = 2 * I + M * LC**2 + M * (A1**2 + LC**2 + 2 * A1 * LC * c2)
    b12 = I + M * (LC**2 + A1 * LC * c2)
    b22 = I + M * LC**2
    return np.array([[b11, b12], [b12, b22]])


def planar_gravity(q: np.ndarray) -> np.ndarray:
    c1, c12 = math.cos(q[0]), math.cos(q[0] + q[1])
    return np.array([(M * LC + M * A1) * G0 * c1 + M * LC * G0 * c12, M * LC * G0 * c12])


def test_planar_inertia_and_gravity_match_closed_forms(models):
    model = models["planar_2dof"]
    rng = np.random.default_rng(0)
    for q in rng.uniform(-np.pi, np.pi, size=(50, 2)):
        np.testing.assert_allclose(model.inertia(q), planar_inertia(q), rtol=0, atol=1e-9)
        np.testing.assert_allclose(model.gravity(q), planar_gravity(q), rtol=0, atol=1e-9)


def test_planar_golden_values_at_known_configurations(models):
    """Hand-checked numbers: stretched horizontally, and hanging straight up."""
    model = models["planar_2dof"]
    # q = 0: horizontal; g1 = (25 + 50 + 25)·9.81, g2 = 25·9.81;
    # b11 = 2·10 + 50·0.25 + 50·(1 + 0.25 + 1), b12 = 10 + 50·(0.25 + 0.5), b22 = 10 + 12.5
    np.testing.assert_allclose(model.gravity(np.zeros(2)), [981.0, 245.25], atol=1e-9)
    np.testing.assert_allclose(
        model.inertia(np.zeros(2)), [[145.0, 47.5], [47.5, 22.5]], atol=1e-9
    )
    # arm pointing straight up: no gravity torque; positive angles raise the arm
    np.testing.assert_allclose(model.gravity(np.array([np.pi / 2, 0.0])), [0, 0], atol=1e-9)
    assert model.gravity(np.array([0.3, 0.0]))[0] < model.gravity(np.zeros(2))[0]


# -- identities on every built-in robot ----------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_nonlinear_effects_and_gravity_are_rnea(models, friction_models, name):
    for model in (models[name], friction_models[name]):
        zero = np.zeros(model.n)
        for q, dq, _ in random_states(model, 10, seed=1):
            assert_close(model.nonlinear_effects(q, dq), model.rnea(q, dq, zero), 1e-9, "nle")
            assert_close(model.gravity(q), model.rnea(q, zero, zero), 1e-9, "g")


@pytest.mark.parametrize("name", ROBOTS)
def test_rnea_equals_b_ddq_plus_c_dq_plus_g_plus_f_dq(models, friction_models, name):
    for model in (models[name], friction_models[name]):
        for q, dq, ddq in random_states(model, 10, seed=2):
            expected = (
                model.inertia(q) @ ddq
                + model.coriolis(q, dq) @ dq
                + model.gravity(q)
                + model.friction * dq
            )
            assert_close(model.rnea(q, dq, ddq), expected, 1e-9, "rnea")
    # the friction term is really there: F q̇ with F > 0 per joint
    q, dq, ddq = next(random_states(models[name], 1, seed=3))
    delta = friction_models[name].rnea(q, dq, ddq) - models[name].rnea(q, dq, ddq)
    assert_close(delta, friction_models[name].friction * dq, 1e-9, "F q̇")
    assert np.all(friction_models[name].friction > 0)


@pytest.mark.parametrize("name", ROBOTS)
def test_inertia_symmetric_positive_definite(models, name):
    model = models[name]
    for q, _, _ in random_states(model, 20, seed=4):
        B = model.inertia(q)
        assert B.shape == (model.n, model.n)
        np.testing.assert_array_equal(B, B.T)
        assert np.linalg.eigvalsh(B).min() > 0


@pytest.mark.parametrize("name", ROBOTS)
def test_bdot_minus_2c_is_skew_symmetric_and_passive(models, name):
    model = models[name]
    h = 1e-5  # central-difference step along q̇ (see the module docstring)
    rng = np.random.default_rng(5)
    for q, dq, _ in random_states(model, 10, seed=5):
        b_dot = (model.inertia(q + h * dq) - model.inertia(q - h * dq)) / (2 * h)
        C = model.coriolis(q, dq)
        N = b_dot - 2 * C
        scale = np.max(np.abs(b_dot)) + 2 * np.max(np.abs(C))
        assert scale > 0
        assert np.max(np.abs(N + N.T)) <= 1e-6 * scale
        for x in (dq, rng.standard_normal(model.n)):
            assert abs(x @ N @ x) <= 1e-6 * scale * (x @ x)
        # C q̇ is the Coriolis/centrifugal part of n: n − g − F q̇
        assert_close(C @ dq, model.nonlinear_effects(q, dq) - model.gravity(q), 1e-9, "C q̇")


# -- PyBullet agrees with Pinocchio ----------------------------------------------------


@pytest.fixture(scope="module")
def bullet():
    """One DIRECT client with every built-in robot loaded as PyBullet's plant loads it."""
    client = pb.connect(pb.DIRECT)
    pb.setGravity(0.0, 0.0, -G0, physicsClientId=client)
    bodies = {}
    for name in ROBOTS:
        body = pb.loadURDF(
            str(builtin_robots()[name].urdf_path),
            useFixedBase=True,
            flags=pb.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=client,
        )
        movable = []
        for j in range(pb.getNumJoints(body, physicsClientId=client)):
            info = pb.getJointInfo(body, j, physicsClientId=client)
            if info[2] != pb.JOINT_FIXED:
                movable.append(info[1].decode())
        bodies[name] = (body, movable)
    yield client, bodies
    pb.disconnect(client)


@pytest.mark.parametrize(
    ("name", "tol", "relative"),
    [("planar_2dof", 1e-12, True), ("iiwa", 1e-12, False), ("panda", 1e-12, False)],
)
def test_pybullet_inverse_dynamics_equals_pinocchio_rnea(models, bullet, name, tol, relative):
    """Absolute 1e-12 N·m on iiwa/panda; relative 1e-12 on the planar arm (~1e3 N·m, where
    one ulp is already ~1e-13 N·m and ten rounded operations reach ~1e-12 N·m)."""
    client, bodies = bullet
    body, movable = bodies[name]
    model = models[name]
    # every movable joint is either controlled or locked (panda fingers)
    assert set(movable) == set(model.joint_names) | set(model.locked_positions)
    if name == "panda":
        assert set(model.locked_positions) == {"panda_finger_joint1", "panda_finger_joint2"}
    for q, dq, ddq in random_states(model, 10, seed=6):
        pos = dict(model.locked_positions) | dict(zip(model.joint_names, q, strict=True))
        vel = dict(zip(model.joint_names, dq, strict=True))
        acc = dict(zip(model.joint_names, ddq, strict=True))
        tau = pb.calculateInverseDynamics(
            body,
            [float(pos[j]) for j in movable],
            [float(vel.get(j, 0.0)) for j in movable],
            [float(acc.get(j, 0.0)) for j in movable],
            physicsClientId=client,
        )
        by_name = dict(zip(movable, tau, strict=True))
        expected = model.rnea(q, dq, ddq)
        actual = np.array([by_name[j] for j in model.joint_names])
        bound = tol * float(np.max(np.abs(expected))) if relative else tol
        assert np.max(np.abs(actual - expected)) <= bound
        assert np.max(np.abs(expected)) > 1.0  # a non-trivial comparison


# -- joint order ------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
def test_reversed_joint_order_permutes_everything(models, name):
    model = models[name]
    reversed_model = RobotModel(model.spec, joints=tuple(reversed(model.joint_names)))
    assert reversed_model.joint_names == tuple(reversed(model.joint_names))
    p = np.arange(model.n)[::-1]
    for q, dq, ddq in random_states(model, 5, seed=7):
        np.testing.assert_allclose(
            reversed_model.inertia(q[p]), model.inertia(q)[np.ix_(p, p)], rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(reversed_model.gravity(q[p]), model.gravity(q)[p], atol=1e-12)
        np.testing.assert_allclose(
            reversed_model.coriolis(q[p], dq[p]), model.coriolis(q, dq)[np.ix_(p, p)], atol=1e-12
        )
        np.testing.assert_allclose(
            reversed_model.rnea(q[p], dq[p], ddq[p]), model.rnea(q, dq, ddq)[p], atol=1e-10
        )
    np.testing.assert_array_equal(reversed_model.effort_limits, model.effort_limits[p])
    np.testing.assert_array_equal(reversed_model.position_limits[0], model.position_limits[0][p])


# -- perturbations ------------------------------------------------------------------------


def test_mass_scale_scales_planar_gravity(models):
    scaled = RobotModel(
        resolve_robot("planar_2dof"), perturbation=ModelPerturbation(mass_scale=1.2)
    )
    for q in np.random.default_rng(8).uniform(-np.pi, np.pi, size=(20, 2)):
        np.testing.assert_allclose(
            scaled.gravity(q), 1.2 * models["planar_2dof"].gravity(q), rtol=1e-12, atol=1e-9
        )
        np.testing.assert_allclose(
            scaled.inertia(q), 1.2 * models["planar_2dof"].inertia(q), rtol=1e-12
        )


def test_mass_scale_per_joint_only_scales_that_link(models):
    """Scaling link 2 only changes g2 by exactly that factor (g2 depends on link 2 alone)."""
    scaled = RobotModel(
        resolve_robot("planar_2dof"), perturbation=ModelPerturbation(mass_scale=[1.0, 2.0])
    )
    q = np.array([0.2, -0.4])
    nominal = models["planar_2dof"].gravity(q)
    assert scaled.gravity(q)[1] == pytest.approx(2.0 * nominal[1], rel=1e-12)
    assert scaled.gravity(q)[0] != pytest.approx(2.0 * nominal[0], rel=1e-3)


def test_payload_sits_at_link2_centre_of_mass(models):
    mp = 3.0
    model = RobotModel(
        resolve_robot("planar_2dof"), perturbation=ModelPerturbation(payload_mass=mp)
    )
    np.testing.assert_allclose(model.payload_point(), [0.5, 0.0, 0.0], atol=1e-12)
    for q1, q2 in np.random.default_rng(9).uniform(-np.pi, np.pi, size=(20, 2)):
        q = np.array([q1, q2])
        c12 = math.cos(q1 + q2)
        expected = np.array([mp * G0 * (A1 * math.cos(q1) + 0.5 * c12), mp * G0 * 0.5 * c12])
        delta = model.gravity(q) - models["planar_2dof"].gravity(q)
        np.testing.assert_allclose(delta, expected, rtol=0, atol=1e-9)
        # a point mass at the COM of link 2 adds mp·(lever)² to the inertia, no rotation
        d_b22 = model.inertia(q)[1, 1] - models["planar_2dof"].inertia(q)[1, 1]
        assert d_b22 == pytest.approx(mp * 0.25, abs=1e-9)


@pytest.mark.parametrize("name", ROBOTS)
def test_no_gravity(name, models):
    model = RobotModel(resolve_robot(name), perturbation=ModelPerturbation(gravity=False))
    for q, dq, ddq in random_states(model, 5, seed=10):
        np.testing.assert_array_equal(model.gravity(q), np.zeros(model.n))
        # the rest of the dynamics is untouched
        np.testing.assert_allclose(
            model.rnea(q, dq, ddq),
            models[name].rnea(q, dq, ddq) - models[name].gravity(q),
            atol=1e-9,
        )
    assert np.any(models[name].gravity(q) != 0)


def test_friction_adds_f_dq(models):
    friction = [0.5, 3.0]
    model = RobotModel(resolve_robot("planar_2dof"), perturbation=ModelPerturbation(friction))
    np.testing.assert_array_equal(model.friction, friction)
    q, dq, ddq = np.array([0.1, 0.2]), np.array([1.5, -2.0]), np.array([0.3, 0.4])
    nominal = models["planar_2dof"]
    np.testing.assert_allclose(
        model.nonlinear_effects(q, dq) - nominal.nonlinear_effects(q, dq),
        [0.75, -6.0],
        atol=1e-9,
    )
    np.testing.assert_allclose(
        model.rnea(q, dq, ddq) - nominal.rnea(q, dq, ddq), [0.75, -6.0], atol=1e-9
    )
    np.testing.assert_array_equal(model.gravity(q), nominal.gravity(q))


@pytest.mark.parametrize(
    ("perturbation", "match"),
    [
        (ModelPerturbation(mass_scale=-1.0), "mass_scale"),
        (ModelPerturbation(mass_scale=0.0), "mass_scale"),
        (ModelPerturbation(mass_scale=[1.0, math.nan]), "mass_scale"),
        (ModelPerturbation(payload_mass=-0.1), "payload_mass"),
        (ModelPerturbation(payload_mass=math.nan), "payload_mass"),
        (ModelPerturbation(payload_mass=math.inf), "payload_mass"),
        (ModelPerturbation(friction=math.nan), "friction"),
        (ModelPerturbation(friction=[0.1, 0.2, 0.3]), "friction"),
        (ModelPerturbation(friction=-0.1), "friction"),
        (ModelPerturbation(mass_scale=[1.0, 1.0, 1.0]), "mass_scale"),
    ],
)
def test_invalid_perturbations_raise(perturbation, match):
    with pytest.raises(ValueError, match=match):
        RobotModel(resolve_robot("planar_2dof"), perturbation=perturbation)


def test_per_joint_broadcasts_and_validates():
    np.testing.assert_array_equal(per_joint(2.0, 3, "x"), [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(per_joint([1, 2], 2, "x"), [1.0, 2.0])
    with pytest.raises(ValueError, match="'x' needs 1 or 3 values, got 2"):
        per_joint([1, 2], 3, "x")
    with pytest.raises(ValueError, match="finite"):
        per_joint([1, math.inf], 2, "x")


# -- a URDF with a continuous joint and an uncontrolled prismatic joint --------------------

CONTINUOUS_URDF = """<?xml version="1.0"?>
<robot name="cont_arm">
  <link name="base">
    <inertial><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="spin" type="continuous">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit effort="50" velocity="5"/>
  </joint>
  <link name="arm">
    <inertial><origin xyz="0.3 0 0" rpy="0 0 0"/><mass value="2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
  </link>
  <joint name="elbow" type="revolute">
    <parent link="arm"/><child link="forearm"/>
    <origin xyz="0.6 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="20" velocity="5"/>
  </joint>
  <link name="forearm">
    <inertial><origin xyz="0.2 0 0" rpy="0 1.5707963267948966 0"/><mass value="1"/>
      <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/></inertial>
  </link>
  <joint name="tool_mount" type="fixed">
    <parent link="forearm"/><child link="tool"/>
    <origin xyz="0.4 0 0" rpy="0 0 0"/>
  </joint>
  <link name="tool">
    <inertial><mass value="0.2"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
  <joint name="finger" type="prismatic">
    <parent link="tool"/><child link="finger_link"/>
    <origin xyz="0.05 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0.01" upper="0.04" effort="10" velocity="0.1"/>
  </joint>
  <link name="finger_link">
    <inertial><mass value="0.1"/>
      <inertia ixx="0.0001" ixy="0" ixz="0" iyy="0.0001" iyz="0" izz="0.0001"/></inertial>
  </link>
</robot>
"""


@pytest.fixture
def continuous_urdf(tmp_path) -> Path:
    path = tmp_path / "cont_arm.urdf"
    path.write_text(CONTINUOUS_URDF)
    return path


def test_urdf_path_default_joints_are_actuated_joints_in_file_order(continuous_urdf):
    spec = resolve_robot(urdf_path=str(continuous_urdf))
    assert spec.name == "cont_arm"
    assert spec.urdf_path == continuous_urdf.resolve()
    assert spec.default_joints == ("spin", "elbow", "finger")
    assert actuated_joints(continuous_urdf) == ("spin", "elbow", "finger")


def test_continuous_joint_model(continuous_urdf):
    spec = resolve_robot(urdf_path=str(continuous_urdf))
    model = RobotModel(spec, joints=["spin", "elbow"])
    assert model.n == 2
    # the uncontrolled finger is locked, at 0 clamped into its limits [0.01, 0.04]
    assert model.locked_positions == {"finger": pytest.approx(0.01)}
    lo, hi = model.position_limits
    assert lo[0] == -np.inf and hi[0] == np.inf
    assert (lo[1], hi[1]) == (-2.0, 2.0)
    np.testing.assert_array_equal(model.effort_limits, [50.0, 20.0])
    rng = np.random.default_rng(11)
    for q in rng.uniform(-np.pi, np.pi, size=(10, 2)):
        shifted = q + np.array([2 * np.pi, 0.0])
        np.testing.assert_allclose(model.gravity(shifted), model.gravity(q), atol=1e-12)
        np.testing.assert_allclose(model.inertia(shifted), model.inertia(q), atol=1e-12)
        # …and gravity does depend on the continuous angle
        assert np.max(np.abs(model.gravity(q + [1.0, 0.0]) - model.gravity(q))) > 0.1
    assert model.inertia(q).shape == (2, 2)
    for q, dq, ddq in random_states(model, 5, seed=12):
        expected = model.inertia(q) @ ddq + model.coriolis(q, dq) @ dq + model.gravity(q)
        assert_close(model.rnea(q, dq, ddq), expected, 1e-9, "rnea continuous")


def test_locked_positions_are_applied_and_validated(continuous_urdf):
    spec = resolve_robot(urdf_path=str(continuous_urdf))
    model = RobotModel(spec, joints=["spin", "elbow"], locked_positions={"finger": 0.03})
    assert model.locked_positions == {"finger": pytest.approx(0.03)}
    # clamped into the limits
    model = RobotModel(spec, joints=["spin", "elbow"], locked_positions={"finger": 1.0})
    assert model.locked_positions == {"finger": pytest.approx(0.04)}
    with pytest.raises(ValueError, match="locked_positions"):
        RobotModel(spec, joints=["spin", "elbow"], locked_positions={"elbow": 0.1})
    with pytest.raises(ValueError, match="locked_positions"):
        RobotModel(spec, joints=["spin", "elbow"], locked_positions={"nope": 0.1})


def test_locked_prismatic_position_moves_the_payload_point(continuous_urdf):
    """The finger is part of the rigid body after locking: its position changes g."""
    spec = resolve_robot(urdf_path=str(continuous_urdf))
    near = RobotModel(spec, joints=["spin", "elbow"], locked_positions={"finger": 0.01})
    far = RobotModel(spec, joints=["spin", "elbow"], locked_positions={"finger": 0.04})
    q = np.zeros(2)
    # horizontal arm, axes +y (a positive angle lowers the arm: z = −r sin q, so
    # g = ∂U/∂q = −m g0 r at q = 0): the finger (0.1 kg) moved 0.03 m outwards changes
    # g by −0.1·g0·0.03 on both joints
    expected = [-0.1 * G0 * 0.03] * 2
    np.testing.assert_allclose(far.gravity(q) - near.gravity(q), expected, atol=1e-9)


def test_urdf_facts_reads_inertials_in_the_link_frame(continuous_urdf):
    facts = urdf_facts(continuous_urdf)
    assert [j.name for j in facts.joints] == ["spin", "elbow", "tool_mount", "finger"]
    assert [j.type for j in facts.joints] == ["continuous", "revolute", "fixed", "prismatic"]
    arm = facts.inertials["arm"]
    assert arm.mass == 2.0
    np.testing.assert_array_equal(arm.com, [0.3, 0.0, 0.0])
    # forearm's inertial frame is pitched by 90°: x and z moments swap in the link frame
    np.testing.assert_allclose(
        facts.inertials["forearm"].inertia, np.diag([0.03, 0.02, 0.005]), atol=1e-12
    )


def test_inertia_is_physical():
    assert inertia_is_physical(np.diag([1.0, 1.0, 2.0]))  # equality case of a thin disc
    assert inertia_is_physical(np.diag([1.0, 2.0, 2.5]))
    assert not inertia_is_physical(np.diag([1.0, 1.0, 5.0]))  # triangle inequality violated
    assert not inertia_is_physical(np.diag([-1.0, 2.0, 2.0]))  # negative moment
    # rotated tensors are judged on their principal moments
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert not inertia_is_physical(rot @ np.diag([5.0, 1.0, 1.0]) @ rot.T)


# -- resolve_robot and joint-name validation -----------------------------------------------


def test_resolve_builtin_robots():
    robots = builtin_robots()
    assert set(robots) == set(ROBOTS)
    for name in ROBOTS:
        spec = resolve_robot(name)
        assert spec == robots[name]
        assert spec.urdf_path.is_file()
    assert resolve_robot("iiwa").default_joints == tuple(
        f"lbr_iiwa_joint_{i}" for i in range(1, 8)
    )


def test_resolve_robot_errors(tmp_path, continuous_urdf):
    with pytest.raises(ValueError, match=r"unknown robot 'ur5'.*planar_2dof, iiwa, panda"):
        resolve_robot("ur5")
    with pytest.raises(ValueError, match="unknown robot ''"):
        resolve_robot()
    missing = tmp_path / "missing.urdf"
    with pytest.raises(ValueError, match="is not a file"):
        resolve_robot(urdf_path=str(missing))
    with pytest.raises(ValueError, match="is not a file"):
        resolve_robot(urdf_path=str(tmp_path))  # a directory
    with pytest.raises(ValueError, match="either 'robot' or 'urdf_path', not both"):
        resolve_robot("iiwa", urdf_path=str(continuous_urdf))


@pytest.mark.parametrize(
    ("robot", "joints", "match"),
    [
        ("planar_2dof", ["joint1", "joint3"], "unknown joint 'joint3'"),
        ("planar_2dof", ["joint1", "joint1"], "duplicated"),
        ("panda", [f"panda_joint{i}" for i in range(1, 9)], "'panda_joint8' is fixed"),
        ("iiwa", ["lbr_iiwa_joint_1", "nope"], "unknown joint 'nope'"),
    ],
)
def test_bad_joint_names_raise(robot, joints, match):
    with pytest.raises(ValueError, match=match):
        RobotModel(resolve_robot(robot), joints=joints)


def test_subset_of_joints_locks_the_others(models):
    """Controlling joint2 only: joint1 is locked at 0 and g matches the closed form."""
    model = RobotModel(resolve_robot("planar_2dof"), joints=["joint2"])
    assert model.n == 1
    assert model.locked_positions == {"joint1": 0.0}
    for q2 in (-1.0, 0.3, 2.0):
        assert model.gravity(np.array([q2]))[0] == pytest.approx(
            planar_gravity(np.array([0.0, q2]))[1], abs=1e-9
        )
        assert model.inertia(np.array([q2]))[0, 0] == pytest.approx(I + M * LC**2, abs=1e-9)


# -- limits -----------------------------------------------------------------------------


def test_effort_limits(models):
    np.testing.assert_array_equal(models["iiwa"].effort_limits, [300.0] * 7)
    np.testing.assert_array_equal(models["panda"].effort_limits, [87.0] * 4 + [12.0] * 3)
    np.testing.assert_array_equal(models["planar_2dof"].effort_limits, [2000.0, 1000.0])


def test_position_limits(models):
    lo, hi = models["planar_2dof"].position_limits
    np.testing.assert_allclose(lo, [-3.14159] * 2)
    np.testing.assert_allclose(hi, [3.14159] * 2)
    for model in models.values():
        lo, hi = model.position_limits
        assert lo.shape == hi.shape == (model.n,)
        assert np.all(lo < hi)
