"""Rolling windows of samples and their decimation to a fixed point budget (pure).

A loop at 1 kHz gives 10,000 samples per joint and signal in a 10 s window; a browser
plot needs a few hundred. :func:`decimate` keeps, in each of its buckets, the samples where
every series has its minimum and its maximum, so a peak (an overshoot, a torque spike) is
never lost however far the window is thinned.
"""

from __future__ import annotations

import numpy as np


class Window:
    """The newest samples (t, values) within ``seconds`` of the last one, in a ring of
    ``capacity`` rows; time going backwards (a reset) starts the window anew."""

    def __init__(self, channels: int, seconds: float = 10.0, capacity: int = 20_000) -> None:
        self.seconds = float(seconds)
        self._t = np.zeros(capacity)
        self._y = np.zeros((capacity, channels))
        self._next = 0
        self._count = 0

    @property
    def channels(self) -> int:
        return self._y.shape[1]

    def __len__(self) -> int:
        return self._count

    def clear(self) -> None:
        self._next = self._count = 0

    def append(self, t: float, values: np.ndarray) -> None:
        if self._count and t < self.last_time():
            self.clear()
        capacity = len(self._t)
        self._t[self._next] = t
        self._y[self._next] = values
        self._next = (self._next + 1) % capacity
        self._count = min(self._count + 1, capacity)

    def last_time(self) -> float:
        return float(self._t[self._next - 1]) if self._count else float("nan")

    def view(self) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) in time order, only the last ``seconds``; copies."""
        capacity = len(self._t)
        start = (self._next - self._count) % capacity
        order = (np.arange(self._count) + start) % capacity
        t, y = self._t[order], self._y[order]
        if self._count:
            keep = t >= t[-1] - self.seconds
            t, y = t[keep], y[keep]
        return t, y


def decimate(t: np.ndarray, y: np.ndarray, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ``budget`` samples of (t, y) (y: samples × series), in time order: for each
    bucket of consecutive samples, the first one and those where a series is smallest or
    largest. Fewer samples than the budget come back as they are."""
    n = len(t)
    if n <= budget:
        return t, y
    series = y.shape[1] if y.ndim == 2 else 1
    per_bucket = 1 + 2 * series
    buckets = max(1, budget // per_bucket)
    edges = np.linspace(0, n, buckets + 1).astype(int)
    keep = []
    y2 = y.reshape(n, series)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        if hi <= lo:
            continue
        chunk = y2[lo:hi]
        keep.append(lo)
        keep.extend(lo + np.argmin(chunk, axis=0))
        keep.extend(lo + np.argmax(chunk, axis=0))
    index = np.unique(np.asarray(keep, dtype=int))
    return t[index], y[index]
