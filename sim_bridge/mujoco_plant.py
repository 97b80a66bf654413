r"""The MuJoCo plant, without ROS: the same interface and meaning as :mod:`sim_bridge.plant`.

B(q) q̈ + C(q, q̇) q̇ + F q̇ + g(q) = τ (THEORY.md §1), compiled by MuJoCo from the very URDF
every node loads (:attr:`RobotSpec.urdf_path`: xacro expanded, ``package://`` resolved), never
from a hand-made MJCF. What is done to it, and why:

- its ``<visual>``, ``<collision>`` and ``<mujoco>`` blocks are dropped before MuJoCo reads it:
  contacts are off and the plant has no viewer, so geometry has no part in the dynamics, and
  no mesh (``.dae`` included, which MuJoCo cannot read) is ever loaded; the description's own
  MuJoCo options, if it has any, give way to the ones below;
- joints that are not controlled (gripper fingers, mimic joints) are welded at the positions of
  the controller model (``locked_positions``, else 0): their motion at that value is folded into
  the link's pose and the joint removed, which is Pinocchio's reduced model exactly (PyBullet
  holds them with stiff servos). The ``<mimic>`` couplings MuJoCo makes into joint equality
  constraints go too: PyBullet ignores them, and a mimic joint is never controlled;
- the URDF's ``<dynamics damping friction>`` is zeroed on every joint (with armature and
  stiffness), as PyBullet's plant zeroes its damping: the only friction is the plant's own.

Compiler options (:class:`mujoco.MjsCompiler`), every one that bears on the dynamics:

- ``inertiafromgeom`` false: a link's mass and inertia are its ``<inertial>``; a link without
  one is massless, as in Pinocchio and the URDF spec (MuJoCo would otherwise compute them from
  the geometry);
- ``balanceinertia`` false: an inertia that violates the triangle inequality is never
  silently balanced. Such a description is refused (:class:`DescriptionError` naming the
  links) before compiling: MuJoCo cannot simulate it unchanged (PyBullet replaces it and
  :attr:`sim_bridge.plant.Plant.warnings` says so; the controller model keeps the URDF's);
- ``boundmass`` and ``boundinertia`` 0, ``settotalmass`` −1: no mass or inertia is raised or
  rescaled. A massless link on a joint of its own with no mass welded to it (the link between
  the two joints of a two-axis wrist, say) is refused by MuJoCo ("mass and inertia of moving
  bodies must be larger than mjMINVAL"), where Pinocchio and PyBullet take it: a
  :class:`DescriptionError`;
- ``fusestatic`` false: every URDF link stays a body of its own, so a wrench on a link fixed
  to its parent (a tool frame) acts where it is named; fusing would change no dynamics;
- ``autolimits`` true: a joint is limited where the URDF gives limits (continuous joints are
  not), enforced as on PyBullet, here by MuJoCo's limit constraint, as stiff as it allows
  (:data:`STIFF_SOLIMP`, time constant 2 dt: 300 N·m against the iiwa's joint 2 limit passes
  it by 2e-7 rad);
- ``discardvisual`` true and ``degree`` false: no visual geometry, angles in radians (the
  URDF's unit) — both moot after the stripping above, set so that nothing is left to a
  default.

The root link is fixed to the world, as PyBullet's ``useFixedBase``: MuJoCo's URDF reader
gives it no joint (a floating joint is refused earlier, :func:`~joint_space_control.model.
description.parse_urdf`). Physics options (:class:`mujoco.MjOption`): time step
``1 / physics_rate``; gravity (0, 0, −9.81); the integrator is semi-implicit Euler
(``mjINT_EULER``: v₁ = v₀ + dt q̈(q₀, v₀), q₁ = q₀ + dt v₁), Bullet's, so the two engines
differ by their arithmetic, not their scheme (``eulerdamp`` off: there is no joint damping to
integrate implicitly); contacts off (``mjDSBL_CONTACT``): the PyBullet plant loads no ground
and no self-collision;
``mjDSBL_AUTORESET``: MuJoCo would otherwise restart a blown-up simulation from its initial
state with only a printed warning; here a non-finite or huge position, velocity or
acceleration is a :class:`PlantFaultError`, raised by the step that met it, and the state stays as
it is until :meth:`MujocoPlant.reset`; no fluid forces (density, viscosity, wind 0); the Newton
solver (100 iterations, tolerance 1e-10) for the only constraints there are (joint limits,
Coulomb friction, brakes), with dense Jacobians (the arms are small, and 4.0.0's sparse
Cholesky factorisation had a bug fixed in 4.0.1).

Torque control as on PyBullet: the command, clamped to the effort limits (and approached at
the torque-rate limit if set), is held over every physics sub-step (zero-order hold) as
``qfrc_applied``, with the viscous friction −F q̇ of each sub-step; a wrench w on a link adds
Jᵀw (``mj_applyFT`` at the link frame's origin, :mod:`sim_bridge.wrench`); the payload is a
point mass at the centre of mass of the last controlled joint's child link, the place of
:class:`~joint_space_control.model.dynamics.ModelPerturbation`.

Coulomb friction, stiction and the brakes are MuJoCo's dry friction (``frictionloss``), a
constraint solved with the dynamics like Bullet's velocity motors: F_c (F_s while
|q̇| < :data:`~sim_bridge.torque_plant.STICTION_SPEED`), or the effort limit while braking. MuJoCo's
constraints are soft: set as stiff as it allows (:data:`STIFF_SOLIMP`, time constant 2 dt), a
joint held by friction still creeps, at 7e-7 rad/s on planar_2dof held 10 N·m below stiction
(PyBullet: ~1e-13 rad in a second).

What MuJoCo says while reading and compiling the description (equal lower and upper joint
limits, which it ignores, say) is in :attr:`MujocoPlant.warnings`. What the MuJoCo plant
cannot do, refused in one line rather than done otherwise: a GUI
(``gui=True``: ValueError; the plant has no geometry to show, watch it on the dashboard),
descriptions with a non-physical inertia or a moving massless link (DescriptionError, above).
Robots in one :class:`MujocoWorld` cannot touch (contacts are off), so each is a MuJoCo model of
its own, stepped together on the world's clock: a robot's numbers never depend on the others.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from lxml import etree

from joint_space_control.arrays import per_joint
from joint_space_control.model.description import DescriptionError
from joint_space_control.model.robots import RobotSpec, inertia_is_physical, urdf_facts
from sim_bridge.torque_plant import (
    GRAVITY,
    LOCK_FORCE,
    PlantFaultError,
    TorquePlant,
    TorqueWorld,
)

#: solimp of the joint limits, the Coulomb friction and the brakes: the stiffest impedance
#: MuJoCo allows (0.9999) at every violation; with the time constant of 2 dt (its smallest
#: stable one) a joint held by friction creeps at 7e-7 rad/s, 8e-3 with MuJoCo's defaults.
STIFF_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: MuJoCo's warning of a blown-up simulation: an acceleration that is not finite or beyond
#: 1e10. It always comes first (positions and velocities only go bad by integrating one), so
#: it is the one checked after every step (the three checks would double the step's overhead).
BAD_ACCELERATION = mujoco.mjtWarning.mjWARN_BADQACC


class MujocoWorld(TorqueWorld):
    """The clock of every :class:`MujocoPlant` in it: the time step, and the step of all of
    them together (each robot is a MuJoCo model of its own: contacts are off)."""

    def __init__(self, physics_rate: float = 1000.0, gui: bool = False) -> None:
        if not (np.isfinite(physics_rate) and physics_rate > 0):
            raise ValueError("physics_rate must be a positive number")
        if gui:
            raise ValueError("gui: the MuJoCo plant has no viewer; watch it on the dashboard")
        self.dt = 1.0 / physics_rate
        self.gui = False
        self.plants: list[MujocoPlant] = []
        quiet_runtime_warnings()

    engine = "mujoco"

    def step(self) -> None:
        """One physics step of every plant (PlantFaultError if one blows up)."""
        for plant in self.plants:
            plant.advance()

    def load(self, spec: RobotSpec, joints: Sequence[str], **kwargs: Any) -> MujocoPlant:
        return MujocoPlant(spec, joints, world=self, **kwargs)

    def close(self) -> None:
        self.plants.clear()


class MujocoPlant(TorquePlant):
    """One robot in a :class:`MujocoWorld` (its own, or a shared one); the constructor's
    arguments mean what they mean for :class:`sim_bridge.plant.Plant`."""

    def __init__(
        self,
        spec: RobotSpec,
        joints: Sequence[str],
        physics_rate: float = 1000.0,
        friction: float | Sequence[float] = 0.0,
        payload_mass: float = 0.0,
        initial_positions: Sequence[float] | None = None,
        locked_positions: dict[str, float] | None = None,
        effort_limits: Sequence[float] | None = None,
        gui: bool = False,
        world: MujocoWorld | None = None,
        base_position: Sequence[float] = (0.0, 0.0, 0.0),
        base_orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
    ) -> None:
        """``base_orientation``: quaternion (x, y, z, w), PyBullet's order."""
        self.spec = spec
        self.joint_names = tuple(joints)
        self.n = len(self.joint_names)
        self._own_world = world is None
        self.world = MujocoWorld(physics_rate, gui) if world is None else world
        self.dt = self.world.dt
        with caught_warnings() as said:
            mj_spec = compile_spec(spec, self.joint_names, locked_positions or {}, self.dt)
            place_base(mj_spec, base_position, base_orientation)
            self.model = compile_model(mj_spec, spec.name)
        self.data = mujoco.MjData(self.model)
        m = self.model
        ids = [m.joint(name).id for name in self.joint_names]
        #: joint index of each dof (all dofs are controlled joints: the others are welded)
        self._joint_of_dof = np.argsort(m.jnt_dofadr[ids])
        self._qadr = index(m.jnt_qposadr[ids])
        self._vadr = index(m.jnt_dofadr[ids])
        self.effort_limits = self._limits(mj_spec, effort_limits)
        self._brake_force = np.where(
            np.isfinite(self.effort_limits), self.effort_limits, LOCK_FORCE
        )
        root = root_link(Path(spec.urdf_path))
        names = (m.body(b).name for b in range(1, m.nbody))  # body 0: the world
        self.link_names = {b: name for b, name in enumerate(names, 1) if name != root}
        self._payload_body = int(m.jnt_bodyid[ids[-1]])
        self._last_link = self._payload_body
        self._base_mass = float(m.body_mass[self._payload_body])
        self._start(friction)
        self.payload_mass = 0.0
        self.set_payload(payload_mass)
        self.initial_positions = per_joint(
            0.0 if initial_positions is None else initial_positions, self.n, "initial_positions"
        )
        #: What MuJoCo said reading and compiling the URDF (a joint limit it ignores, say).
        #: Nothing is replaced silently: what PyBullet replaces with a warning is refused here.
        self.warnings = [f"MuJoCo, loading {spec.name}: {text}" for text in said]
        self.reset()
        self.world.plants.append(self)

    def _limits(self, mj_spec: mujoco.MjSpec, given: Sequence[float] | None) -> np.ndarray:
        """The controller model's effort limits when given, else the URDF's (inf where it
        says 0 or nothing), as MuJoCo's URDF reader gives them."""
        if given is not None:
            limits = np.broadcast_to(np.asarray(given, dtype=float), (self.n,))
            if not np.all(limits > 0):  # inf: no limit (a URDF that says none)
                raise ValueError(f"effort limits must be > 0, got {limits.tolist()}")
            return limits.copy()
        urdf = np.array([mj_spec.joint(name).actfrcrange[1] for name in self.joint_names])
        return np.where(urdf > 0, urdf, np.inf)

    # -- perturbations -----------------------------------------------------------------
    def _coulomb_changed(self, was_on: bool) -> None:
        """MuJoCo's dry friction (``frictionloss``) of each joint is the Coulomb friction (a
        joint held by it creeps, see the module docstring)."""
        self._set_coulomb(self._coulomb_at(self._velocities()))

    def _set_coulomb(self, bounds: np.ndarray) -> None:
        self.model.dof_frictionloss[self._vadr] = bounds

    def _velocities(self) -> np.ndarray:
        return self.data.qvel[self._vadr]

    def _apply_wrench(self, t: float) -> None:
        """Jᵀw of the held and the scheduled wrench at time t, added to ``qfrc_applied``
        (J at the current configuration: the kinematics are brought up to date first)."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        if self._held is not None:
            self._push(*self._held)
        if self._schedule is not None:
            b, schedule = self._schedule
            self._push(b, *schedule.at(t))

    def _push(self, b: int, force: np.ndarray, torque: np.ndarray) -> None:
        d = self.data
        mujoco.mj_applyFT(self.model, d, force, torque, d.xpos[b], b, d.qfrc_applied)

    def set_payload(self, mass: float) -> None:
        """A point mass at the link's centre of mass: its mass grows, its inertia about that
        point does not. The constants MuJoCo derives from the masses (the constraints'
        impedance scale) are computed again, as if compiled with it."""
        if not np.isfinite(mass) or mass < 0:
            raise ValueError("payload_mass must be a finite value >= 0")
        self.model.body_mass[self._payload_body] = self._base_mass + mass
        mujoco.mj_setConst(self.model, mujoco.MjData(self.model))  # scratch: the state stays
        self.payload_mass = float(mass)

    # -- simulation --------------------------------------------------------------------
    def reset(self, q: Sequence[float] | None = None) -> None:
        """Put the controlled joints at q (default: the initial positions), at rest; MuJoCo's
        data (warm start, warnings, a fault) start afresh, so a run after a reset repeats."""
        q = self.initial_positions if q is None else per_joint(q, self.n, "q")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self._qadr] = q
        self._effort = np.zeros(self.n)

    def read_state(self, q: np.ndarray, dq: np.ndarray, effort: np.ndarray) -> None:
        """Write the state into the given arrays (the node's message image)."""
        q[:] = self.data.qpos[self._qadr]
        dq[:] = self.data.qvel[self._vadr]
        effort[:] = self._effort

    def advance(self) -> None:
        """One physics step of this plant's model (the world steps every plant with it);
        PlantFaultError if MuJoCo found the state blown up."""
        mujoco.mj_step(self.model, self.data)
        stat = self.data.warning[BAD_ACCELERATION]
        if stat.number:
            joint = self.joint_names[self._joint_of_dof[stat.lastinfo]]
            raise PlantFaultError(
                f"the MuJoCo simulation of {self.spec.name} blew up in the step from t = "
                f"{self.data.time - self.dt:.6g} s (non-finite or huge acceleration at joint "
                f"'{joint}'); it stays stopped until reset: lower the gains or raise "
                "physics_rate"
            )

    def _command(self, applied: np.ndarray) -> None:
        self.data.qfrc_applied[self._vadr] = applied

    def begin_brake(self) -> None:
        self.model.dof_frictionloss[self._vadr] = self._brake_force

    def apply_brake(self, k: int, t: float) -> None:
        self.data.qfrc_applied[self._vadr] = 0.0
        super().apply_brake(k, t)

    def end_brake(self) -> None:
        """The effort is what the brakes exerted in the last step (their constraint forces)."""
        d = self.data
        rows = d.efc_type == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        self._effort = np.zeros(self.n)
        self._effort[self._joint_of_dof[d.efc_id[rows]]] = d.efc_force[rows]
        self._set_coulomb(self._coulomb_at(d.qvel[self._vadr]))

    def close(self) -> None:
        """Leave the world (and close it when it is this plant's own)."""
        if self in self.world.plants:
            self.world.plants.remove(self)
        if self._own_world:
            self.world.close()


# -- the description, compiled -----------------------------------------------------------------
def index(addresses: np.ndarray) -> slice | np.ndarray:
    """``addresses`` as an index into MuJoCo's vectors: a slice when they are 0, 1, …, n − 1
    (the common case, and ~0.7 µs less per access than an index array)."""
    if np.array_equal(addresses, np.arange(addresses.size)):
        return slice(None)
    return addresses.copy()


def compile_spec(
    spec: RobotSpec, joints: tuple[str, ...], locked: dict[str, float], dt: float
) -> mujoco.MjSpec:
    """The MjSpec of the robot's URDF with every option of the module docstring set:
    geometry stripped, uncontrolled joints welded at ``locked`` (else 0), joint damping and
    friction zeroed; DescriptionError for an unphysical inertia or an unknown joint."""
    path = Path(spec.urdf_path)
    bad = [
        link
        for link, inertial in urdf_facts(path).inertials.items()
        if not inertia_is_physical(inertial.inertia)
    ]
    if bad:
        raise DescriptionError(
            f"links {bad} of {spec.name} have inertias that are not physical (triangle "
            "inequality or sign): MuJoCo cannot simulate them unchanged and never balances "
            "them here (PyBullet replaces them, with a warning); fix the URDF's <inertia>"
        )
    try:
        mj_spec = mujoco.MjSpec.from_string(dynamics_only(path.read_text(encoding="utf-8")))
    except ValueError as err:
        raise DescriptionError(f"MuJoCo cannot read {path.name}: {_one_line(err)}") from None
    set_compiler(mj_spec.compiler)
    set_options(mj_spec.option, dt)
    missing = [name for name in joints if name not in {j.name for j in mj_spec.joints}]
    if missing:
        raise ValueError(f"unknown joints {missing} in {path.name}")
    for equality in list(mj_spec.equalities):  # the URDF's <mimic>: PyBullet ignores them
        mj_spec.delete(equality)
    for joint in list(mj_spec.joints):
        if joint.name not in joints:
            weld(joint.parent, joint, float(locked.get(joint.name, 0.0)))
            mj_spec.delete(joint)
            continue
        joint.damping = np.zeros(3)
        joint.stiffness = np.zeros(3)
        joint.frictionloss = 0.0
        joint.armature = 0.0
        joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE  # clamped by the plant
        joint.solref_limit = joint.solref_friction = (2.0 * dt, 1.0)
        joint.solimp_limit = joint.solimp_friction = STIFF_SOLIMP
    return mj_spec


def dynamics_only(urdf: str) -> str:
    """The URDF text without ``<visual>``, ``<collision>`` and ``<mujoco>`` blocks."""
    root = etree.fromstring(urdf.encode("utf-8"))
    for node in list(root.iter("visual", "collision", "mujoco")):
        node.getparent().remove(node)
    return etree.tostring(root, encoding="unicode")


def set_compiler(compiler: mujoco.MjsCompiler) -> None:
    """The compiler options of the module docstring."""
    compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    compiler.balanceinertia = False
    compiler.boundmass = 0.0
    compiler.boundinertia = 0.0
    compiler.settotalmass = -1.0
    compiler.fusestatic = False
    compiler.autolimits = True
    compiler.discardvisual = True
    compiler.degree = False


def set_options(option: mujoco.MjOption, dt: float) -> None:
    """The physics options of the module docstring."""
    option.timestep = dt
    option.gravity = GRAVITY
    option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    flags = mujoco.mjtDisableBit
    option.disableflags = flags.mjDSBL_CONTACT | flags.mjDSBL_AUTORESET | flags.mjDSBL_EULERDAMP
    option.enableflags = 0
    option.density = option.viscosity = 0.0
    option.wind = np.zeros(3)
    option.solver = mujoco.mjtSolver.mjSOL_NEWTON
    option.iterations = 100
    option.tolerance = 1e-10
    option.jacobian = mujoco.mjtJacobian.mjJAC_DENSE


def weld(body: mujoco.MjsBody, joint: mujoco.MjsJoint, value: float) -> None:
    """Fold the joint's motion at ``value`` into the body's pose in its parent: the body frame
    moves by T_j (rotation about the joint's anchor, or translation along its axis)."""
    axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
    shift = value - joint.ref
    turn = np.array([1.0, 0.0, 0.0, 0.0])
    if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
        mujoco.mju_axisAngle2Quat(turn, axis, shift)
        anchor = np.asarray(joint.pos, dtype=float)
        moved = np.empty(3)
        mujoco.mju_rotVecQuat(moved, anchor, turn)
        offset = anchor - moved
    else:  # slide
        offset = shift * axis
    quat = np.asarray(body.quat, dtype=float) / np.linalg.norm(body.quat)
    shifted = np.empty(3)
    mujoco.mju_rotVecQuat(shifted, offset, quat)
    combined = np.empty(4)
    mujoco.mju_mulQuat(combined, quat, turn)
    body.pos = np.asarray(body.pos) + shifted
    body.quat = combined


def root_link(urdf_path: Path) -> str:
    """The URDF's root link: the parent that is no joint's child."""
    joints = urdf_facts(urdf_path).joints
    children = {j.child for j in joints}
    return next(j.parent for j in joints if j.parent not in children)


def place_base(
    mj_spec: mujoco.MjSpec, position: Sequence[float], orientation: Sequence[float]
) -> None:
    """Stand the fixed root link at ``position`` [m], turned by ``orientation`` (x, y, z, w):
    every body on the world moves with it (the root link itself, or, when the URDF names its
    root "world" and MuJoCo takes it for its world body, the links fixed to it)."""
    x, y, z, w = orientation
    base = np.array([w, x, y, z], dtype=float) / np.linalg.norm(orientation)
    for body in mj_spec.worldbody.bodies:
        rotated = np.empty(3)
        mujoco.mju_rotVecQuat(rotated, np.asarray(body.pos, dtype=float), base)
        combined = np.empty(4)
        mujoco.mju_mulQuat(combined, base, np.asarray(body.quat, dtype=float))
        body.pos = np.asarray(position, dtype=float) + rotated
        body.quat = combined


#: What MuJoCo said while stepping, newest last (:func:`quiet_runtime_warnings`).
RUNTIME_WARNINGS: deque[str] = deque(maxlen=16)


def quiet_runtime_warnings() -> None:
    """MuJoCo's warnings while stepping go to :data:`RUNTIME_WARNINGS` instead of stdout
    and ./MUJOCO_LOG.TXT (a file in whatever directory the user started the node from).
    The one that matters, a blown-up simulation, is the plant's :class:`PlantFaultError`,
    said in one line by whoever steps it. The handler is the process's: set once."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(RUNTIME_WARNINGS.append)


@contextmanager
def caught_warnings() -> Iterator[list[str]]:
    """MuJoCo's warnings while reading and compiling a description, into a list rather than
    printed and written to ./MUJOCO_LOG.TXT (the handler is the process's: set for that
    while only)."""
    said: list[str] = []
    handler = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(said.append)
    try:
        yield said
    finally:
        mujoco.set_mju_user_warning(handler)


def compile_model(mj_spec: mujoco.MjSpec, name: str) -> mujoco.MjModel:
    try:
        return mj_spec.compile()
    except ValueError as err:
        raise DescriptionError(f"MuJoCo cannot compile {name}: {_one_line(err)}") from None


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
