r"""Gains ↔ second order: (K_P, K_D) ↔ (ω_n, ζ) of ë + K_D ė + K_P e = 0 (THEORY.md §3).

The relation is used in both directions by different layers: the gain design of the control
laws (:mod:`joint_space_control.laws.gains`) turns a wanted ω_n and ζ into gains, and the
analysis (:mod:`joint_space_control.analysis.metrics`, ``run_metrics``) turns a controller's
gains into the second-order response the theory predicts. It lives with the laws, the lower
of the two, so that the laws need nothing from the analysis. Numpy only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def gains_to_second_order(kp: ArrayLike, kd: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(ω_n [rad/s], ζ) of ë + K_D ė + K_P e = 0: ω_n = √K_P, ζ = K_D / (2√K_P).

    K_P [1/s²] > 0 and K_D [1/s] ≥ 0 are the (diagonal) gains of the inverse-dynamics outer
    loop, THEORY.md §3 eq. 15; arrays broadcast together.
    """
    kp = np.asarray(kp, dtype=float)
    kd = np.asarray(kd, dtype=float)
    if not (np.all(np.isfinite(kp)) and np.all(np.isfinite(kd))):
        raise ValueError("'kp' and 'kd' must be finite")
    if np.any(kp <= 0.0) or np.any(kd < 0.0):
        raise ValueError(f"need kp > 0 and kd >= 0, got kp={kp.tolist()}, kd={kd.tolist()}")
    omega_n = np.sqrt(kp)
    return omega_n, kd / (2.0 * omega_n)


def second_order_to_gains(omega_n: ArrayLike, zeta: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(K_P, K_D) = (ω_n², 2ζω_n): the inverse of :func:`gains_to_second_order`."""
    omega_n, zeta = second_order_parameters(omega_n, zeta)
    return omega_n**2, 2.0 * zeta * omega_n


def second_order_parameters(omega_n: ArrayLike, zeta: ArrayLike) -> tuple[np.ndarray, ...]:
    """(ω_n, ζ) as float arrays, checked: finite, ω_n > 0, ζ ≥ 0 (ValueError otherwise)."""
    omega_n = np.asarray(omega_n, dtype=float)
    zeta = np.asarray(zeta, dtype=float)
    if not (np.all(np.isfinite(omega_n)) and np.all(np.isfinite(zeta))):
        raise ValueError("'omega_n' and 'zeta' must be finite")
    if np.any(omega_n <= 0.0) or np.any(zeta < 0.0):
        raise ValueError(
            f"need omega_n > 0 and zeta >= 0, got omega_n={omega_n.tolist()}, zeta={zeta.tolist()}"
        )
    return omega_n, zeta


def second_order_frequency_response(omega: ArrayLike, omega_n: float, zeta: float) -> np.ndarray:
    r"""G(jω) = ω_n² / (−ω² + 2jζω_nω + ω_n²), complex, of the shape of ``omega`` [rad/s].

    The closed loop of nominal inverse dynamics in its regulation form (q̇_d = q̈_d = 0 in
    eq. 15, THEORY.md §3) from q_d to q: gain |G|, phase arg G ∈ (−π, 0].
    """
    omega_n, zeta = (float(v) for v in second_order_parameters(float(omega_n), float(zeta)))
    w = np.asarray(omega, dtype=float)
    return omega_n**2 / (omega_n**2 - w * w + 2j * zeta * omega_n * w)


def second_order_bandwidth(omega_n: ArrayLike, zeta: ArrayLike) -> np.ndarray:
    r"""−3 dB bandwidth ω_b [rad/s] of ω_n²/(s² + 2ζω_n s + ω_n²): |G(jω_b)| = 1/√2,

    ω_b = ω_n √(1 − 2ζ² + √(2 − 4ζ² + 4ζ⁴))  (ω_b = ω_n at ζ = 1/√2, ω_n √(√2 − 1) at ζ = 1).
    Arrays broadcast together.
    """
    omega_n, zeta = second_order_parameters(omega_n, zeta)
    z2 = zeta * zeta
    return omega_n * np.sqrt(1.0 - 2.0 * z2 + np.sqrt(2.0 - 4.0 * z2 + 4.0 * z2 * z2))
