r"""The PyBullet plant, without ROS: B(q) q̈ + C(q, q̇) q̇ + F q̇ + g(q) = τ (THEORY.md §1).

Torque control done so that the plant is exactly what its parameters say:
- the URDF is loaded with ``URDF_USE_INERTIA_FROM_FILE`` (PyBullet would otherwise recompute
  link inertias from the collision shapes), and every link's inertia is checked against the
  URDF afterwards: PyBullet silently replaces inertias it finds physically invalid, and
  :attr:`Plant.warnings` says so;
- PyBullet's own damping is switched off: the URDF's ``<dynamics damping>`` (the iiwa has
  0.5 N·m·s/rad on every joint) and Bullet's default link damping (0.04). The only friction
  is the explicit friction of :class:`Plant`: viscous, −F q̇ at every physics sub-step, and,
  when set, Coulomb friction and stiction (:meth:`Plant.set_coulomb_friction`);
- the default velocity motors of the controlled joints are disabled (zero force), so the
  commanded torque is all there is; it is held constant over every physics sub-step until
  the next command (zero-order hold) and clamped to the URDF effort limits;
- an external wrench on a link (:meth:`Plant.hold_wrench`, :meth:`Plant.set_wrench_schedule`)
  adds Jᵀw to the right-hand side (w applied to the robot, w = −h_e; :mod:`sim_bridge.wrench`);
- joints of the URDF that are not controlled (gripper fingers) are locked at the same
  positions as in the controller model, by stiff position servos;
- the payload is a point mass at the centre of mass of the last controlled joint's child
  link, the same place as :class:`~joint_space_control.model.dynamics.ModelPerturbation`.

Integration is Bullet's semi-implicit Euler at ``1 / physics_rate``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb

from joint_space_control.arrays import per_joint
from joint_space_control.model.description import DescriptionError
from joint_space_control.model.robots import RobotSpec, inertia_is_physical, urdf_facts
from sim_bridge.torque_plant import GRAVITY, LOCK_FORCE, TorquePlant, TorqueWorld
from sim_bridge.view import frame_view

#: Bullet's constraint solver while Coulomb friction is on: every iteration run (no early
#: stop on the residual), enough of them that a stuck arm stays stuck (drift ~1e-10 rad/s
#: on the iiwa, against ~3e-4 rad/s with the defaults, where the coupled joints creep).
FRICTION_SOLVER = {"numSolverIterations": 100, "solverResidualThreshold": 0.0}
#: PyBullet's defaults, restored when Coulomb friction is switched off again.
DEFAULT_SOLVER = {"numSolverIterations": 50, "solverResidualThreshold": 1.0e-7}


def rotation(quaternion: Sequence[float]) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w), PyBullet's order."""
    x, y, z, w = quaternion
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


class World(TorqueWorld):
    """One PyBullet physics client: gravity, the time step, and the step of every robot in
    it together (several :class:`Plant` may share one world: one clock for all)."""

    def __init__(self, physics_rate: float = 1000.0, gui: bool = False) -> None:
        if not (np.isfinite(physics_rate) and physics_rate > 0):
            raise ValueError("physics_rate must be a positive number")
        self.dt = 1.0 / physics_rate
        self.gui = gui
        self.client = pb.connect(pb.GUI if gui else pb.DIRECT)
        c = self.client
        pb.setGravity(*GRAVITY, physicsClientId=c)
        pb.setTimeStep(self.dt, physicsClientId=c)
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=c)
        self._friction: set[int] = set()  # plants with Coulomb friction (ids)

    engine = "pybullet"

    def step(self) -> None:
        pb.stepSimulation(physicsClientId=self.client)

    def load(self, spec: RobotSpec, joints: Sequence[str], **kwargs: Any) -> Plant:
        return Plant(spec, joints, world=self, **kwargs)

    def friction_solver(self, plant: Plant, on: bool) -> None:
        """Bullet's solver settings for Coulomb friction while any plant of the world has it
        (:data:`FRICTION_SOLVER`; the solver is the world's)."""
        was = bool(self._friction)
        if on:
            self._friction.add(id(plant))
        else:
            self._friction.discard(id(plant))
        if bool(self._friction) != was:
            solver = FRICTION_SOLVER if self._friction else DEFAULT_SOLVER
            pb.setPhysicsEngineParameter(**solver, physicsClientId=self.client)

    def close(self) -> None:
        if pb.isConnected(self.client):
            pb.disconnect(self.client)


