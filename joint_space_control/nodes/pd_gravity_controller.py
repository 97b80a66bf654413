"""``pd_gravity_controller``: PD + gravity compensation family (shared THEORY.md §2).

    τ = ĝ + u + K_P (q_d − q) − K_D q̇ + K_I ∫(q_d − q) dt,   clamped to the effort limits

``gravity_compensation`` picks ĝ: ``full`` g(q), ``none`` 0, ``desired`` g(q_d); ``ki`` > 0
adds integral action (with anti-windup); ``gravity_estimate`` is the constant u of the
iterative gravity estimation. All of them can be changed while the node runs.

Gains: ``kp``, ``kd`` [N·m/rad, N·m·s/rad] as given, or designed from ``omega_n``/``zeta``
(given, or the defaults ω_n = 10 rad/s, ζ = 1 when no gain is given) with the controller
model's inertia at the first measured configuration q₀ (:func:`~joint_space_control.laws.
gains.pd_gains_from_second_order`):

    K_P,i = B̂_ii(q₀) ω_n,i²,   K_D,i = 2 ζ_i B̂_ii(q₀) ω_n,i

so that each joint, about q₀, is a second-order loop with that ω_n and ζ whatever its
inertia. They are designed again at the configuration measured after a restart, and at q₀
when ω_n, ζ or the model parameters change; ``~/config`` shows the gains in force.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from joint_space_control.arrays import nonnegative, per_joint
from joint_space_control.laws.gains import GainChoice, PDGains, pd_gains_from_second_order
from joint_space_control.laws.pd_gravity import (
    GravityCompensation,
    TorqueSplit,
    integrate_error,
    pid_torque_split,
)
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.nodes import parameters as params
from joint_space_control.nodes.controller_base import JointController
from joint_space_control.nodes.node_main import run_node
from joint_space_control.trajectories.reference import Sample


@dataclass(frozen=True)
class PDConfig:
    model: RobotModel
    gains: PDGains | None  # None: designed from ω_n, ζ at the first measured configuration
    gravity: GravityCompensation
    gravity_estimate: np.ndarray
    choice: GainChoice
    ki: np.ndarray


class PDGravityController(JointController):
    LAW_PARAMETERS = (
        params.ParamSpec(
            "gravity_compensation",
            "full",
            "Gravity term: full = g(q) | none = pure PD | desired = g(q_d)",
        ),
        params.ParamSpec(
            "ki",
            0.0,
            "Integral gain K_I [N·m/(rad·s)], one value or one per joint, "
            ">= 0; anti-windup at the effort limits",
            dynamic=True,
        ),
        params.ParamSpec(
            "gravity_estimate",
            0.0,
            "Constant torque u [N·m] added to the law, one "
            "value or one per joint (iterative gravity estimation)",
            dynamic=True,
        ),
    )

    EXECUTABLE = "pd_gravity_controller"
    GAINS_NEED_CONFIGURATION = True

    def __init__(self, **kwargs: Any) -> None:
        self._integral: np.ndarray | None = None
        self._g_des_key: tuple[RobotModel, bytes] | None = None
        self._g_des = None
        super().__init__("pd_gravity_controller", **kwargs)
        self._integral = np.zeros(self.n)

    def build_config(self, values: dict[str, Any], model: RobotModel) -> PDConfig:
        n = self.n
        choice = self.gain_choice(values)
        ki = nonnegative(params.numbers(values, "ki"), n, "ki")
        gains = None if choice.designed else PDGains.build(n, choice.kp, choice.kd, ki)
        mode = GravityCompensation.parse(values["gravity_compensation"])
        estimate = per_joint(params.numbers(values, "gravity_estimate"), n, "gravity_estimate")
        return PDConfig(model, gains, mode, estimate, choice, ki)

    def design_gains(self, config: PDConfig, q0: np.ndarray) -> PDConfig:
        inertia = np.diag(config.model.inertia(q0))
        choice = config.choice
        gains = pd_gains_from_second_order(inertia, choice.omega_n, choice.zeta, config.ki)
        return replace(config, gains=gains)

    def law_name(self, config: PDConfig) -> str:
        return "pd_gravity"  # the variant: gravity_compensation, ki in "parameters"

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

    def after_command(
        self, ref: Sample, q: np.ndarray, tau_unclamped: np.ndarray, dt: float
    ) -> None:
        gains = self.config.gains
        if np.any(gains.ki > 0):
            self._integral = integrate_error(
                self._integral, ref.q - q, dt, gains, tau_unclamped, self.effort_limits
            )
        elif np.any(self._integral):
            self._integral = np.zeros(self.n)

    def reset_state(self) -> None:
        self._integral = np.zeros(self.n)


def main(args: list[str] | None = None) -> None:
    run_node(PDGravityController, args)


if __name__ == "__main__":
    main()
