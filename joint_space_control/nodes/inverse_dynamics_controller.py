"""``inverse_dynamics_controller``: inverse dynamics and feedforward + PD (THEORY.md §3).

``law`` picks (see :mod:`joint_space_control.laws.inverse_dynamics`):

- ``inverse_dynamics``         τ = B̂(q)[q̈_d + K_D ė + K_P e] + n̂(q, q̇)            (eq. 15)
- ``feedforward_pd``           τ = B̂(q)q̈_d + Ĉ(q, q̇)q̇_d + F̂q̇_d + ĝ(q) + K_D ė + K_P e (eq. 17)
- ``precomputed_feedforward``  the same feedforward evaluated on the reference, + ĝ(q) + PD

Gains are per-joint ``omega_n``/``zeta`` (K_P = ω_n², K_D = 2ζω_n) when ``omega_n`` > 0, else
``kp``/``kd`` when ``kp`` > 0, else the defaults ω_n = 10 rad/s, ζ = ``zeta`` (1)
(:func:`~joint_space_control.laws.gains.choose_gains`). The hatted model is the controller's
own Pinocchio model of the URDF with the ``model_*`` perturbations. Everything can be
changed while the node runs.

The parameters and the configuration they give are ROS-free
(:data:`~joint_space_control.control.configure.INVERSE_DYNAMICS`); this is the node around
them.
"""

from __future__ import annotations

from typing import Any

from joint_space_control.control.configure import INVERSE_DYNAMICS
from joint_space_control.nodes.controller_base import JointController
from joint_space_control.ros.node_main import run_node


class InverseDynamicsControllerNode(JointController):
    """The ROS wrapper of
    :class:`~joint_space_control.control.inverse_dynamics.InverseDynamicsController`."""

    KIND = INVERSE_DYNAMICS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(self.KIND.executable, **kwargs)


def main(args: list[str] | None = None) -> None:
    run_node(InverseDynamicsControllerNode, args)


if __name__ == "__main__":
    main()
