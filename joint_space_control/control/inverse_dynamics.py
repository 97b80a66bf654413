r"""Inverse dynamics and feedforward + PD (THEORY.md §3), as a controller object.

- ``inverse_dynamics``         τ = B̂(q)[q̈_d + K_D ė + K_P e] + n̂(q, q̇)            (eq. 15)
- ``feedforward_pd``           τ = B̂(q)q̈_d + Ĉ(q, q̇)q̇_d + F̂q̇_d + ĝ(q) + K_D ė + K_P e (eq. 17)
- ``precomputed_feedforward``  the same feedforward evaluated on the reference, + ĝ(q) + PD

(:mod:`joint_space_control.laws.inverse_dynamics`). Gains K_P = ω_n², K_D = 2ζω_n from ω_n,
ζ, or ``kp``/``kd`` as given (:func:`~joint_space_control.laws.gains.choose_gains`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from joint_space_control.control.controller import Controller
from joint_space_control.control.sampling import Sampling
from joint_space_control.laws.gains import GainChoice, PDGains, inverse_dynamics_gains
from joint_space_control.laws.inverse_dynamics import (
    LAWS,
    ModelLaw,
    precomputed_feedforward,
    reference_feedforward,
)
from joint_space_control.laws.split import TorqueSplit
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.trajectories.reference import Sample


@dataclass(frozen=True)
class IDConfig:
    model: RobotModel
    gains: PDGains
    law: ModelLaw
    choice: GainChoice


def gains_from_choice(choice: GainChoice, n: int) -> PDGains:
    """K_P = ω_n², K_D = 2ζω_n from ω_n, ζ (given or the defaults), else ``kp``/``kd``."""
    if choice.designed:
        return inverse_dynamics_gains(choice.omega_n, choice.zeta, n)
    return PDGains.build(n, choice.kp, choice.kd)


class InverseDynamicsController(Controller):
    """The model-based laws, with the reference feedforward cached per reference sample."""

    def __init__(
        self,
        config: IDConfig,
        effort_limits: np.ndarray,
        sampling: Sampling | None = None,
        gravity_by_hardware: bool = False,
    ) -> None:
        self._ff_key: tuple[RobotModel, bytes] | None = None
        self._ff: np.ndarray | None = None
        super().__init__(config, effort_limits, sampling, gravity_by_hardware)

    def compute(self, q: np.ndarray, dq: np.ndarray, ref: Sample, dt: float) -> TorqueSplit:
        config = self.config
        if config.law is ModelLaw.PRECOMPUTED_FEEDFORWARD:
            return precomputed_feedforward(
                config.model, q, dq, ref, config.gains, self._feedforward(config.model, ref)
            )
        return LAWS[config.law](config.model, q, dq, ref, config.gains)

    def _feedforward(self, model: RobotModel, ref: Sample) -> np.ndarray:
        """The reference's feedforward, computed once per distinct reference sample (a
        set-point or a hold needs it once)."""
        key = (model, np.concatenate((ref.q, ref.dq, ref.ddq)).tobytes())  # holds the model
        if key != self._ff_key:
            self._ff, self._ff_key = reference_feedforward(model, ref), key
        return self._ff