class Plant(TorquePlant):
    """One robot, in a PyBullet world of its own or in a shared :class:`World`."""

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
        world: World | None = None,
        base_position: Sequence[float] = (0.0, 0.0, 0.0),
        base_orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
    ) -> None:
        """``world``: the world to load into (its rate and GUI apply; ``physics_rate`` and
        ``gui`` are then ignored), None: one of its own, closed with the plant.
        ``base_position`` [m] and ``base_orientation`` (quaternion x, y, z, w): where the
        fixed base stands in the world."""
        self.spec = spec
        self.joint_names = tuple(joints)
        self.n = len(self.joint_names)
        self._own_world = world is None
        self.world = World(physics_rate, gui) if world is None else world
        self.dt = self.world.dt
        self.client = self.world.client
        try:
            self._load(
                self.joint_names,
                locked_positions or {},
                effort_limits,
                tuple(base_position),
                tuple(base_orientation),
            )
        except Exception:
            if self._own_world:
                self.world.close()
            raise
        self._start(friction)
        self._origins: dict[int, np.ndarray] = {}  # link frame origin in the CoM frame
        info = pb.getDynamicsInfo(self.body, self._idx[-1], self.client)
        self._base_mass, self._last_inertia = info[0], list(info[2])
        self.payload_mass = 0.0
        self.set_payload(payload_mass)
        self.initial_positions = per_joint(
            0.0 if initial_positions is None else initial_positions, self.n, "initial_positions"
        )
        self.warnings = self._inertia_warnings()
        self.reset()
        if self._own_world and self.world.gui:  # the robot as it starts, no panels
            frame_view(self.client, [self.body])

    # -- set-up ------------------------------------------------------------------------
    def _load(
        self,
        joints: tuple[str, ...],
        locked: dict[str, float],
        effort_limits: Sequence[float] | None,
        base_position: tuple[float, ...],
        base_orientation: tuple[float, ...],
    ) -> None:
        c = self.client
        try:
            self.body = pb.loadURDF(
                str(self.spec.urdf_path),
                basePosition=base_position,
                baseOrientation=base_orientation,
                useFixedBase=True,
                flags=pb.URDF_USE_INERTIA_FROM_FILE,
                physicsClientId=c,
            )
        except pb.error as err:
            raise DescriptionError(f"PyBullet cannot load {self.spec.urdf_path}: {err}") from None
        by_name, self.link_names = {}, {}
        for j in range(pb.getNumJoints(self.body, c)):
            info = pb.getJointInfo(self.body, j, c)
            by_name[info[1].decode()] = (j, info)
            self.link_names[j] = info[12].decode()
        missing = [name for name in self.joint_names if name not in by_name]
        if missing:
            raise ValueError(f"unknown joints {missing} in {Path(self.spec.urdf_path).name}")
        self._idx = [by_name[name][0] for name in self.joint_names]
        self._last_link = self._idx[-1]
        if effort_limits is not None:  # the controller model's (override or URDF)
            limits = np.broadcast_to(np.asarray(effort_limits, dtype=float), (self.n,))
            if not np.all(limits > 0):  # inf: no limit (a URDF that says none)
                raise ValueError(f"effort limits must be > 0, got {limits.tolist()}")
            self.effort_limits = limits.copy()
        else:
            self.effort_limits = np.array(
                [by_name[name][1][10] if by_name[name][1][10] > 0 else np.inf for name in joints]
            )
        # A link without <inertial> is massless for Pinocchio (and the URDF spec); PyBullet
        # would give it 1 kg and a unit inertia.
        inertials = urdf_facts(Path(self.spec.urdf_path)).inertials
        for j, link in self.link_names.items():
            if link not in inertials:
                pb.changeDynamics(
                    self.body, j, mass=0.0, localInertiaDiagonal=[0.0] * 3, physicsClientId=c
                )
        for link in range(-1, pb.getNumJoints(self.body, c)):
            pb.changeDynamics(
                self.body,
                link,
                linearDamping=0.0,
                angularDamping=0.0,
                jointDamping=0.0,
                physicsClientId=c,
            )
        pb.setJointMotorControlArray(
            self.body, self._idx, pb.VELOCITY_CONTROL, forces=[0.0] * self.n, physicsClientId=c
        )
        self._locked = []
        for name, (j, info) in by_name.items():
            if name in self.joint_names or info[2] == pb.JOINT_FIXED:
                continue
            target = float(locked.get(name, 0.0))
            pb.resetJointState(self.body, j, target, 0.0, physicsClientId=c)
            pb.setJointMotorControl2(
                self.body,
                j,
                pb.POSITION_CONTROL,
                targetPosition=target,
                force=LOCK_FORCE,
                physicsClientId=c,
            )
            self._locked.append((j, target))

    def _inertia_warnings(self) -> list[str]:
        """Differences between the links PyBullet simulates and the URDF's inertials."""
        facts = urdf_facts(Path(self.spec.urdf_path))
        warnings = []
        for j, link in self.link_names.items():
            urdf = facts.inertials.get(link)
            if urdf is None:
                continue
            info = pb.getDynamicsInfo(self.body, j, self.client)
            mass = info[0] - (self.payload_mass if j == self._idx[-1] else 0.0)
            urdf_moments = np.sort(np.linalg.eigvalsh(urdf.inertia))
            pb_moments = np.sort(np.asarray(info[2]))
            scale = max(1e-9, float(np.max(np.abs(urdf_moments))))
            if not inertia_is_physical(urdf.inertia):
                warnings.append(
                    f"link '{link}': URDF inertia {urdf_moments.tolist()} is not physical "
                    f"(triangle inequality or sign); PyBullet simulates {pb_moments.tolist()} "
                    "while the controller model keeps the URDF values"
                )
            elif np.max(np.abs(urdf_moments - pb_moments)) > 1e-6 * scale or (
                abs(mass - urdf.mass) > 1e-9 * max(1.0, urdf.mass)
            ):
                warnings.append(
                    f"link '{link}': PyBullet uses mass {mass:g} kg, principal inertia "
                    f"{pb_moments.tolist()} but the URDF says {urdf.mass:g} kg, "
                    f"{urdf_moments.tolist()}"
                )
        return warnings

    # -- perturbations -----------------------------------------------------------------
    def _coulomb_changed(self, was_on: bool) -> None:
        """Each joint's velocity motor, with target speed 0 and at most the Coulomb bound, is
        the friction (Bullet's solver set for it while any plant of the world has one)."""
        if self._coulomb_on != was_on:
            self.world.friction_solver(self, self._coulomb_on)
        if self._coulomb_on or was_on:
            self._set_coulomb(self._coulomb_at(self._velocities()))

    def _velocities(self) -> np.ndarray:
        states = pb.getJointStates(self.body, self._idx, physicsClientId=self.client)
        return np.array([s[1] for s in states])

    def _set_coulomb(self, bounds: np.ndarray) -> None:
        """Velocity motors as Coulomb friction (force 0 when there is none)."""
        pb.setJointMotorControlArray(
            self.body,
            self._idx,
            pb.VELOCITY_CONTROL,
            targetVelocities=[0.0] * self.n,
            forces=bounds.tolist(),
            physicsClientId=self.client,
        )

    def _apply_wrench(self, t: float) -> None:
        """The held and the scheduled wrench at time t, for the next physics step (Bullet
        clears external forces after every step)."""
        if self._held is not None:
            self._push(*self._held)
        if self._schedule is not None:
            j, schedule = self._schedule
            force, torque = schedule.at(t)
            self._push(j, force, torque)

    def _push(self, j: int, force: np.ndarray, torque: np.ndarray) -> None:
        c = self.client
        # PyBullet's link frame is the centre of mass; the URDF link frame's origin is
        # computed from it here, in double precision (getLinkState's worldLinkFramePosition
        # is rounded to single precision: 3e-5 m off on the iiwa's last link).
        com, orientation = pb.getLinkState(
            self.body, j, computeForwardKinematics=True, physicsClientId=c
        )[:2]
        origin = np.asarray(com) + rotation(orientation) @ self._link_origin(j)
        pb.applyExternalForce(self.body, j, force.tolist(), origin.tolist(), pb.WORLD_FRAME, c)
        pb.applyExternalTorque(self.body, j, torque.tolist(), pb.WORLD_FRAME, c)

    def _link_origin(self, j: int) -> np.ndarray:
        """The origin of link j's URDF frame in its centre-of-mass frame, −R_cᵀ c, with
        (c, R_c) the inertial frame in the link frame."""
        origin = self._origins.get(j)
        if origin is None:
            c, quaternion = pb.getDynamicsInfo(self.body, j, physicsClientId=self.client)[3:5]
            origin = -rotation(quaternion).T @ np.asarray(c)
            self._origins[j] = origin
        return origin

    def set_payload(self, mass: float) -> None:
        if not np.isfinite(mass) or mass < 0:
            raise ValueError("payload_mass must be a finite value >= 0")
        # PyBullet recomputes the inertia from the collision shapes when only the mass is
        # changed; a point mass at the centre of mass leaves the inertia as it is.
        pb.changeDynamics(
            self.body,
            self._idx[-1],
            mass=self._base_mass + mass,
            localInertiaDiagonal=self._last_inertia,
            physicsClientId=self.client,
        )
        self.payload_mass = float(mass)

    # -- simulation --------------------------------------------------------------------
    def reset(self, q: Sequence[float] | None = None) -> None:
        """Put the controlled joints at q (default: the initial positions), at rest."""
        q = self.initial_positions if q is None else per_joint(q, self.n, "q")
        for j, value in zip(self._idx, q, strict=True):
            pb.resetJointState(self.body, j, float(value), 0.0, physicsClientId=self.client)
        for j, target in self._locked:
            pb.resetJointState(self.body, j, target, 0.0, physicsClientId=self.client)
        self._effort = np.zeros(self.n)

    def read_state(self, q: np.ndarray, dq: np.ndarray, effort: np.ndarray) -> None:
        """Write the state into the given arrays (the node's message image): no allocation
        per joint."""
        states = pb.getJointStates(self.body, self._idx, physicsClientId=self.client)
        positions, velocities, _, _ = zip(*states, strict=True)
        q[:] = positions
        dq[:] = velocities
        effort[:] = self._effort

    def _command(self, applied: np.ndarray) -> None:
        pb.setJointMotorControlArray(
            self.body,
            self._idx,
            pb.TORQUE_CONTROL,
            forces=applied.tolist(),
            physicsClientId=self.client,
        )

    def begin_brake(self) -> None:
        forces = np.where(np.isfinite(self.effort_limits), self.effort_limits, LOCK_FORCE)
        pb.setJointMotorControlArray(
            self.body,
            self._idx,
            pb.VELOCITY_CONTROL,
            targetVelocities=[0.0] * self.n,
            forces=forces.tolist(),
            physicsClientId=self.client,
        )

    def end_brake(self) -> None:
        c, body, idx = self.client, self.body, self._idx
        _, dq, _, applied = zip(*pb.getJointStates(body, idx, physicsClientId=c), strict=True)
        self._effort = np.array(applied)
        if self._coulomb_on:
            self._set_coulomb(self._coulomb_at(np.array(dq)))
        else:
            pb.setJointMotorControlArray(
                body, idx, pb.VELOCITY_CONTROL, forces=[0.0] * self.n, physicsClientId=c
            )

    def close(self) -> None:
        """Close the world when it is this plant's own."""
        if self._own_world:
            self.world.close()
