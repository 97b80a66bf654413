r"""PD control with gravity compensation and its variants (shared THEORY.md §2).

    τ = ĝ + K_P (q_d − q) − K_D q̇ + K_I ξ,      ξ̇ = q_d − q          [N·m]

with the gravity term ĝ chosen by the mode:
- ``full``: ĝ = g(q), global asymptotic stability for any K_P ≻ 0, K_D ≻ 0;
- ``none``: ĝ = 0, pure PD: the arm settles at q_e with g(q_e) = K_P (q_d − q_e);
- ``desired``: ĝ = g(q_d), constant, stable when every K_P,i > α ≥ ‖∂g/∂q‖.
A constant torque u (the iterative gravity estimate u_i) can be added to any mode.
"""

from __future__ import annotations

import numpy as np

from joint_space_control.enums import ParsedEnum
from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.split import TorqueSplit


class GravityCompensation(
    ParsedEnum, invalid="gravity_compensation '{value}' is not one of: {allowed}"
):
    FULL = "full"
    NONE = "none"
    DESIRED = "desired"


def pid_torque_split(
    q: np.ndarray,
    dq: np.ndarray,
    q_des: np.ndarray,
    integral: np.ndarray,
    gains: PDGains,
    gravity: np.ndarray,
) -> TorqueSplit:
    r"""τ = ĝ + K_P (q_d − q) − K_D q̇ + K_I ξ, split into feedback and gravity parts."""
    feedback = gains.kp * (q_des - q) - gains.kd * dq + gains.ki * integral
    return TorqueSplit(feedback, np.zeros_like(feedback), gravity)


def integrate_error(
    integral: np.ndarray,
    error: np.ndarray,
    dt: float,
    gains: PDGains,
    tau_unclamped: np.ndarray,
    effort_limits: np.ndarray,
) -> np.ndarray:
    r"""One step of ξ̇ = q_d − q with anti-windup (conditional integration and clamping).

    A joint whose command is saturated does not integrate an error that would push it
    further into saturation; and |K_I ξ| never exceeds the effort limit. Returns a new array.
    """
    pushing = np.sign(gains.ki * error) == np.sign(tau_unclamped)
    saturated = (np.abs(tau_unclamped) >= effort_limits) & pushing
    updated = np.where(saturated, integral, integral + error * dt)
    with np.errstate(divide="ignore"):
        bound = np.where(gains.ki > 0, effort_limits / gains.ki, np.inf)
    return np.where(gains.ki > 0, np.clip(updated, -bound, bound), 0.0)


def iterative_gravity_estimate(
    kp: np.ndarray, q_d: np.ndarray, q_e: np.ndarray, previous: np.ndarray
) -> np.ndarray:
    r"""The next constant of the iterative gravity estimation (THEORY.md §2):

        u_i = K_P (q_d − q_e,i) + u_{i−1}      [N·m]

    at the equilibrium q_e,i the loop τ = u_{i−1} + K_P (q_d − q) − K_D q̇ came to rest in;
    u_i → g(q_d) and q_e,i → q_d when every K_P,i > α."""
    return kp * (q_d - q_e) + previous
