"""Small numpy helpers shared by the maths modules (no ROS, no Pinocchio)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def per_joint(value: float | Sequence[float], n: int, name: str) -> np.ndarray:
    """Broadcast a scalar or check a length-n sequence; finite values only (a new array)."""
    arr = np.array(value, dtype=float).reshape(-1)
    if arr.size == 1:
        arr = np.full(n, float(arr[0]))
    if arr.size != n:
        raise ValueError(f"'{name}' needs 1 or {n} values, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"'{name}' must be finite, got {arr.tolist()}")
    return arr


def nonnegative(value: float | Sequence[float], n: int, name: str) -> np.ndarray:
    """Per-joint, finite, ≥ 0 values (a single value applies to every joint); read-only."""
    arr = per_joint(value, n, name)
    if np.any(arr < 0):
        raise ValueError(f"'{name}' must be >= 0, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr
