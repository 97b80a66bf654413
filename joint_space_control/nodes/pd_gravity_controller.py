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

from typing import Any

from joint_space_control.control.pd_gravity import PDConfig, PDGravityController
from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.pd_gravity import GravityCompensation
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.nodes.controller_base import JointController
from joint_space_control.ros import parameters as params
from joint_space_control.ros.node_main import run_node


class PDGravityControllerNode(JointController):
    """The ROS wrapper of :class:`~joint_space_control.control.pd_gravity.PDGravityController`."""

    CORE = PDGravityController
    LAW_PARAMETERS = (
        params.ParamSpec(
            "gravity_compensation",
            "full",
            "Gravity term: full = g(q) | none = pure PD | desired = g(q_d)",
            choices=tuple(mode.value for mode in GravityCompensation),
        ),
        params.ParamSpec(
            "ki",
            0.0,
            "Integral gain K_I; anti-windup at the effort limits",
            dynamic=True,
            unit="N·m/(rad·s)",
            minimum=0.0,
            maximum=1e6,
        ),
        params.ParamSpec(
            "gravity_estimate",
            0.0,
            "Constant torque u added to the law (iterative gravity estimation)",
            dynamic=True,
            unit="N·m",
            minimum=-1e6,
            maximum=1e6,
        ),
    )

    EXECUTABLE = "pd_gravity_controller"

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.EXECUTABLE, **kwargs)

    def build_config(self, values: dict[str, Any], model: RobotModel) -> PDConfig:
        n = self.n
        choice = self.gain_choice(values)
        ki = params.value(values, "ki", n)
        gains = None if choice.designed else PDGains.build(n, choice.kp, choice.kd, ki)
        mode = GravityCompensation.parse(params.value(values, "gravity_compensation"))
        estimate = params.value(values, "gravity_estimate", n)
        return PDConfig(model, gains, mode, estimate, choice, ki)

    def law_name(self, config: PDConfig) -> str:
        return "pd_gravity"  # the variant: gravity_compensation, ki in "parameters"


def main(args: list[str] | None = None) -> None:
    run_node(PDGravityControllerNode, args)


if __name__ == "__main__":
    main()
