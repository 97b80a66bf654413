"""What a measured joint state can be (no ROS): a position far outside the joint's range or
an absurd velocity is a broken sender, not a state to act on.

A controller that took q = 1e9 rad for a measurement computed 1.7e18 N·m (clamped to the
effort limits, and driving the arm at them for seconds): the fault soak's burst of malformed
joint states found it. Finite but absurd values are refused where they arrive, like
non-finite ones (STYLE.md, "Validate at the boundary"), with bounds no real or simulated arm
reaches: a position more than :data:`POSITION_SLACK` beyond a joint's limits (a plant's
limits are enforced within a small fraction of that, a real arm's soft limits too), a joint
without limits beyond ±:data:`UNLIMITED_POSITION`, a speed beyond :data:`SPEED_BOUND`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: [rad or m] beyond a joint's limits: half a turn.
POSITION_SLACK = np.pi
#: [rad or m] |q| of a joint without limits (a continuous joint): ~1,600 turns.
UNLIMITED_POSITION = 1.0e4
#: [rad/s or m/s] |q̇| of any joint: ~160 turns a second.
SPEED_BOUND = 1.0e3


class PlausibleStates:
    """The check of one arm's measured states: :meth:`reason` is "" for a plausible state."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, names: Sequence[str]) -> None:
        lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        bounded = np.isfinite(lower) & np.isfinite(upper)
        self.center = np.where(bounded, 0.5 * (lower + upper), 0.0)
        self.reach = np.where(bounded, 0.5 * (upper - lower) + POSITION_SLACK, UNLIMITED_POSITION)
        self.lower = np.where(bounded, lower - POSITION_SLACK, -UNLIMITED_POSITION)
        self.upper = np.where(bounded, upper + POSITION_SLACK, UNLIMITED_POSITION)
        self.names = tuple(names)

    def reason(self, q: np.ndarray, dq: np.ndarray) -> str:
        """Why the state (q, q̇) cannot be a measurement of this arm ("" when it can; q̇ may
        be empty: not measured). Finite values are assumed (checked before)."""
        if np.all(np.abs(q - self.center) <= self.reach) and (
            not dq.size or np.all(np.abs(dq) <= SPEED_BOUND)
        ):
            return ""
        far = [
            f"{name} at {x:.4g} (range [{lo:.4g}, {hi:.4g}])"
            for name, x, lo, hi in zip(self.names, q, self.lower, self.upper, strict=True)
            if not lo <= x <= hi
        ]
        fast = [
            f"{name} at {v:.4g}/s"
            for name, v in zip(self.names, dq, strict=False)
            if abs(v) > SPEED_BOUND
        ]
        parts = []
        if far:
            parts.append(
                "positions beyond the joints' limits by more than half a turn: " + ", ".join(far)
            )
        if fast:
            parts.append(f"speeds beyond {SPEED_BOUND:g}: " + ", ".join(fast))
        return "implausible measurement: " + "; ".join(parts)
