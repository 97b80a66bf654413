"""Control-loop statistics without ROS: period, jitter, compute time, latency and lateness.

A loop records one row per tick with :meth:`LoopStatistics.tick` (wall-clock nanoseconds; -1
where a quantity is not measured). Recording writes five integers into a preallocated ring
buffer: no allocation, about a microsecond. :meth:`LoopStatistics.summary`, called at a low
rate (the nodes publish it on ``/diagnostics`` once a second), turns the rows recorded since
the previous summary into statistics of that window, and folds them into histograms of 1 µs
bins so that the statistics since the first tick (``total.*``) stay exact to the microsecond
however long the run. The spirit is ros2_control's controller statistics (execution time,
periodicity), with percentiles.

Per tick k (all in µs in the summary):

- ``period``: start_k − start_{k−1};
- ``jitter``: |period − nominal|, ``nominal`` as recorded with the tick (the loop's rate, or
  the simulation-time step between the joint states answered);
- ``compute``: end_k − start_k, the work of the tick;
- ``latency``: as recorded (state-to-command: the command against the state it answers);
- ``lateness``: as recorded (paced loops: start against the schedule); a tick is *late* when
  its lateness exceeds ``late_us`` (200 µs) and *too late* beyond ``too_late_us`` (1 ms).

Percentiles are nearest-rank (the smallest sample with at least p % of the samples at or
below it); the ``total.*`` ones are the same sample's 1 µs bin (rounded down). Writer and
reader may be different threads: a row is complete before the tick count moves past it, and
the summary only reads rows behind that count, under the GIL.
"""

from __future__ import annotations

import array
import math

import numpy as np

#: Quantities of a tick, in the order of a recorded row (ns; -1: not measured).
ROW = ("start", "end", "latency", "lateness", "nominal")
#: Statistics published per quantity, with the summary key ``<quantity>.<stat>_us``.
METRICS = {
    "period": ("mean", "p50", "p99", "max"),
    "jitter": ("p50", "p99", "max"),
    "compute": ("mean", "p50", "p99", "max"),
    "latency": ("p50", "p99", "max"),
    "lateness": ("p50", "p99", "max"),
}
_START, _END, _LATENCY, _LATENESS, _NOMINAL = range(len(ROW))


def nearest_rank(values: np.ndarray, percent: float) -> float:
    """The smallest sample with at least ``percent`` % of the samples at or below it."""
    if values.size == 0:
        return math.nan
    rank = max(1, math.ceil(percent / 100.0 * values.size))
    return float(np.partition(values, rank - 1)[rank - 1])


def summary_keys() -> list[str]:
    """Every key of :meth:`LoopStatistics.summary`, in order."""
    window = ["ticks", "seconds", "rate_hz"]
    window += [f"{m}.{s}_us" for m, stats in METRICS.items() for s in stats]
    window += ["late", "too_late"]
    return window + [f"total.{k}" for k in window]


class _Histogram:
    """Counts per 1 µs bin up to ``bins`` µs, one overflow bin, and the exact sum and max."""

    def __init__(self, bins: int) -> None:
        self.counts = np.zeros(bins + 1, dtype=np.int64)
        self.n = 0
        self.sum = 0.0
        self.max = -math.inf

    def add(self, values_us: np.ndarray) -> None:
        if values_us.size == 0:
            return
        idx = np.minimum(np.floor(values_us), self.counts.size - 1).astype(np.int64)
        counts = np.bincount(idx)  # as long as the largest value: short, no 50 000-bin array
        self.counts[: counts.size] += counts
        self.n += values_us.size
        self.sum += float(values_us.sum())
        self.max = max(self.max, float(values_us.max()))

    def stats(self, names: tuple[str, ...]) -> list[float]:
        """``mean``, ``max`` and ``pNN`` (the 1 µs bin, lower edge, of the nearest-rank
        sample; ``max`` when it overflowed), NaN without samples."""
        if self.n == 0:
            return [math.nan] * len(names)
        cumulative = None
        out = []
        for name in names:
            if name == "mean":
                out.append(self.sum / self.n)
            elif name == "max":
                out.append(self.max)
            else:
                if cumulative is None:
                    cumulative = np.cumsum(self.counts)
                rank = max(1, math.ceil(float(name[1:]) / 100.0 * self.n))
                b = int(np.searchsorted(cumulative, rank))
                out.append(self.max if b == self.counts.size - 1 else float(b))
        return out


