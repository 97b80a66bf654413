r"""Gains ↔ second order: (K_P, K_D) ↔ (ω_n, ζ) of ë + K_D ė + K_P e = 0 (THEORY.md §3).

The relation is used in both directions by different layers: the gain design of the control
laws (:mod:`joint_space_control.laws.gains`) turns a wanted ω_n and ζ into gains, and the
analysis (:mod:`joint_space_control.analysis.metrics`, ``run_metrics``) turns a controller's
gains into the second-order response the theory predicts. It lives with the laws, the lower
of the two, so that the laws need nothing from the analysis. Numpy only.

The analytic step response and its figures (:func:`second_order_step`,
:func:`second_order_prediction`: rise, peak, overshoot, exact settling times) are here too:
what the theory predicts, against which the analysis measures a run.
"""

from __future__ import annotations

import math

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


RISE_LOW = 0.1
"""Lower level of the rise time, as a fraction of the step."""
RISE_HIGH = 0.9
"""Upper level of the rise time, as a fraction of the step."""
_MAX_BISECTIONS = 200
_MAX_DOUBLINGS = 1100


def _unit_step(x: ArrayLike, zeta: ArrayLike) -> np.ndarray:
    r"""Unit step response s(x) of 1/(s² + 2ζs + 1) at normalised times x = ω_n t ≥ 0.

    ζ ≤ 1:  s = 1 − e^{−ζx} (cos ω_d x + ζ x sinc(ω_d x)),  ω_d = √(1 − ζ²), sinc(u) = sin u/u
    ζ > 1:  s = 1 − e^{−ζx} (cosh βx + ζ sinh(βx)/β),       β = √(ζ² − 1)
    Both forms are written to stay accurate as ζ → 1 (ζ = 1 gives 1 − e^{−x}(1 + x)) and for
    large x (e^{−ζx} cosh βx as a sum of decaying exponentials).
    """
    x, zeta = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(zeta, dtype=float))
    out = np.empty(x.shape)
    under = zeta <= 1.0
    if np.any(under):
        z, xu = zeta[under], x[under]
        wd = np.sqrt(1.0 - z * z)
        out[under] = 1.0 - np.exp(-z * xu) * (np.cos(wd * xu) + z * xu * np.sinc(wd * xu / np.pi))
    over = ~under
    if np.any(over):
        z, xo = zeta[over], x[over]
        beta = np.sqrt(z * z - 1.0)
        slow = np.exp(-xo / (z + beta))  # e^{(β − ζ)x}, since (ζ − β)(ζ + β) = 1
        fast = np.exp(-(z + beta) * xo)
        sinh_over_beta = -slow * np.expm1(-2.0 * beta * xo) / (2.0 * beta)  # e^{−ζx} sinh(βx)/β
        out[over] = 1.0 - (0.5 * (slow + fast) + z * sinh_over_beta)
    return out


def second_order_step(
    t: ArrayLike, omega_n: float, zeta: float, y0: float = 0.0, y1: float = 1.0
) -> np.ndarray:
    r"""Analytic step response of ω_n² / (s² + 2ζω_n s + ω_n²) from y0 to y1, step at t = 0.

    y(t) = y0 for t < 0 and y(t) = y0 + (y1 − y0)·s(ω_n t) for t ≥ 0, starting at rest, with

    - ζ < 1: s = 1 − e^{−ζω_n t}(cos ω_d t + ζ/√(1−ζ²) sin ω_d t),  ω_d = ω_n√(1−ζ²);
    - ζ = 1: s = 1 − e^{−ω_n t}(1 + ω_n t);
    - ζ > 1: s = 1 − e^{−ζω_n t}(cosh ω_β t + ζ/√(ζ²−1) sinh ω_β t),  ω_β = ω_n√(ζ²−1).

    ``omega_n`` [rad/s] > 0 and ``zeta`` ≥ 0 are scalars; t [s] has any shape, and so does
    the result (in the unit of y0, y1).
    """
    omega_n, zeta = second_order_parameters(float(omega_n), float(zeta))
    t = np.asarray(t, dtype=float)
    x = np.maximum(omega_n * t, 0.0)
    return np.where(t < 0.0, y0, y0 + (y1 - y0) * _unit_step(x, zeta))


