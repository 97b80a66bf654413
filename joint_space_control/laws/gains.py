"""Validated, immutable gain sets. A runtime update builds a new object and swaps it whole."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from joint_space_control.arrays import nonnegative


@dataclass(frozen=True)
class PDGains:
    """Diagonal gains: K_P [N·m/rad], K_D [N·m·s/rad], K_I [N·m/(rad·s)]."""

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray

    @classmethod
    def build(
        cls,
        n: int,
        kp: float | Sequence[float],
        kd: float | Sequence[float],
        ki: float | Sequence[float] = 0.0,
    ) -> PDGains:
        gains = cls(nonnegative(kp, n, "kp"), nonnegative(kd, n, "kd"), nonnegative(ki, n, "ki"))
        if np.any(gains.kp <= 0):
            raise ValueError(f"'kp' must be > 0 on every joint (K_P ≻ 0), got {gains.kp.tolist()}")
        return gains
