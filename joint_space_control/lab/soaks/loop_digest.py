"""What the nodes said of their own loops during a run, from the ``/diagnostics`` they
published once a second and the bag kept (no ROS): per node and per window, the lowest loop
rate, the longest compute time and the worst level, with the first message at that level.

A fault soak that fails prints this digest, so that a run on another machine (CI) says
which loop slowed or alarmed, and when, without its logs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

#: DiagnosticStatus levels, by value.
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


@dataclass(frozen=True)
class LoopSample:
    """One DiagnosticStatus as recorded: receive time [s since the epoch], the status's
    name ("<node>: control loop"), level, message and the loop's figures (NaN: none)."""

    wall: float
    name: str
    level: int
    message: str
    rate_hz: float
    compute_p99_us: float


def sample(wall: float, name: str, level: int, message: str, values: Mapping[str, str]):
    """A :class:`LoopSample` from a status's key-value pairs (text, as published)."""
    return LoopSample(
        wall,
        name,
        int(level),
        message,
        _number(values.get("rate_hz")),
        _number(values.get("compute.p99_us")),
    )


def _number(text: str | None) -> float:
    try:
        return float(text) if text is not None else math.nan
    except ValueError:
        return math.nan


@dataclass(frozen=True)
class LoopWindow:
    """One node's loop over one window: ``start`` [s from the run's start]."""

    start: float
    statuses: int
    min_rate_hz: float
    max_compute_p99_us: float
    level: int
    message: str  # the first message at ``level``


def loop_windows(
    samples: Sequence[LoopSample], t0: float, window: float = 10.0
) -> dict[str, list[LoopWindow]]:
    """Per status name, one :class:`LoopWindow` per ``window`` [s] with a status in it,
    counted from ``t0`` [s since the epoch], in time order."""
    grouped: dict[str, dict[int, list[LoopSample]]] = {}
    for s in sorted(samples, key=lambda s: s.wall):
        k = int(math.floor((s.wall - t0) / window))
        grouped.setdefault(s.name, {}).setdefault(k, []).append(s)
    out: dict[str, list[LoopWindow]] = {}
    for name, windows in grouped.items():
        rows = []
        for k in sorted(windows):
            group = windows[k]
            level = max(s.level for s in group)
            rows.append(
                LoopWindow(
                    start=k * window,
                    statuses=len(group),
                    min_rate_hz=_nanmin([s.rate_hz for s in group]),
                    max_compute_p99_us=_nanmax([s.compute_p99_us for s in group]),
                    level=level,
                    message=next(s.message for s in group if s.level == level),
                )
            )
        out[name] = rows
    return out


def _nanmin(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return min(finite) if finite else math.nan


def _nanmax(values: list[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return max(finite) if finite else math.nan


def format_loops(windows: Mapping[str, Sequence[LoopWindow]], window: float = 10.0) -> str:
    """Per node: its lowest rate [Hz] in each window, then each change of level with the
    window it happened in and its message."""
    lines = [f"the loops by their /diagnostics (lowest rate [Hz] per {window:g} s):"]
    for name in sorted(windows):
        rows = windows[name]
        rates = " ".join(
            "-" if math.isnan(w.min_rate_hz) else f"{w.min_rate_hz:.0f}" for w in rows
        )
        lines.append(f"  {name}: {rates}")
        level = 0
        for w in rows:
            if w.level != level:
                lines.append(f"    {w.start:6.0f} s  {LEVELS.get(w.level, w.level)}: {w.message}")
                level = w.level
    return "\n".join(lines)
