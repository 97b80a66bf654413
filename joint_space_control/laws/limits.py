"""Torque limits every command passes through on its way to the arm (no ROS).

The effort limit bounds the torque, the rate limit its change per step, like libfranka's
torque-rate limiter; both keep the command finite as long as their inputs are.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def rate_steps(max_rate: np.ndarray, dt: float) -> np.ndarray:
    """Largest change per step of ``dt`` seconds [N·m] for the rates ``max_rate`` [N·m/s];
    a rate of 0 means no limit (inf)."""
    max_rate = np.asarray(max_rate, dtype=float)
    if np.any(max_rate < 0) or not np.all(np.isfinite(max_rate)) or dt <= 0:
        raise ValueError("torque rates must be finite and >= 0, the step > 0")
    return np.where(max_rate > 0, max_rate * dt, np.inf)


def limit_rate(target: np.ndarray, previous: np.ndarray, max_step: np.ndarray) -> np.ndarray:
    """``target``, moved from ``previous`` by at most ``max_step`` per joint (exactly
    ``target`` where it is within reach, and always where ``max_step`` is inf)."""
    return np.clip(target, previous - max_step, previous + max_step)


def beyond_bound(tau: np.ndarray, limits: np.ndarray, factor: float) -> bool:
    """True when some |τ_i| exceeds ``factor`` × its effort limit: not a torque to clamp but
    a sign that its sender is broken (no bound where the limit is inf)."""
    return bool(np.any(np.abs(tau) > factor * np.asarray(limits)))


def joints_beyond(
    tau: np.ndarray, limits: np.ndarray, names: Sequence[str], factor: float = 1.0
) -> str:
    """The joints whose |τ_i| exceeds ``factor`` × its effort limit, each with its torque and
    limit ("right_s1 -212 N·m (limit 50)"), comma-separated; "" when none does."""
    limits = np.asarray(limits, dtype=float)
    return ", ".join(
        f"{name} {t:.4g} N·m (limit {limit:g})"
        for name, t, limit in zip(names, np.asarray(tau, dtype=float), limits, strict=True)
        if abs(t) > factor * limit
    )
