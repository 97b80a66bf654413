r"""Frequency response from sampled signals: gain and phase at a known ω, −3 dB bandwidth.

Arrays in, numbers out (numpy only, no ROS). Times in s, ω in rad/s, phases in rad.

- :func:`sine_fit`: the phasor of a signal at ω, by least squares;
- :func:`frequency_response`: gain and phase of y relative to u at ω (e.g. q relative to q_d
  under a sinusoidal reference, or a point of a sine sweep);
- :func:`bandwidth`: the −3 dB bandwidth from measured (ω, gain) points.

The analytic closed loop these are compared with is
:func:`joint_space_control.laws.second_order.second_order_frequency_response` and its
bandwidth :func:`~joint_space_control.laws.second_order.second_order_bandwidth`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

HALF_POWER = 1.0 / math.sqrt(2.0)
"""|G| at the −3 dB bandwidth (20 log₁₀(1/√2) = −3.0103 dB)."""


def _signals(t: ArrayLike, *signals: ArrayLike) -> tuple[np.ndarray, ...]:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 3:
        raise ValueError(f"'t' must be 1-D with at least 3 samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0.0):
        raise ValueError("'t' must be finite and non-decreasing")
    out = [t]
    for x in signals:
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        if x.ndim != 2 or x.shape[0] != t.size:
            raise ValueError(
                f"a signal has shape {x.shape}, expected ({t.size},) or ({t.size}, n)"
            )
        if not np.all(np.isfinite(x)):
            raise ValueError("a signal contains NaN or infinite values")
        out.append(x)
    return tuple(out)


def _window(t: np.ndarray, omega: float, t_start: float | None) -> tuple[np.ndarray, int]:
    """Samples of the last whole number of periods 2π/ω that start at or after t_start."""
    if not (math.isfinite(omega) and omega > 0.0):
        raise ValueError(f"'omega' must be finite and > 0 rad/s, got {omega}")
    lo = float(t[0]) if t_start is None else float(t_start)
    period = 2.0 * math.pi / omega
    periods = math.floor((t[-1] - lo) / period * (1.0 + 1e-12))
    if periods < 1:
        raise ValueError(
            f"less than one period {period:.6g} s of ω = {omega:.6g} rad/s in "
            f"[{lo:.6g}, {t[-1]:.6g}] s"
        )
    first = t[-1] - periods * period
    keep = t >= first - 1e-9 * period
    return keep, periods


def sine_fit(
    t: ArrayLike, x: ArrayLike, omega: float, t_start: float | None = None
) -> tuple[np.ndarray, np.ndarray, int]:
    r"""Least-squares fit x(t) ≈ a + b sin ωt + c cos ωt per column.

    The fit uses the samples of the last whole number of periods 2π/ω of the record that
    begin at or after ``t_start`` (default ``t[0]``; a settle time skips the transient).
    Returns (phasor X = b + j c, shape (n,), so that b sin ωt + c cos ωt = Im(X e^{jωt});
    offset a, shape (n,); the number of periods used). The samples need not be uniform.
    """
    t, x = _signals(t, x)
    keep, periods = _window(t, float(omega), t_start)
    tw = t[keep] - t[keep][0]
    basis = np.column_stack([np.ones(tw.size), np.sin(omega * tw), np.cos(omega * tw)])
    coef, *_ = np.linalg.lstsq(basis, x[keep], rcond=None)
    # back to the phase of t (not t − t_window_start): rotate by e^{−jω t_window_start}
    phasor = (coef[1] + 1j * coef[2]) * np.exp(-1j * omega * t[keep][0])
    return phasor, coef[0], periods


@dataclass(frozen=True)
class FrequencyPoint:
    """Gain |Y/U| and phase arg(Y/U) ∈ (−π, π] [rad] of y relative to u at ``omega``
    [rad/s], per column (shape (n,)); ``periods`` whole periods in [t_start, t_end] [s]."""

    omega: float
    gain: np.ndarray
    phase: np.ndarray
    periods: int
    t_start: float
    t_end: float

    @property
    def gain_db(self) -> np.ndarray:
        """20 log₁₀ gain [dB]."""
        return 20.0 * np.log10(self.gain)


def frequency_response(
    t: ArrayLike, u: ArrayLike, y: ArrayLike, omega: float, t_start: float | None = None
) -> FrequencyPoint:
    r"""Gain and phase of y relative to u at ω from sampled signals (one column per joint).

    Both are fitted by :func:`sine_fit` over the same last whole number of periods after
    ``t_start``; H = Y/U (the ratio of their phasors), gain |H|, phase arg H. Fitting u as well
    as y removes the need to know the input's amplitude and phase; an offset in either
    (q̄ of q_d = q̄ + Δ sin ωt) is fitted away. Columns where u has no component at ω
    (|U| = 0) give NaN. Additive white noise of σ on y, N samples in the window and an
    input amplitude A give a gain error of about σ√(2/N)/A (one standard deviation).
    """
    t, u, y = _signals(t, u, y)
    if u.shape != y.shape:
        raise ValueError(f"'u' has shape {u.shape} but 'y' has {y.shape}")
    keep, periods = _window(t, float(omega), t_start)
    pu, _, _ = sine_fit(t, u, omega, t_start)
    py, _, _ = sine_fit(t, y, omega, t_start)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(pu != 0.0, py / np.where(pu != 0.0, pu, 1.0), np.nan + 0j)
    tw = t[keep]
    return FrequencyPoint(
        float(omega), np.abs(h), np.angle(h), periods, float(tw[0]), float(tw[-1])
    )


def bandwidth(
    omega: ArrayLike, gain: ArrayLike, level: float = HALF_POWER, reference_gain: float = 1.0
) -> float:
    r"""ω [rad/s] where the gain first falls below ``level`` × ``reference_gain`` (−3 dB of a
    unit DC gain by default), from measured points.

    ``omega`` (> 0, increasing) and ``gain`` (> 0) are 1-D of the same size. The crossing is
    the first pair of consecutive points with the gain at or above the level and then below
    it, interpolated linearly in (log ω, gain in dB). NaN if the first point is already
    below the level or no point falls below it (the bandwidth lies outside the points).
    """
    w = np.asarray(omega, dtype=float)
    g = np.asarray(gain, dtype=float)
    if w.ndim != 1 or w.shape != g.shape or w.size < 2:
        raise ValueError(
            f"'omega' and 'gain' must be 1-D of the same size >= 2: {w.shape}, {g.shape}"
        )
    if not (np.all(np.isfinite(w)) and np.all(w > 0.0) and np.all(np.diff(w) > 0.0)):
        raise ValueError("'omega' must be finite, > 0 and increasing")
    if not (np.all(np.isfinite(g)) and np.all(g > 0.0)):
        raise ValueError("'gain' must be finite and > 0")
    if not (level > 0.0 and reference_gain > 0.0):
        raise ValueError("'level' and 'reference_gain' must be > 0")
    db = 20.0 * np.log10(g / (level * reference_gain))  # 0 dB at the level
    below = db < 0.0
    if below[0] or not np.any(below):
        return math.nan
    k = int(np.argmax(below))
    lw = np.log(w[k - 1 : k + 1])
    frac = db[k - 1] / (db[k - 1] - db[k])
    return float(np.exp(lw[0] + frac * (lw[1] - lw[0])))
