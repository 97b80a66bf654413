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

The parameters and the configuration they give are ROS-free
(:data:`~joint_space_control.control.configure.PD_GRAVITY`); this is the node around them.
"""

from __future__ import annotations

from typing import Any

from joint_space_control.control.configure import PD_GRAVITY
from joint_space_control.nodes.controller_base import JointController
from joint_space_control.ros.node_main import run_node


class PDGravityControllerNode(JointController):
    """The ROS wrapper of :class:`~joint_space_control.control.pd_gravity.PDGravityController`."""

    KIND = PD_GRAVITY

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.KIND.executable, **kwargs)


def main(args: list[str] | None = None) -> None:
    run_node(PDGravityControllerNode, args)


if __name__ == "__main__":
    main()