def _bisect(inside, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Boundary between ``inside(lo)`` True and ``inside(hi)`` False, to machine precision."""
    lo, hi = lo.astype(float), hi.astype(float)
    for _ in range(_MAX_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if np.all((mid <= lo) | (mid >= hi)):
            break
        below = inside(mid)
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _reach(zeta: np.ndarray, level: float) -> np.ndarray:
    """A normalised time at which the overdamped (ζ ≥ 1) response is at or past ``level``."""
    hi = np.ones(zeta.shape)
    for _ in range(_MAX_DOUBLINGS):
        short = _unit_step(hi, zeta) < level
        if not short.any():
            break
        hi[short] *= 2.0
    return hi


def _first_time(zeta: np.ndarray, level: float) -> np.ndarray:
    """Normalised first instant s(x) = level, 0 < level < 1."""
    hi = np.empty(zeta.shape)
    under = zeta < 1.0
    # before its first peak x_p = π/ω_d (where s = 1 + M_p) the response rises monotonically
    hi[under] = np.pi / np.sqrt(1.0 - zeta[under] ** 2)
    hi[~under] = _reach(zeta[~under], level)  # monotonic for ζ ≥ 1
    return _bisect(lambda x: _unit_step(x, zeta) < level, np.zeros(zeta.shape), hi)


def _settling(zeta: np.ndarray, band: float) -> np.ndarray:
    """Normalised exact settling time: the last instant |s(x) − 1| = band. NaN for ζ = 0.

    ζ < 1: s − 1 has its extrema at x_k = kπ/ω_d with |s(x_k) − 1| = M_p^k, decreasing in k,
    and |s − 1| has a single zero between two extrema; so the last exit lies in
    (x_k, x_{k+1}] with k the largest index such that M_p^k > band. ζ ≥ 1: s rises
    monotonically to 1 and the answer is the single crossing of 1 − band.
    """
    lo = np.zeros(zeta.shape)
    hi = np.empty(zeta.shape)
    under = (zeta > 0.0) & (zeta < 1.0)
    z = zeta[under]
    wd = np.sqrt(1.0 - z * z)
    # M_p^k > band  ⇔  k < m = ω_d ln(1/band) / (ζπ); k = 0 (x = 0, |s − 1| = 1) always counts
    k = np.maximum(np.ceil(wd * math.log(1.0 / band) / (z * np.pi)) - 1.0, 0.0)
    lo[under] = k * np.pi / wd
    hi[under] = (k + 1.0) * np.pi / wd
    mono = zeta >= 1.0
    hi[mono] = _reach(zeta[mono], 1.0 - band)
    out = np.full(zeta.shape, math.nan)
    ok = under | mono
    zok = zeta[ok]
    out[ok] = _bisect(lambda x: np.abs(_unit_step(x, zok) - 1.0) > band, lo[ok], hi[ok])
    return out


def second_order_prediction(omega_n: ArrayLike, zeta: ArrayLike) -> dict[str, np.ndarray]:
    r"""Step-response figures of ω_n² / (s² + 2ζω_n s + ω_n²), per joint.

    ``omega_n`` [rad/s] > 0 and ``zeta`` ≥ 0 broadcast together (a scalar is one joint);
    every entry is an array of that shape (at least 1-D), times in s:

    - ``rise_time``: 10 %–90 % rise time, exact (bisection on the analytic response, which
      rises monotonically up to its first peak), for any ζ;
    - ``peak_time``: π / (ω_n√(1−ζ²)) for ζ < 1, inf otherwise;
    - ``overshoot_percent``: 100·exp(−πζ/√(1−ζ²)) for ζ < 1, else 0;
    - ``settling_time_2``, ``settling_time_5``: exact last instant the response leaves the
      ±2 % (±5 %) band around its final value (bisection on the analytic response between
      the bracketing extrema); NaN for ζ = 0, which never settles;
    - ``settling_time_2_approx`` = 4/(ζω_n), ``settling_time_5_approx`` = 3/(ζω_n): the
      textbook envelope estimates (inf for ζ = 0), for comparison only.
    """
    omega_n, zeta = second_order_parameters(omega_n, zeta)
    omega_n, zeta = (np.array(a, dtype=float) for a in np.broadcast_arrays(omega_n, zeta))
    omega_n, zeta = np.atleast_1d(omega_n), np.atleast_1d(zeta)
    under = zeta < 1.0
    wd = np.sqrt(np.where(under, 1.0 - zeta**2, 1.0))
    overshoot = np.where(under, 100.0 * np.exp(-np.pi * zeta / wd), 0.0)
    peak_time = np.where(under, np.pi / (omega_n * wd), math.inf)
    rise = (_first_time(zeta, RISE_HIGH) - _first_time(zeta, RISE_LOW)) / omega_n
    with np.errstate(divide="ignore"):
        decay = 1.0 / (zeta * omega_n)
    return {
        "omega_n": omega_n,
        "zeta": zeta,
        "rise_time": rise,
        "peak_time": peak_time,
        "overshoot_percent": overshoot,
        "settling_time_2": _settling(zeta, 0.02) / omega_n,
        "settling_time_5": _settling(zeta, 0.05) / omega_n,
        "settling_time_2_approx": 4.0 * decay,
        "settling_time_5_approx": 3.0 * decay,
    }
