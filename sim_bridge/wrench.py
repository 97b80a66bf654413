r"""External wrench schedules for scenarios, on simulation time, no ROS.

A schedule applies w(t) = s(t) w₀ to one link, with w₀ = (f₀ [N], μ₀ [N·m]) expressed in the
world frame and acting at the link frame's origin, and the profile (instants closer than
:data:`SAME_TIME` are equal)

- ``step``:      s(t) = 1 for t ≥ t₀, else 0;
- ``pulse``:     s(t) = 1 for t₀ ≤ t < t₀ + T, else 0;
- ``sinusoid``:  s(t) = sin(2π f (t − t₀)) for t ≥ t₀, else 0 (starts from zero).

w is the wrench applied *to* the robot by its environment, w = −h_e with h_e the wrench the
robot exerts on the environment (THEORY.md §1): the plant is B q̈ + C q̇ + F q̇ + g = τ + Jᵀw
= τ − Jᵀh_e, with J the link frame's Jacobian, world-aligned, [linear; angular].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

PROFILES = ("step", "pulse", "sinusoid")
#: Times closer than this [s] are the same instant (the node's clock counts nanoseconds; t₀ + T
#: in floating point may land a rounding error past a step's time).
SAME_TIME = 1e-10


def wrench_vector(values: Sequence[float], name: str) -> np.ndarray:
    """Three finite components as a read-only array; raises ValueError with ``name``."""
    arr = np.array(values, dtype=float).reshape(-1)
    if arr.size != 3:
        raise ValueError(f"'{name}' must have 3 components (x, y, z), got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"'{name}' must be finite, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class WrenchSchedule:
    """w(t) = s(t) (force, torque) on ``link`` ("" = the last controlled joint's child)."""

    force: np.ndarray
    torque: np.ndarray
    profile: str = "step"
    start: float = 0.0  # t₀ [s]
    duration: float = 0.0  # T [s], pulse
    frequency: float = 0.0  # f [Hz], sinusoid
    link: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "force", wrench_vector(self.force, "wrench_force"))
        object.__setattr__(self, "torque", wrench_vector(self.torque, "wrench_torque"))
        if self.profile not in PROFILES:
            raise ValueError(
                f"'wrench_profile' is '{self.profile}'; allowed: {', '.join(PROFILES)}"
            )
        for name, value in (
            ("wrench_start", self.start),
            ("wrench_duration", self.duration),
            ("wrench_frequency", self.frequency),
        ):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"'{name}' must be a finite number >= 0, got {value!r}")

    @property
    def active(self) -> bool:
        """False when w₀ = 0 (the schedule is off)."""
        return bool(np.any(self.force) or np.any(self.torque))

    def scale(self, t: float) -> float:
        """s(t), the profile at simulation time t [s]."""
        if t < self.start - SAME_TIME:
            return 0.0
        if self.profile == "step":
            return 1.0
        if self.profile == "pulse":
            return 1.0 if t < self.start + self.duration - SAME_TIME else 0.0
        return math.sin(2.0 * math.pi * self.frequency * (t - self.start))

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(force [N], torque [N·m]) at simulation time t [s], world frame."""
        s = self.scale(t)
        return s * self.force, s * self.torque
