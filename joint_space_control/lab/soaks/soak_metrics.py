"""Figures and verdict of a soak run (``jsc soak``), no ROS: resident memory and its growth,
the audit of effort commands, parameter-update bookkeeping, the pass/fail criteria, and the
configurations the arm is moved between.

The growth of a process's memory is the slope of a least-squares line through its resident
set size (VmRSS) samples taken after the warm-up, in MB/min (1 MB = 10⁶ bytes). A process
that leaks grows steadily, so over minutes the slope shows it; allocator steps and the
first-use growth of caches belong to the warm-up and are left out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

MB = 1e6


def parse_vmrss(status: str) -> int | None:
    """Resident set size [bytes] from the text of ``/proc/<pid>/status`` (None if absent,
    e.g. a zombie)."""
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            value, unit = line.split()[1:3]
            if unit.lower() != "kb":  # pragma: no cover - the kernel always writes kB
                raise ValueError(f"unexpected VmRSS unit {unit!r}")
            return int(value) * 1024
    return None


#: The parts of VmRSS the kernel reports (``/proc/<pid>/status``): the process's own
#: (anonymous: heap, stacks, the allocator's pools), file pages it maps (libraries), and
#: shared memory it maps (the middleware's shared-memory transport segments, counted in
#: every process that maps them).
RSS_PARTS = ("RssAnon", "RssFile", "RssShmem")


def parse_rss_parts(status: str) -> dict[str, int]:
    """The :data:`RSS_PARTS` [bytes] found in the text of ``/proc/<pid>/status``."""
    parts = {}
    for line in status.splitlines():
        key, _, rest = line.partition(":")
        if key in RSS_PARTS:
            parts[key] = int(rest.split()[0]) * 1024
    return parts


def parse_cpu_seconds(stat: str, ticks_per_second: float) -> float:
    """CPU time [s] a process has used (user + system) from the text of
    ``/proc/<pid>/stat``: its fields 14 and 15, counted after the command name, which is in
    parentheses and may hold spaces or parentheses of its own."""
    fields = stat.rpartition(")")[2].split()  # from field 3 (the state) on
    return (int(fields[11]) + int(fields[12])) / ticks_per_second


#: The columns of ``/proc/stat``'s ``cpu`` line, in the kernel's order.
_CPU_COLUMNS = ("user", "nice", "system", "idle", "iowait", "irq", "softirq", "steal")


def parse_system_cpu(stat: str, ticks_per_second: float) -> dict[str, float]:
    """The machine's CPU time [s] since boot, summed over its cores, from the text of
    ``/proc/stat``: ``busy`` (user, nice, system, irq, softirq), ``idle`` (idle, iowait) and
    ``steal`` (time the hypervisor gave another guest: a slower machine that no process of
    this one caused)."""
    line = next(row for row in stat.splitlines() if row.startswith("cpu "))
    ticks = dict(zip(_CPU_COLUMNS, (int(x) for x in line.split()[1:]), strict=False))
    busy = sum(ticks.get(k, 0) for k in ("user", "nice", "system", "irq", "softirq"))
    idle = ticks.get("idle", 0) + ticks.get("iowait", 0)
    return {
        "busy": busy / ticks_per_second,
        "idle": idle / ticks_per_second,
        "steal": ticks.get("steal", 0) / ticks_per_second,
    }


def cores_used(
    times_s: Sequence[float], cpu_s: Sequence[float], window_s: float = 60.0
) -> tuple[float, float]:
    """Cores a process kept busy from samples of its CPU time: the mean over the samples'
    span, and the highest mean over ``window_s`` (between the samples nearest that apart).
    NaN for both with fewer than two samples."""
    t = np.asarray(times_s, dtype=float)
    c = np.asarray(cpu_s, dtype=float)
    if t.size < 2 or t[-1] <= t[0]:
        return math.nan, math.nan
    mean = float((c[-1] - c[0]) / (t[-1] - t[0]))
    ends = np.searchsorted(t, t + window_s)  # the first sample at least window_s later
    inside = ends < t.size
    if not inside.any():
        return mean, mean
    start = np.flatnonzero(inside)
    end = ends[inside]
    rates = (c[end] - c[start]) / (t[end] - t[start])
    return mean, float(rates.max())


def format_cpu(series: Mapping[str, tuple[Sequence[float], Sequence[float]]]) -> str:
    """One line per process (or the machine's ``busy`` and ``steal``): the cores it kept
    busy, on average and in its busiest minute."""
    lines = ["CPU (cores kept busy: mean, busiest minute):"]
    for name, (t, cpu) in series.items():
        mean, peak = cores_used(t, cpu)
        if not math.isnan(mean):
            lines.append(f"  {name:34s} {mean:5.2f} {peak:5.2f}")
    return "\n".join(lines)


def slope_per_minute(times_s: Sequence[float], values: Sequence[float]) -> float:
    r"""Least-squares slope of ``values`` over ``times_s`` [s], per minute:
    b = Σ(tᵢ − t̄)(yᵢ − ȳ) / Σ(tᵢ − t̄)² · 60. NaN with fewer than two distinct times."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.size < 2:
        return math.nan
    dt = t - t.mean()
    ss = float(dt @ dt)
    if ss == 0.0:
        return math.nan
    return float(dt @ (y - y.mean())) / ss * 60.0


def _theil_sen_per_minute(
    t: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None, points: int = 600
) -> float:
    """The median of the slopes (yⱼ − yᵢ)/(tⱼ − tᵢ) [per minute] over the pairs i < j (of at
    most ``points`` samples, evenly thinned), only pairs within one group when ``groups``
    labels the samples; NaN without such a pair over distinct times."""
    if t.size > points:
        keep = np.linspace(0, t.size - 1, points).round().astype(int)
        t, y = t[keep], y[keep]
        groups = None if groups is None else groups[keep]
    i, j = np.triu_indices(t.size, k=1)
    dt = t[j] - t[i]
    ok = dt > 0
    if groups is not None:
        ok &= groups[i] == groups[j]
    if not ok.any():
        return math.nan
    return float(np.median((y[j] - y[i])[ok] / dt[ok])) * 60.0


def median_slope_per_minute(
    times_s: Sequence[float], values: Sequence[float], points: int = 600
) -> float:
    r"""Theil–Sen slope of ``values`` over ``times_s`` [s], per minute: the median of the
    slopes (yⱼ − yᵢ)/(tⱼ − tᵢ) over every pair i < j (of at most ``points`` samples, evenly
    thinned). Steady growth gives its rate; a single step (an allocator's high-water mark
    at one fault) gives 0, since at most half of the pairs straddle it; steps that recur
    through the series make most pairs straddle one and show as growth. NaN with fewer than
    two distinct times."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(values, dtype=float)
    return _theil_sen_per_minute(t, y, points=points)


def step_rises(
    times_s: Sequence[float], values: Sequence[float], step: float, window_s: float
) -> np.ndarray:
    """Per interval between consecutive samples (one fewer than the samples), whether it is
    part of a step: a rise of at least ``step`` from a sample to a later one at most
    ``window_s`` [s] after it (the highest in that window) marks the intervals between the
    two that rise. A high-water mark taken at once or over seconds is a step; growth slower
    than ``step`` per ``window_s`` is not."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(values, dtype=float)
    rising = np.diff(y) > 0.0
    marked = np.zeros_like(rising)
    ends = np.searchsorted(t, t + window_s, side="right")
    for i in range(y.size - 1):
        window = y[i + 1 : ends[i]]
        if window.size and window.max() - y[i] >= step:
            top = i + 1 + int(np.argmax(window))
            marked[i:top] |= rising[i:top]
    return marked


def plateaus(
    times_s: Sequence[float], values: Sequence[float], step: float, window_s: float
) -> np.ndarray:
    """A label per sample: it changes at every interval that is part of a step
    (:func:`step_rises`), so each label is a plateau between steps and the samples a step
    passes through stand alone."""
    y = np.asarray(values, dtype=float)
    if y.size == 0:
        return np.zeros(0, dtype=int)
    return np.concatenate([[0], np.cumsum(step_rises(times_s, y, step, window_s))]).astype(int)


def steady_slope_per_minute(
    times_s: Sequence[float],
    values: Sequence[float],
    step: float,
    window_s: float,
    points: int = 600,
) -> float:
    r"""Theil–Sen slope [per minute] between steps: over the pairs of samples with no step
    (:func:`step_rises`) between them (:func:`plateaus`). A process's steady growth, however
    many one-off steps its faults cause (each step is reported on its own); NaN when no
    plateau holds two samples at distinct times."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(values, dtype=float)
    return _theil_sen_per_minute(t, y, plateaus(t, y, step, window_s), points)


def steps_of(
    times_s: Sequence[float], values: Sequence[float], step: float, window_s: float
) -> list[tuple[float, float]]:
    """Each step as (time [s] of its first sample, its rise to its last): the intervals of
    :func:`step_rises`, those less than ``window_s`` apart taken as one step (a rise that
    pauses for a sample is one high-water mark)."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(values, dtype=float)
    steps: list[list[int]] = []  # [first interval, last interval]
    for k in np.flatnonzero(step_rises(t, y, step, window_s)):
        if steps and t[k] - t[steps[-1][1] + 1] < window_s:
            steps[-1][1] = int(k)
        else:
            steps.append([int(k), int(k)])
    return [(float(t[a]), float(y[b + 1] - y[a])) for a, b in steps]


def largest_step(times_s: Sequence[float], values: Sequence[float]) -> tuple[float, float]:
    """The largest rise between two consecutive samples and the time [s] of the later one
    ((0, NaN) with fewer than two samples)."""
    y = np.asarray(values, dtype=float)
    if y.size < 2:
        return 0.0, math.nan
    rise = np.diff(y)
    k = int(np.argmax(rise))
    return float(max(rise[k], 0.0)), float(np.asarray(times_s, dtype=float)[k + 1])


#: A rise of at least STEP_MB [MB] within STEP_WINDOW_S [s] is a step: a high-water mark
#: taken at a fault, at once (a megabyte message's buffers: 1-10 MB between two samples 2 s
#: apart) or over seconds (a writer keeping samples for a killed reader until its lease ends:
#: 5.5 MB over 18 s at 250 Hz). A steady 30 MB/h is 0.25 MB in STEP_WINDOW_S, far below a
#: step; growth at 240 MB/h and more is all steps, and fails over the run
#: (``fault_metrics.run_growth``) instead.
STEP_MB = 2.0
STEP_WINDOW_S = 30.0


def memory_summary(
    times_s: Sequence[float],
    rss_bytes: Sequence[float],
    warmup_s: float,
    step_mb: float = STEP_MB,
    window_s: float = STEP_WINDOW_S,
) -> dict[str, Any]:
    """RSS figures of one process [MB]: at the first sample after the warm-up (``start``),
    at the last (``end``), the largest over the whole run (``max``), the growth slope after
    the warm-up [MB/min] (least squares, Theil–Sen: ``median_slope_mb_per_min``, and
    Theil–Sen between steps of ``step_mb`` or more within ``window_s``:
    ``steady_slope_mb_per_min``), its steps (``steps``, their sum ``steps_mb``), its
    largest rise between two samples (``largest_step_mb``, at ``largest_step_s``) and the
    time span the slopes cover [min]."""
    t = np.asarray(times_s, dtype=float)
    y = np.asarray(rss_bytes, dtype=float) / MB
    after = t >= warmup_s
    ta, ya = t[after], y[after]
    largest_mb, largest_s = largest_step(ta, ya)
    steps = steps_of(ta, ya, step_mb, window_s)
    nan = math.nan
    return {
        "samples": int(t.size),
        "samples_after_warmup": int(ta.size),
        "start_mb": float(ya[0]) if ya.size else nan,
        "end_mb": float(ya[-1]) if ya.size else nan,
        "max_mb": float(y.max()) if y.size else nan,
        "first_mb": float(y[0]) if y.size else nan,
        "growth_mb": float(ya[-1] - ya[0]) if ya.size else nan,
        "slope_mb_per_min": slope_per_minute(ta, ya),
        "median_slope_mb_per_min": median_slope_per_minute(ta, ya),
        "steady_slope_mb_per_min": steady_slope_per_minute(ta, ya, step_mb, window_s),
        "steps": len(steps),
        "steps_mb": float(sum(rise for _, rise in steps)),
        "largest_step_mb": largest_mb,
        "largest_step_s": largest_s,
        "span_min": float(ta[-1] - ta[0]) / 60.0 if ta.size else 0.0,
    }


def move_targets(
    lower: np.ndarray, upper: np.ndarray, fraction: float = 0.15
) -> tuple[np.ndarray, np.ndarray]:
    """Two configurations inside the position limits [rad]: mid-range ± ``fraction`` of the
    range, the sign alternating from joint to joint (±0.5 rad around 0 for a joint without
    limits)."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    bounded = np.isfinite(lower) & np.isfinite(upper)
    lo, hi = np.where(bounded, lower, -1.0), np.where(bounded, upper, 1.0)
    mid = np.where(bounded, 0.5 * (lo + hi), 0.0)
    half = np.where(bounded, fraction * (hi - lo), 0.5)
    sign = np.where(np.arange(lower.size) % 2 == 0, 1.0, -1.0)
    return mid + sign * half, mid - sign * half


@dataclass
class CommandAudit:
    """Every effort command checked against the URDF effort limits: finite, and
    |τᵢ| ≤ limitᵢ (plus ``tolerance`` [N·m] for rounding), each named joint known."""

    joints: tuple[str, ...]
    limits: np.ndarray
    tolerance: float = 1e-9
    commands: int = 0
    violations: int = 0
    non_finite: int = 0
    over_limit: int = 0
    unknown_joints: int = 0
    max_ratio: float = 0.0  # largest |τᵢ| / limitᵢ seen
    examples: list[str] = field(default_factory=list)
    _index: dict[tuple[str, ...], np.ndarray | None] = field(default_factory=dict, repr=False)

    def check(self, names: Sequence[str], effort: np.ndarray) -> bool:
        """Count one command; True when it is safe."""
        self.commands += 1
        key = tuple(names)
        index = self._index.get(key, ...)
        if index is ...:
            position = {j: k for k, j in enumerate(self.joints)}
            index = (
                np.array([position[n] for n in key], dtype=int)
                if all(n in position for n in key) and len(key) == len(effort)
                else None
            )
            self._index[key] = index
        if index is None:
            self.unknown_joints += 1
            return self._violation(f"names {list(key)} with {len(effort)} efforts")
        effort = np.asarray(effort, dtype=float)
        if not np.isfinite(effort).all():
            self.non_finite += 1
            return self._violation(f"non-finite effort {effort.tolist()}")
        limits = self.limits[index]
        ratio = float(np.max(np.abs(effort) / limits)) if effort.size else 0.0
        self.max_ratio = max(self.max_ratio, ratio)
        if np.any(np.abs(effort) > limits + self.tolerance):
            self.over_limit += 1
            return self._violation(f"effort {effort.tolist()} beyond limits {limits.tolist()}")
        return True

    def _violation(self, what: str) -> bool:
        self.violations += 1
        if len(self.examples) < 5:
            self.examples.append(what)
        return False

    def figures(self) -> dict[str, Any]:
        return {
            "commands": self.commands,
            "violations": self.violations,
            "non_finite": self.non_finite,
            "over_limit": self.over_limit,
            "unknown_joints": self.unknown_joints,
            "max_effort_over_limit": self.max_ratio,
            "examples": list(self.examples),
        }


@dataclass
class UpdateTally:
    """Parameter updates sent and how the node answered: valid ones must be accepted,
    invalid ones rejected with the old values kept."""

    valid_sent: int = 0
    valid_accepted: int = 0
    invalid_sent: int = 0
    invalid_rejected: int = 0
    kept_after_reject: int = 0  # rejections after which the node still had the old values
    reasons: list[str] = field(default_factory=list)

    def valid(self, accepted: bool) -> None:
        self.valid_sent += 1
        self.valid_accepted += int(accepted)

    def invalid(self, rejected: bool, reason: str, kept: bool) -> None:
        self.invalid_sent += 1
        self.invalid_rejected += int(rejected)
        self.kept_after_reject += int(rejected and kept)
        if reason and reason not in self.reasons:
            self.reasons.append(reason)

    def figures(self) -> dict[str, Any]:
        return {
            "valid_sent": self.valid_sent,
            "valid_accepted": self.valid_accepted,
            "invalid_sent": self.invalid_sent,
            "invalid_rejected": self.invalid_rejected,
            "old_values_kept_after_reject": self.kept_after_reject,
            "reject_reasons": list(self.reasons),
        }


def numeric_values(status: Mapping[str, Any]) -> dict[str, float]:
    """The numeric entries of a parsed diagnostics status (every key the node publishes,
    counters added later included; text values such as ``message`` left out)."""
    return {
        k: float(v)
        for k, v in status.items()
        if isinstance(v, int | float) and not isinstance(v, bool)
    }


@dataclass(frozen=True)
class Thresholds:
    """Pass/fail limits of a soak run."""

    #: Largest RSS growth after the warm-up [MB/min], per node process.
    max_slope_mb_per_min: float = 1.0
    #: The slope is judged only when the samples after the warm-up span this long [min]:
    #: over seconds an allocator step looks like a leak.
    min_span_min: float = 2.0
    #: Unsafe effort commands allowed (non-finite or beyond the URDF limits).
    max_violations: int = 0


@dataclass(frozen=True)
class Criterion:
    name: str
    met: bool | None  # None: not judged (the run was too short for it)
    detail: str


def verdict(report: Mapping[str, Any], thresholds: Thresholds = Thresholds()) -> list[Criterion]:
    """The criteria of a soak report (as written to soak.json): memory growth per node
    process, unsafe commands, commands not checked, parameter updates answered as they
    must be, diagnostics received and every node alive to the end."""
    out = []
    for name, mem in report["memory"].items():
        if not mem.get("node", True):
            continue
        slope = mem["slope_mb_per_min"]
        if mem["span_min"] < thresholds.min_span_min or math.isnan(slope):
            met = None
            detail = (
                f"{slope:+.3f} MB/min over {mem['span_min']:.2f} min: not judged "
                f"(needs {thresholds.min_span_min:g} min after the warm-up)"
            )
        else:
            met = slope < thresholds.max_slope_mb_per_min
            detail = f"{slope:+.3f} MB/min (limit {thresholds.max_slope_mb_per_min:g})"
        out.append(Criterion(f"memory growth of {name}", met, detail))
    cmd = report["commands"]
    out.append(
        Criterion(
            "effort commands finite and within the URDF limits",
            cmd["commands"] > 0 and cmd["violations"] <= thresholds.max_violations,
            f"{cmd['violations']} violations in {cmd['commands']} commands",
        )
    )
    ticks = report.get("controller_ticks")
    if ticks is not None:
        out.append(
            Criterion(
                "every controller tick's command checked",
                cmd["commands"] >= ticks,
                f"{cmd['commands']} commands checked, {int(ticks)} controller ticks",
            )
        )
    upd = report["parameter_updates"]
    out.append(
        Criterion(
            "every valid gain change accepted",
            upd["valid_sent"] > 0 and upd["valid_accepted"] == upd["valid_sent"],
            f"{upd['valid_accepted']}/{upd['valid_sent']} accepted",
        )
    )
    out.append(
        Criterion(
            "every invalid update rejected, old values kept",
            upd["invalid_sent"] > 0
            and upd["invalid_rejected"] == upd["invalid_sent"]
            and upd["old_values_kept_after_reject"] == upd["invalid_sent"],
            f"{upd['invalid_rejected']}/{upd['invalid_sent']} rejected, "
            f"{upd['old_values_kept_after_reject']} with the old values kept",
        )
    )
    for node, count in report["diagnostics_received"].items():
        out.append(
            Criterion(
                f"/diagnostics from {node}",
                count > 0,
                f"{count} statuses",
            )
        )
    return out


def passed(criteria: Sequence[Criterion]) -> bool:
    """No criterion failed (the ones not judged do not count)."""
    return all(c.met is not False for c in criteria)
