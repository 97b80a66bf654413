r"""Inverse dynamics (computed torque) and its relatives (shared THEORY.md §3).

With the controller's model B̂, Ĉ, F̂, ĝ (n̂ = Ĉq̇ + F̂q̇ + ĝ), the error e = q_d − q and
the PD gains K_P, K_D (diagonal):

- ``inverse_dynamics`` (eq. 15): τ = B̂(q)[q̈_d + K_D ė + K_P e] + n̂(q, q̇). With a perfect
  model every joint obeys ë + K_D ė + K_P e = 0: decoupled, second order, ω_n = √K_P,
  ζ = K_D / (2√K_P).
- ``feedforward_pd`` (eq. 17): τ = B̂(q)q̈_d + Ĉ(q, q̇)q̇_d + F̂q̇_d + ĝ(q) + K_D ė + K_P e,
  globally asymptotically stable for tracking; with a constant q_d it is PD + g(q).
- ``precomputed_feedforward``: τ = B̂(q_d)q̈_d + Ĉ(q_d, q̇_d)q̇_d + F̂q̇_d + ĝ(q) + K_D ė
  + K_P e, the feedforward evaluated on the reference (cheaper; no stability proof).

Every law returns a :class:`TorqueSplit`: ``feedback`` is what the error produces (for eq. 15
B̂(q)(K_D ė + K_P e)), ``model`` the rest of the model's feedforward without gravity, and
``gravity`` ĝ(q). The model is any object with the :class:`RobotModel` methods used below
(``inertia``, ``coriolis``, ``gravity``, ``nonlinear_effects``, ``rnea``, ``friction``).
"""

from __future__ import annotations

import numpy as np

from joint_space_control.enums import ParsedEnum
from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.split import TorqueSplit
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.trajectories.reference import Sample


class ModelLaw(ParsedEnum, invalid="'law' is {value!r}; allowed: {allowed}"):
    INVERSE_DYNAMICS = "inverse_dynamics"
    FEEDFORWARD_PD = "feedforward_pd"
    PRECOMPUTED_FEEDFORWARD = "precomputed_feedforward"


def pd_acceleration(q: np.ndarray, dq: np.ndarray, ref: Sample, gains: PDGains) -> np.ndarray:
    """K_D (q̇_d − q̇) + K_P (q_d − q): the error feedback, as an acceleration [rad/s²] in
    eq. 15 and as a torque [N·m] in eq. 17."""
    return gains.kd * (ref.dq - dq) + gains.kp * (ref.q - q)


def inverse_dynamics(
    model: RobotModel, q: np.ndarray, dq: np.ndarray, ref: Sample, gains: PDGains
) -> TorqueSplit:
    """Eq. 15: τ = B̂(q)[q̈_d + K_D ė + K_P e] + n̂(q, q̇)."""
    inertia = model.inertia(q)
    gravity = model.gravity(q)
    feedback = inertia @ pd_acceleration(q, dq, ref, gains)
    feedforward = inertia @ ref.ddq + model.nonlinear_effects(q, dq) - gravity
    return TorqueSplit(feedback, feedforward, gravity)


def feedforward_pd(
    model: RobotModel, q: np.ndarray, dq: np.ndarray, ref: Sample, gains: PDGains
) -> TorqueSplit:
    """Eq. 17: τ = B̂(q)q̈_d + Ĉ(q, q̇)q̇_d + F̂q̇_d + ĝ(q) + K_D ė + K_P e."""
    feedforward = (
        model.inertia(q) @ ref.ddq + model.coriolis(q, dq) @ ref.dq + model.friction * ref.dq
    )
    return TorqueSplit(pd_acceleration(q, dq, ref, gains), feedforward, model.gravity(q))


def reference_feedforward(model: RobotModel, ref: Sample) -> np.ndarray:
    """B̂(q_d)q̈_d + Ĉ(q_d, q̇_d)q̇_d + F̂q̇_d: the model on the reference, without gravity."""
    return model.rnea(ref.q, ref.dq, ref.ddq) - model.gravity(ref.q)


def precomputed_feedforward(
    model: RobotModel,
    q: np.ndarray,
    dq: np.ndarray,
    ref: Sample,
    gains: PDGains,
    feedforward: np.ndarray | None = None,
) -> TorqueSplit:
    """τ = B̂(q_d)q̈_d + Ĉ(q_d, q̇_d)q̇_d + F̂q̇_d + ĝ(q) + K_D ė + K_P e. ``feedforward``
    is :func:`reference_feedforward` of ``ref`` when the caller has it already (it depends
    on the reference only, so it can be computed ahead or cached)."""
    if feedforward is None:
        feedforward = reference_feedforward(model, ref)
    return TorqueSplit(pd_acceleration(q, dq, ref, gains), feedforward, model.gravity(q))


LAWS = {
    ModelLaw.INVERSE_DYNAMICS: inverse_dynamics,
    ModelLaw.FEEDFORWARD_PD: feedforward_pd,
    ModelLaw.PRECOMPUTED_FEEDFORWARD: precomputed_feedforward,
}
