"""Backward jumps of a time base, and when they repeat.

One simulator's time only goes forwards; it goes back once when the simulator is restarted
(its time starts again at 0), and a controller restarts from the measured configuration.
Two simulators in one ROS domain both publishing ``/clock`` (or both publishing one
``joint_states`` topic) make the time go back and forth all the time: restarting at each
jump would restart the controller hundreds of times a second. The two are told apart on the
wall clock: ``count`` backward jumps within ``window`` seconds are *repeated* jumps, and
they stay repeated until ``window`` seconds pass without one. No ROS here.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable

#: Backward jumps within WINDOW [s] (wall time) that make them repeated.
COUNT = 3
WINDOW = 2.0


class BackwardJumps:
    """Counts the backward jumps of one time base and says whether they repeat."""

    def __init__(
        self,
        count: int = COUNT,
        window: float = WINDOW,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.count, self.window = count, window
        self._clock = clock
        self._recent: deque[float] = deque(maxlen=count)  # wall times of the last jumps
        self._repeated_until = -math.inf
        self.total = 0  # jumps since the start

    def jumped(self) -> bool:
        """One backward jump; returns whether the jumps repeat (this one included)."""
        now = self._clock()
        self.total += 1
        self._recent.append(now)
        full = len(self._recent) == self.count and now - self._recent[0] <= self.window
        if full or now < self._repeated_until:
            self._repeated_until = now + self.window
            return True
        return False

    @property
    def repeating(self) -> bool:
        """The last jump repeated others, less than ``window`` seconds ago."""
        return self._clock() < self._repeated_until
