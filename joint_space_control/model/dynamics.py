r"""Rigid-body dynamics of the controlled joints with Pinocchio (shared THEORY.md §1).

    B(q) q̈ + C(q, q̇) q̇ + F q̇ + g(q) = τ,        n(q, q̇) = C(q, q̇) q̇ + F q̇ + g(q)

Vectors are in the order of the controlled joints (the ``joints`` list), one coordinate per
joint (an angle for revolute and continuous joints, a length for prismatic ones), whatever
order Pinocchio uses inside. Joints of the URDF that are not controlled (gripper fingers,
say) are locked at fixed positions (:attr:`RobotModel.locked_positions`); the simulator
holds them at the same positions.

Viscous friction F is not part of a URDF: it is an explicit, separate setting of each
model, so that the controller's F̂ and the plant's F can differ on purpose. The same holds
for the other deliberate perturbations (:class:`ModelPerturbation`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from joint_space_control.arrays import per_joint
from joint_space_control.model.description import DescriptionError
from joint_space_control.model.robots import (
    ACTUATED_JOINT_TYPES,
    RobotSpec,
    urdf_facts,
)


@dataclass(frozen=True)
class ModelPerturbation:
    """Deliberate differences between a model and the URDF.

    - ``friction``: viscous friction F (diagonal) [N·m·s/rad], per joint or one value;
    - ``mass_scale``: multiplies the mass *and* rotational inertia of the link moved by each
      controlled joint (a density error), per joint or one value; centres of mass unchanged;
    - ``payload_mass``: a point mass [kg] at the centre of mass of the child link of the last
      controlled joint (so it adds no rotational inertia about that point);
    - ``gravity``: False models a world without gravity (g(q) ≡ 0).
    """

    friction: float | Sequence[float] = 0.0
    mass_scale: float | Sequence[float] = 1.0
    payload_mass: float = 0.0
    gravity: bool = True


class RobotModel:
    """Pinocchio model of the controlled joints of one URDF, with B, C, g, n and rnea."""

    def __init__(
        self,
        spec: RobotSpec,
        joints: Sequence[str] | None = None,
        perturbation: ModelPerturbation | None = None,
        locked_positions: dict[str, float] | None = None,
        effort_limits: float | Sequence[float] | None = None,
    ) -> None:
        self.spec = spec
        pert = perturbation or ModelPerturbation()
        self.perturbation = pert
        try:
            full = pin.buildModelFromUrdf(str(spec.urdf_path))
        except (RuntimeError, ValueError) as err:
            raise DescriptionError(
                f"Pinocchio cannot read {Path(spec.urdf_path).name}: {' '.join(str(err).split())}"
            ) from None
        joints = tuple(joints) if joints else spec.default_joints
        self.joint_names = _check_joint_names(joints, full, Path(spec.urdf_path))
        self.locked_positions = _locked_positions(full, self.joint_names, locked_positions)
        self.model = _reduce(full, self.locked_positions)
        self.n = len(self.joint_names)
        if self.model.nv != self.n:  # pragma: no cover - guarded by _check_joint_names
            raise ValueError("reduced model does not match the controlled joints")
        self._joint_ids = [self.model.getJointId(name) for name in self.joint_names]
        self._apply_perturbation(pert)
        self.data = self.model.createData()
        self._build_index_maps()
        self.friction = per_joint(pert.friction, self.n, "friction")
        if np.any(self.friction < 0):
            raise ValueError("friction must be >= 0")
        self._has_friction = bool(np.any(self.friction))
        self._effort_override = effort_limits
        self._effort_limits, self.warnings = self._limits(effort_limits)

    def with_perturbation(self, perturbation: ModelPerturbation) -> RobotModel:
        """The same robot, joints, locked positions and effort limits, another perturbation."""
        if perturbation == self.perturbation:
            return self
        return RobotModel(
            self.spec, self.joint_names, perturbation, self.locked_positions, self._effort_override
        )

    # -- limits ----------------------------------------------------------------------
    @property
    def effort_limits(self) -> np.ndarray:
        """Effort limits [N·m or N] of the controlled joints: the ``effort_limits`` given, else
        the URDF's (inf where it says 0 or nothing: see :attr:`warnings`)."""
        return self._effort_limits.copy()

    def _limits(self, override: float | Sequence[float] | None) -> tuple[np.ndarray, list[str]]:
        if override is not None and np.size(override) > 0:
            limits = per_joint(override, self.n, "effort_limits")
            if not np.all(limits > 0):
                raise ValueError(f"'effort_limits' must be > 0, got {limits.tolist()}")
            return limits, []
        iv = [self.model.joints[j].idx_v for j in self._joint_ids]
        lim = np.array(self.model.effortLimit[iv])
        unset = [name for name, value in zip(self.joint_names, lim, strict=True) if value <= 0]
        warnings = []
        if unset:
            warnings.append(
                f"joints {unset} have no effort limit in the description of {self.spec.name} "
                "(effort 0 or missing): their torque is not limited; set 'effort_limits' "
                "(one value or one per joint) to limit it"
            )
        return np.where(lim > 0, lim, np.inf), warnings

    @property
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) position limits; ±inf for continuous joints."""
        lo, hi = [], []
        for j, continuous in zip(self._joint_ids, self._continuous, strict=True):
            if continuous:
                lo.append(-np.inf)
                hi.append(np.inf)
            else:
                iq = self.model.joints[j].idx_q
                lo.append(self.model.lowerPositionLimit[iq])
                hi.append(self.model.upperPositionLimit[iq])
        return np.array(lo), np.array(hi)

    def clip_into_limits(self, q: Sequence[float]) -> tuple[np.ndarray, list[str]]:
        """q clipped into the position limits, and the joints that had to be clipped."""
        q = np.asarray(q, dtype=float)
        lower, upper = self.position_limits
        clipped = np.clip(q, lower, upper)
        outside = [name for name, a, b in zip(self.joint_names, q, clipped, strict=True) if a != b]
        return clipped, outside

    # -- dynamics --------------------------------------------------------------------
    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration vector for joint coordinates q (cos/sin for continuous)."""
        qc = self._q_neutral.copy()
        qc[self._iq_simple] = q[self._simple]
        if self._has_continuous:
            angles = q[self._cont]
            qc[self._iq_cont] = np.cos(angles)
            qc[self._iq_cont + 1] = np.sin(angles)
        return qc

    # The methods below run in every control tick: Pinocchio's own work is a few µs, so the
    # conversions around it are kept to what the joint order needs. Pinocchio returns fresh
    # arrays (they do not alias ``data``), which are handed out as they are.
    def _q(self, q: np.ndarray) -> np.ndarray:
        """:meth:`configuration` without a copy when the coordinates are Pinocchio's own."""
        return np.asarray(q, dtype=float) if self._q_plain else self.configuration(q)

    def _v(self, x: np.ndarray) -> np.ndarray:
        """Joint-order vector → Pinocchio velocity order."""
        if self._identity:
            return np.asarray(x, dtype=float)
        out = np.empty(self.n)
        out[self._iv] = x
        return out

    def _out(self, x: np.ndarray) -> np.ndarray:
        """Pinocchio velocity order → joint order (a fresh array from Pinocchio's)."""
        return x if self._identity else x[self._iv]

    def _plus_friction(self, x: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return x + self.friction * dq if self._has_friction else x

    def inertia(self, q: np.ndarray) -> np.ndarray:
        """B(q) [kg·m²], symmetric positive definite (crba fills the upper triangle)."""
        upper = pin.crba(self.model, self.data, self._q(q))
        full = np.where(self._strictly_lower, upper.T, upper)
        return full if self._identity else full[self._iv_grid]

    def coriolis(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """C(q, q̇) such that Ḃ − 2C is skew-symmetric [N·m·s]."""
        c = pin.computeCoriolisMatrix(self.model, self.data, self._q(q), self._v(dq))
        return c if self._identity else c[self._iv_grid]

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """g(q) = ∂U/∂q [N·m]."""
        return self._out(pin.computeGeneralizedGravity(self.model, self.data, self._q(q)))

    def nonlinear_effects(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """n(q, q̇) = C(q, q̇) q̇ + F q̇ + g(q) [N·m]."""
        nle = pin.nonLinearEffects(self.model, self.data, self._q(q), self._v(dq))
        return self._plus_friction(self._out(nle), dq)

    def rnea(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """Inverse dynamics τ = B(q) q̈ + C(q, q̇) q̇ + F q̇ + g(q) [N·m]."""
        tau = pin.rnea(self.model, self.data, self._q(q), self._v(dq), self._v(ddq))
        return self._plus_friction(self._out(tau), dq)

    def link_jacobian(self, q: np.ndarray, link: str) -> np.ndarray:
        r"""J(q) of the frame of ``link`` (a URDF link name), 6 × n in joint order: the
        velocity of the frame's origin and the angular velocity, both in world axes
        (Pinocchio's LOCAL_WORLD_ALIGNED), [linear; angular]. A wrench w = (f, μ) applied
        to the robot at that origin, in world axes, is the joint torque Jᵀ w; the wrench
        h_e = −w the robot exerts on its environment enters the dynamics as −Jᵀ h_e."""
        if not self.model.existFrame(link, pin.BODY):
            raise ValueError(f"no link '{link}' in the model of {self.spec.name}")
        frame = self.model.getFrameId(link, pin.BODY)
        qc = self._q(q)
        pin.computeJointJacobians(self.model, self.data, qc)
        pin.updateFramePlacements(self.model, self.data)
        jac = pin.getFrameJacobian(self.model, self.data, frame, pin.LOCAL_WORLD_ALIGNED)
        return jac if self._identity else jac[:, self._iv]

    # -- construction helpers --------------------------------------------------------
    def _apply_perturbation(self, pert: ModelPerturbation) -> None:
        scale = per_joint(pert.mass_scale, self.n, "mass_scale")
        if np.any(scale <= 0):
            raise ValueError("mass_scale must be > 0")
        for jid, s in zip(self._joint_ids, scale, strict=True):
            inertia = self.model.inertias[jid]
            self.model.inertias[jid] = pin.Inertia(
                s * inertia.mass, inertia.lever, s * inertia.inertia
            )
        if not np.isfinite(pert.payload_mass) or pert.payload_mass < 0:
            raise ValueError("payload_mass must be a finite value >= 0")
        if pert.payload_mass > 0:
            jid = self._joint_ids[-1]
            self.model.inertias[jid] = self.model.inertias[jid] + pin.Inertia(
                pert.payload_mass, self.payload_point(), np.zeros((3, 3))
            )
        if not pert.gravity:
            self.model.gravity.linear = np.zeros(3)

    def payload_point(self) -> np.ndarray:
        """Where the payload sits, in the frame of the last controlled joint [m]: the centre
        of mass of that joint's child link."""
        last = self.joint_names[-1]
        facts = urdf_facts(Path(self.spec.urdf_path))
        child = next(j.child for j in facts.joints if j.name == last)
        frame = self.model.frames[self.model.getFrameId(child)]
        com = facts.inertials[child].com if child in facts.inertials else np.zeros(3)
        return frame.placement.act(com)

    def _build_index_maps(self) -> None:
        self._q_neutral = pin.neutral(self.model)
        joints = [self.model.joints[j] for j in self._joint_ids]
        self._iv = np.array([j.idx_v for j in joints])
        self._identity = bool(np.array_equal(self._iv, np.arange(self.n)))
        self._continuous = np.array([j.nq == 2 for j in joints])
        self._simple = np.flatnonzero(~self._continuous)
        self._cont = np.flatnonzero(self._continuous)
        self._iq_simple = np.array([joints[i].idx_q for i in self._simple], dtype=int)
        self._iq_cont = np.array([joints[i].idx_q for i in self._cont], dtype=int)
        self._has_continuous = self._cont.size > 0
        # Pinocchio's configuration is the joint vector itself (no continuous joint, same
        # order): the common case, where q goes to Pinocchio as it is.
        self._q_plain = (
            not self._has_continuous
            and self.model.nq == self.n
            and np.array_equal(self._iq_simple, np.arange(self.n))
        )
        self._iv_grid = np.ix_(self._iv, self._iv)
        self._strictly_lower = np.tri(self.n, k=-1, dtype=bool)


def _check_joint_names(joints: Sequence[str], full: pin.Model, urdf: Path) -> tuple[str, ...]:
    facts = {j.name: j for j in urdf_facts(urdf).joints}
    if len(set(joints)) != len(joints):
        raise ValueError(f"duplicated joint names in {list(joints)}")
    for name in joints:
        if name not in facts:
            raise ValueError(f"unknown joint '{name}' (not in {urdf.name})")
        if facts[name].type not in ACTUATED_JOINT_TYPES or facts[name].mimic:
            raise ValueError(f"joint '{name}' is {facts[name].type}, not an actuated joint")
        if not full.existJointName(name):  # pragma: no cover - pinocchio drops nothing else
            raise ValueError(f"joint '{name}' is not in the Pinocchio model")
    return tuple(joints)


def _locked_positions(
    full: pin.Model, controlled: tuple[str, ...], given: dict[str, float] | None
) -> dict[str, float]:
    """Positions of the uncontrolled 1-DoF joints: as given, else 0 clamped into limits."""
    given = dict(given or {})
    locked = {}
    for jid in range(1, full.njoints):
        name = full.names[jid]
        if name in controlled:
            continue
        joint = full.joints[jid]
        if joint.nq != 1:
            raise ValueError(f"uncontrolled joint '{name}' has nq={joint.nq}; control it")
        lo, hi = full.lowerPositionLimit[joint.idx_q], full.upperPositionLimit[joint.idx_q]
        value = float(given.pop(name, 0.0))
        locked[name] = float(np.clip(value, lo, hi)) if lo <= hi else value
    if given:
        raise ValueError(f"locked_positions names unknown or controlled joints: {list(given)}")
    return locked


def _reduce(full: pin.Model, locked: dict[str, float]) -> pin.Model:
    if not locked:
        return full
    reference = pin.neutral(full)
    ids = []
    for name, value in locked.items():
        jid = full.getJointId(name)
        reference[full.joints[jid].idx_q] = value
        ids.append(jid)
    return pin.buildReducedModel(full, ids, reference)
