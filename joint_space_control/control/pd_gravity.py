r"""PD + gravity compensation family (shared THEORY.md §2), as a controller object.

    τ = ĝ + u + K_P (q_d − q) − K_D q̇ + K_I ∫(q_d − q) dt,   clamped to the effort limits

``gravity`` picks ĝ: ``full`` g(q), ``none`` 0, ``desired`` g(q_d); K_I > 0 adds integral
action (with anti-windup at the effort limits); u is the constant ``gravity_estimate`` of the
iterative gravity estimation.

Gains: ``kp``, ``kd`` as given, or designed from ω_n, ζ with the controller model's inertia at
the first measured configuration q₀ (:func:`~joint_space_control.laws.gains.
pd_gains_from_second_order`): K_P,i = B̂_ii(q₀) ω_n,i², K_D,i = 2 ζ_i B̂_ii(q₀) ω_n,i, so
that each joint, about q₀, is a second-order loop with that ω_n and ζ whatever its inertia.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from joint_space_control.control.controller import Controller
from joint_space_control.control.sampling import Sampling
from joint_space_control.laws.gains import GainChoice, PDGains, pd_gains_from_second_order
from joint_space_control.laws.pd_gravity import (
    GravityCompensation,
    integrate_error,
    pid_torque_split,
)
from joint_space_control.laws.split import TorqueSplit
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.trajectories.reference import Sample


@dataclass(frozen=True)
class PDConfig:
    model: RobotModel
    gains: PDGains | None  # None: designed from ω_n, ζ at the first measured configuration
    gravity: GravityCompensation
    gravity_estimate: np.ndarray
    choice: GainChoice
    ki: np.ndarray


class PDGravityController(Controller):
    """PD + ĝ + u (+ K_I ∫e) with its integrator and the g(q_d) cache."""

    GAINS_NEED_CONFIGURATION = True

    def __init__(
        self,
        config: PDConfig,
        effort_limits: np.ndarray,
        sampling: Sampling | None = None,
        gravity_by_hardware: bool = False,
    ) -> None:
        self._g_des_key: tuple[RobotModel, bytes] | None = None
        self._g_des: np.ndarray | None = None
        super().__init__(config, effort_limits, sampling, gravity_by_hardware)

    def design_gains(self, config: PDConfig, q0: np.ndarray) -> PDConfig:
        inertia = np.diag(config.model.inertia(q0))
        choice = config.choice
        gains = pd_gains_from_second_order(inertia, choice.omega_n, choice.zeta, config.ki)
        return replace(config, gains=gains)

    def _gravity(self, q: np.ndarray, q_des: np.ndarray, config: PDConfig) -> np.ndarray:
        mode = config.gravity
        if mode is GravityCompensation.FULL:
            return config.model.gravity(q)
        if mode is GravityCompensation.DESIRED:
            key = (config.model, q_des.tobytes())  # holds the model: no id reuse
            if key != self._g_des_key:  # g(q_d) is constant for a set-point: compute once
                self._g_des, self._g_des_key = config.model.gravity(q_des), key
            return self._g_des
        return np.zeros(self.n)

    def compute(self, q: np.ndarray, dq: np.ndarray, ref: Sample, dt: float) -> TorqueSplit:
        config = self.config
        gravity = self._gravity(q, ref.q, config) + config.gravity_estimate
        return pid_torque_split(q, dq, ref.q, self._integral, config.gains, gravity)

    def after_step(self, ref: Sample, q: np.ndarray, unclamped: np.ndarray, dt: float) -> None:
        gains = self.config.gains
        if gains is not self._ki_of:  # whether K_I acts: once per gain set, not per step
            self._ki_of, self._ki_on = gains, bool(np.any(gains.ki > 0))
        if self._ki_on:
            self._integral = integrate_error(
                self._integral, ref.q - q, dt, gains, unclamped, self.effort_limits
            )
            self._integral_zero = False
        elif not self._integral_zero:  # K_I set back to 0: the integral goes
            self.reset_state()

    def reset_state(self) -> None:
        self._integral = np.zeros(self.n)
        self._integral_zero = True
        self._ki_of: PDGains | None = None
        self._ki_on = False