class LoopStatistics:
    """Per-tick timing of one loop, summarised on request (see the module docstring).

    ``capacity`` rows are kept between two summaries (16384: 16 s at 1 kHz, 5 s at 3 kHz);
    ticks beyond that are counted but their oldest rows are lost to the window statistics.
    """

    def __init__(
        self,
        capacity: int = 16384,
        late_us: float = 200.0,
        too_late_us: float = 1000.0,
        histogram_us: int = 50_000,
    ) -> None:
        self.capacity = capacity
        self.late_us, self.too_late_us = late_us, too_late_us
        self._rows = array.array("q", bytes(8 * len(ROW) * capacity))
        self._view = np.frombuffer(self._rows, dtype=np.int64).reshape(capacity, len(ROW))
        self._count = 0  # rows written, ever
        self._taken = 0  # rows summarised, ever
        self._previous_start: int | None = None  # start of the last summarised tick
        self._first_start: int | None = None
        self._window_start: int | None = None
        self._histograms = {m: _Histogram(histogram_us) for m in METRICS}
        self._late_total = 0
        self._too_late_total = 0

    @property
    def ticks(self) -> int:
        """Ticks recorded so far."""
        return self._count

    def tick(
        self,
        start_ns: int,
        end_ns: int,
        latency_ns: int = -1,
        lateness_ns: int = -1,
        nominal_ns: int = -1,
    ) -> None:
        """Record one tick (the hot path: five stores into the ring, nothing allocated)."""
        i = (self._count % self.capacity) * 5
        rows = self._rows
        rows[i] = start_ns
        rows[i + 1] = end_ns
        rows[i + 2] = latency_ns
        rows[i + 3] = lateness_ns
        rows[i + 4] = nominal_ns
        self._count += 1

    def _take(self) -> np.ndarray:
        """The rows recorded since the previous summary, oldest first (a copy)."""
        count = self._count
        n = min(count - self._taken, self.capacity)
        first = count - n
        idx = (np.arange(first, count) % self.capacity) if n else np.zeros(0, dtype=np.int64)
        self._taken = count
        return self._view[idx].copy()

    def summary(self, now_ns: int) -> dict[str, float]:
        """Statistics of the ticks since the previous summary (the window, which ends at
        ``now_ns``, wall clock as the ticks) and since the first tick (``total.*``); every key
        of :func:`summary_keys`, NaN where there is no sample."""
        rows = self._take()
        start = rows[:, _START]
        window_start = self._window_start
        if window_start is None:
            window_start = int(start[0]) if start.size else now_ns
        if self._first_start is None and start.size:
            self._first_start = int(start[0])
        previous = self._previous_start
        if start.size:
            self._previous_start = int(start[-1])
        self._window_start = now_ns

        with_previous = start if previous is None else np.concatenate(([previous], start))
        period = np.diff(with_previous)
        nominal = rows[len(rows) - len(period) :, _NOMINAL]
        measured = nominal >= 0
        values = {
            "period": period * 1e-3,
            "jitter": np.abs(period[measured] - nominal[measured]) * 1e-3,
            "compute": (rows[:, _END] - start) * 1e-3,
            "latency": rows[rows[:, _LATENCY] >= 0, _LATENCY] * 1e-3,
            "lateness": rows[rows[:, _LATENESS] >= 0, _LATENESS] * 1e-3,
        }
        late = int(np.count_nonzero(values["lateness"] > self.late_us))
        too_late = int(np.count_nonzero(values["lateness"] > self.too_late_us))
        self._late_total += late
        self._too_late_total += too_late

        seconds = (now_ns - window_start) * 1e-9
        out: dict[str, float] = {
            "ticks": len(rows),
            "seconds": seconds,
            "rate_hz": len(rows) / seconds if seconds > 0 else math.nan,
        }
        for metric, stats in METRICS.items():
            x = values[metric]
            self._histograms[metric].add(x)
            for stat in stats:
                out[f"{metric}.{stat}_us"] = _stat(x, stat)
        out["late"], out["too_late"] = late, too_late

        total_seconds = (now_ns - self._first_start) * 1e-9 if self._first_start else 0.0
        out["total.ticks"] = self._taken
        out["total.seconds"] = total_seconds
        out["total.rate_hz"] = self._taken / total_seconds if total_seconds > 0 else math.nan
        for metric, stats in METRICS.items():
            for stat, value in zip(stats, self._histograms[metric].stats(stats), strict=True):
                out[f"total.{metric}.{stat}_us"] = value
        out["total.late"], out["total.too_late"] = self._late_total, self._too_late_total
        return out


def _stat(x: np.ndarray, name: str) -> float:
    if x.size == 0:
        return math.nan
    if name == "mean":
        return float(x.mean())
    if name == "max":
        return float(x.max())
    return nearest_rank(x, float(name[1:]))
