"""Rolling windows of samples and their decimation to a fixed point budget (pure).

A loop at 1 kHz gives 10,000 samples per joint and signal in a 10 s window; a browser
plot needs a few hundred. :func:`decimate` keeps, in each of its buckets, the samples where
every series has its minimum and its maximum, so a peak (an overshoot, a torque spike) is
never lost however far the window is thinned. :func:`spread` widens the data a plot's
y axis is ranged on to what its labels can tell apart.
"""

from __future__ import annotations

from collections.abc import Sequence

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


#: The smallest span [the plot's unit: rad, N·m] of the data a plot's y axis is ranged on:
#: flatter data (a joint at rest) is drawn in the middle of it. uPlot ranges the axis on
#: the data, and on flatter data gave axes it could not label: ticks every 0.0001 written
#: with its 3 decimals ("-0, -0, 0"), or, for a joint resting within 1e-9 rad of -0.3, a
#: range rounded to nothing (no line and no tick drawn).
LEAST_SPAN = 0.004
#: The tick spacings a y axis may take: 1, 2 or 5 × 10ⁿ, none finer than the 3 decimals
#: uPlot writes its tick labels with (its own list has 0.0001 and 0.0025).
Y_INCREMENTS = tuple(float(f"{m}e{n}") for n in range(-3, 16) for m in (1, 2, 5))


def spread(columns: Sequence[np.ndarray], n: int) -> np.ndarray:
    """``n`` values (n ≥ 2) that, plotted beside ``columns`` and not drawn, widen the data
    the y axis is ranged on to at least :data:`LEAST_SPAN` about its middle: alternately
    half of it below and above. The smallest finite value of ``columns`` (no effect) when
    they span more; zeros when they have no finite value."""
    finite = [c[np.isfinite(c)] for c in columns]
    finite = [c for c in finite if len(c)]
    if not finite:
        return np.zeros(n)
    low = float(min(c.min() for c in finite))
    high = float(max(c.max() for c in finite))
    if high - low >= LEAST_SPAN:
        return np.full(n, low)
    middle = 0.5 * (low + high)
    values = np.full(n, middle - 0.5 * LEAST_SPAN)
    values[1::2] = middle + 0.5 * LEAST_SPAN
    return values
