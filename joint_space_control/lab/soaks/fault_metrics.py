"""Figures and verdict of a fault soak (``jsc soak --faults``), no ROS: how long tracking takes
to come back after each injected fault, how far the arm moves while no controller is in
command, the torques the plant applied, the states missing from the bags, and the memory of
every process incarnation.

The inputs are arrays (a :class:`Timeline` of the whole run, read from its bags by
:mod:`.fault_timeline`) and the runner's fault log (:class:`FaultRecord`); all times are wall
clock [s since the epoch] (the recorder of a fault soak stamps messages with the system
clock), angles [rad], torques [N·m].

The tracking error of the controller is e(t) = maxⱼ |q_d,ⱼ(t) − qⱼ(t)| [rad], from its
``~/state`` rows. A fault is over at its ``end`` (process back and serving, burst sent, hogs
stopped); its *recovery time* is how long after that e takes to come back below a bound and
stay there (:func:`recovery_time`). Missing controller rows count as not tracking: a dead
controller does not track.

The defaults of :class:`FaultThresholds` are first guesses, to be tuned against real runs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from joint_space_control.lab.soaks.loop_digest import LoopSample
from joint_space_control.lab.soaks.soak_metrics import (
    MB,
    Criterion,
    median_slope_per_minute,
    memory_summary,
)

#: The fault kinds the runner injects, in the order the figure gives them colours.
KINDS = (
    "kill_controller",
    "kill_simulator",
    "kill_recorder",
    "rogue_commander",
    "malformed_burst",
    "invalid_parameters",
    "huge_reference",
    "second_reference",
    "cpu_hogs",
    "kill_dashboard",
    "second_clock",
)
#: Plant state period of the fault soak at its default rate (1 kHz) [ns].
PERIOD_NS = 1_000_000


@dataclass(frozen=True)
class FaultRecord:
    """One injected fault as the runner logs it; ``start`` and ``end`` [s since the epoch]:
    when the injection began and when it was over (the process back and serving, the burst
    sent, the hogs stopped)."""

    index: int
    kind: str
    start: float
    end: float
    detail: str = ""


@dataclass(frozen=True)
class BagSpan:
    """One bag of the run and how it was read.

    ``status``: ``complete`` (it had its metadata.yaml), ``recovered`` (it had none, the
    recorder was killed: its recovered copy ``read`` was read), ``unreadable`` (neither
    worked; ``detail`` says why). ``first``/``last`` [s since the epoch]: log times of its
    first and last message (NaN without messages); ``states``/``joint_states``: rows read.
    """

    path: Path
    read: Path | None
    status: str
    detail: str = ""
    first: float = math.nan
    last: float = math.nan
    states: int = 0
    joint_states: int = 0


@dataclass(frozen=True)
class Timeline:
    """The whole run as arrays, bags concatenated in time order.

    Controller (one row per ``~/state`` message):
    - ``state_wall`` (N,): receive time [s since the epoch];
    - ``error`` (N,): e = maxⱼ |q_d,ⱼ − qⱼ| [rad] (:func:`tracking_error`).

    Plant (one row per ``/joint_states`` message), joints in ``joints`` order:
    - ``js_wall`` (M,): receive time [s since the epoch];
    - ``js_stamp_ns`` (M,): header stamp [ns] (simulation time, int64);
    - ``position`` (M, n) [rad], ``effort`` (M, n): torque the plant applied [N·m];
    - ``js_bag`` (M,): index in ``bags`` of the bag each state was read from.
    """

    joints: tuple[str, ...]
    state_wall: np.ndarray
    error: np.ndarray
    js_wall: np.ndarray
    js_stamp_ns: np.ndarray
    position: np.ndarray
    effort: np.ndarray
    js_bag: np.ndarray
    bags: tuple[BagSpan, ...] = ()
    loops: tuple[LoopSample, ...] = ()  # the nodes' /diagnostics, where recorded

    @property
    def recovered(self) -> list[Path]:
        """The bags that had to be recovered (recorder killed)."""
        return [b.path for b in self.bags if b.status == "recovered"]

    @property
    def start(self) -> float:
        """First receive time of any row [s since the epoch] (NaN if there is none)."""
        times = [a.min() for a in (self.state_wall, self.js_wall) if a.size]
        return float(min(times)) if times else math.nan

    @property
    def end(self) -> float:
        """Last receive time of any row [s since the epoch] (NaN if there is none)."""
        times = [a.max() for a in (self.state_wall, self.js_wall) if a.size]
        return float(max(times)) if times else math.nan


@dataclass(frozen=True)
class FaultThresholds:
    """Pass/fail limits of a fault soak. First guesses, to be tuned against real runs."""

    #: Tracking bound on e = maxⱼ |q_d,ⱼ − qⱼ| [rad] …
    tracking_bound: float = 0.02
    #: … held this long [s] for tracking to count as back.
    hold_s: float = 1.0
    #: Longer than this [s] without a controller row counts as not tracking (a row per
    #: period; the recorder may receive late under CPU load, hence the margin).
    max_gap_s: float = 0.1
    #: Largest recovery time after a fault's end [s].
    max_recovery_s: float = 10.0
    #: Largest arm motion |q − q(start)| while no controller is in command [rad] …
    max_motion: float = 0.05
    #: … judged for these kinds (braked after a killed controller; a rogue commander whose
    #: commands the plant must refuse). The motion is measured against q at the fault's
    #: start, so the reference must hold still during these faults.
    motion_kinds: tuple[str, ...] = ("kill_controller", "rogue_commander")
    #: Relative tolerance on the effort limits: |τⱼ| > limitⱼ·(1 + tol) is beyond them.
    effort_rel_tol: float = 1e-6
    #: States allowed to be missing inside a bag (gaps between two recorded states).
    max_lost_inside: int = 0
    #: Stamp period of the plant's states [ns].
    period_ns: int = PERIOD_NS
    #: Largest RSS growth of a process [MB/h], judged twice: each incarnation after its
    #: warm-up between steps (Theil–Sen over pairs of samples with no step, a rise of
    #: ``soak_metrics.STEP_MB`` within ``STEP_WINDOW_S``, between them: steady growth; a
    #: high-water mark at a fault is reported as a step, not judged as growth), and each
    #: process over the whole run, its incarnations' samples after their warm-ups together
    #: (Theil–Sen: steps that recur at every fault or restart show there as growth).
    max_slope_mb_per_hour: float = 30.0
    #: An incarnation's slope is judged only over at least this long after its warm-up [min].
    min_span_min: float = 5.0
    #: Warm-up of each process incarnation, from its first sample [s].
    warmup_s: float = 60.0


# --------------------------------------------------------------------------- single figures


def tracking_error(q_d: np.ndarray, q: np.ndarray) -> np.ndarray:
    """e = maxⱼ |q_d,ⱼ − qⱼ| per row [rad] of (N, n) arrays; NaN where a value is NaN."""
    diff = np.abs(np.asarray(q_d, dtype=float) - np.asarray(q, dtype=float))
    if diff.shape[0] == 0:
        return np.empty(0)
    return diff.max(axis=1)  # NaN propagates: a row with a NaN is not tracking


def recovery_time(
    t: np.ndarray,
    error: np.ndarray,
    after: float,
    bound: float,
    hold: float,
    until: float = math.inf,
    max_gap: float = math.inf,
) -> float:
    """Seconds from ``after`` to the first instant t* from which e stays below ``bound``
    for at least ``hold`` seconds: t* is the time of a sample with e < bound that starts a
    run of samples all below the bound, without a gap longer than ``max_gap`` between two of
    them, whose last sample is at t ≥ t* + hold. Only samples with ``after`` ≤ t < ``until``
    count (the next fault's start, say); NaN when no such run exists.

    A missing stretch of rows (a dead controller) is not tracking: the time before the first
    sample counts, and a gap > ``max_gap`` ends a run. NaN errors are not below the bound.
    Units: ``t``, ``after``, ``until``, ``hold``, ``max_gap`` [s]; ``error``, ``bound`` [rad].
    Result [s], within one sample period of the exact instant for a continuous e.
    """
    t = np.asarray(t, dtype=float)
    e = np.asarray(error, dtype=float)
    inside = (t >= after) & (t < until)
    ts, good = t[inside], e[inside] < bound
    if not good.any():
        return math.nan
    linked = good[:-1] & good[1:] & (np.diff(ts) <= max_gap)
    starts = np.flatnonzero(good & ~np.concatenate(([False], linked)))
    ends = np.flatnonzero(good & ~np.concatenate((linked, [False])))
    held = ts[ends] - ts[starts] >= hold - 1e-9
    if not held.any():
        return math.nan
    return float(ts[starts[np.argmax(held)]] - after)


def largest_motion(t: np.ndarray, q: np.ndarray, start: float, end: float) -> float:
    """maxⱼ max over start ≤ t ≤ end of |qⱼ(t) − qⱼ(start)| [rad]: how far the arm moved in
    the window. q(start) is the last sample at or before ``start`` (the first in the window
    when there is none). NaN without samples in the window; NaN entries are left out.
    ``t`` [s], ``q`` (N, n) [rad]."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    window = (t >= start) & (t <= end)
    if not window.any():
        return math.nan
    before = np.flatnonzero(t <= start)
    ref = q[before[np.argmax(t[before])]] if before.size else q[np.flatnonzero(window)[0]]
    moved = np.abs(q[window] - ref)
    return float(np.nanmax(moved)) if np.isfinite(moved).any() else math.nan


def efforts_beyond(effort: np.ndarray, limits: np.ndarray | float, rel_tol: float = 1e-6) -> int:
    """Number of rows of ``effort`` (N, n) [N·m] with some |τⱼ| > limitⱼ·(1 + rel_tol):
    recorded states in which the plant applied a torque beyond the effort limits ``limits``
    (one per joint, or one for all). NaN entries (no effort recorded) do not count, ±inf
    does."""
    return int(np.count_nonzero(_beyond_rows(effort, limits, rel_tol)))


def peak_effort_ratio(effort: np.ndarray, limits: np.ndarray | float) -> float:
    """maxᵢⱼ |τᵢⱼ| / limitⱼ over the finite entries (0 without any): 1 is at the limit."""
    ratio = np.abs(np.asarray(effort, dtype=float)) / np.asarray(limits, dtype=float)
    finite = ratio[np.isfinite(ratio)]
    return float(finite.max()) if finite.size else 0.0


@dataclass(frozen=True)
class Gap:
    """States missing before the recorded state ``index`` (stamp ``stamp_ns``)."""

    index: int
    stamp_ns: int
    missing: int


@dataclass(frozen=True)
class LostStates:
    """What :func:`lost_states` found: states missing in total, where, and how many times
    the stamps started again (simulator restarts)."""

    total: int
    gaps: tuple[Gap, ...]
    restarts: int


def lost_states(stamp_ns: np.ndarray, period_ns: int = PERIOD_NS) -> LostStates:
    """States missing from a series of recorded plant stamps [ns].

    The plant stamps its k-th state k·T (T = ``period_ns``). Between two consecutive
    recorded stamps a < b, round((b − a)/T) − 1 states are missing. A stamp that decreases
    starts a new run (the simulator was restarted and counts from 0 again): nothing is
    counted across it, nor before a run's first recorded state. Equal stamps (a state
    recorded twice) count nothing.
    """
    s = np.asarray(stamp_ns, dtype=np.int64)
    d = np.diff(s)
    steps = (d + period_ns // 2) // period_ns  # round(d / T) in integers
    missing = np.where(d > 0, np.maximum(steps - 1, 0), 0)
    where = np.flatnonzero(missing)
    gaps = tuple(Gap(int(i + 1), int(s[i + 1]), int(missing[i])) for i in where)
    return LostStates(int(missing.sum()), gaps, int(np.count_nonzero(d < 0)))


def states_lost_at_kill(kill_time: float, last_log_time: float, rate_hz: float = 1000.0) -> int:
    """Estimate of the states a killed recorder received but never wrote: those published
    between the last message of its bag (log time ``last_log_time``) and the kill
    (``kill_time``, both [s since the epoch]), ⌊(kill − last)·rate⌋ at the plant's
    ``rate_hz``. An estimate: it assumes a steady publication rate and a receive time equal
    to the publication time (the recorder writes at least every flush period, so this is
    about that period's worth at most)."""
    if not (math.isfinite(kill_time) and math.isfinite(last_log_time)):
        return 0
    return max(0, math.floor((kill_time - last_log_time) * rate_hz))


# --------------------------------------------------------------------------- per fault


@dataclass(frozen=True)
class FaultOutcome:
    """What one fault did; times [s since the epoch] and [s], angles [rad].

    - ``until``: end of the window judged after the fault (the next fault's start, or the
      end of the run);
    - ``recovery_s``: :func:`recovery_time` from ``end`` to ``until``; NaN: not back;
    - ``peak_error``: largest e over [start, until) (NaN: no controller row);
    - ``motion``: :func:`largest_motion` over [start, end] for the kinds where no
      controller is in command (None for the other kinds; NaN: no plant state);
    - ``efforts_beyond``: plant states in [start, until) beyond the effort limits;
    - ``lost``: states missing (stamp gaps) whose next recorded state arrived in
      [start, until); ``lost_inside``: those of gaps inside one bag (the rest are between
      two bags: the recorder was down);
    - ``lost_at_kill``: for ``kill_recorder``, :func:`states_lost_at_kill` of the bag the
      killed recorder was writing (the m-th recorder kill ends the m-th bag); None for the
      other kinds, or without that bag.
    """

    index: int
    kind: str
    start: float
    end: float
    until: float
    recovery_s: float
    peak_error: float
    motion: float | None
    efforts_beyond: int
    lost: int
    lost_inside: int
    lost_at_kill: int | None = None
    detail: str = ""


@dataclass(frozen=True)
class Assessment:
    """Per-fault outcomes and the whole-run figures behind the verdict."""

    outcomes: list[FaultOutcome]
    lost: LostStates
    lost_inside: int  # states missing from gaps inside one bag
    lost_between: int  # states missing between two bags (the recorder was down)
    efforts_beyond: int  # over the whole run
    peak_effort_ratio: float
    lost_before_faults: int = 0  # states missing before the first fault
    gaps_inside: tuple[Gap, ...] = ()  # the gaps inside one bag


def evaluate(
    faults: Sequence[FaultRecord],
    timeline: Timeline,
    limits: np.ndarray | float,
    thresholds: FaultThresholds = FaultThresholds(),
    run_end: float | None = None,
) -> Assessment:
    """Each fault's outcome (:class:`FaultOutcome`) and the run's totals.

    The window judged after fault i runs from its ``start`` to the next fault's ``start``
    (for the last one: ``run_end``, default the timeline's end). ``limits`` [N·m]: effort
    limits in ``timeline.joints`` order (or one for all).
    """
    faults = sorted(faults, key=lambda f: f.start)
    th = thresholds
    end_of_run = timeline.end if run_end is None else run_end
    lost = lost_states(timeline.js_stamp_ns, th.period_ns)
    bag = timeline.js_bag
    inside = tuple(g for g in lost.gaps if bag[g.index - 1] == bag[g.index])
    inside_ids = {g.index for g in inside}
    gap_wall = np.array([timeline.js_wall[g.index] for g in lost.gaps], dtype=float)
    gap_missing = np.array([g.missing for g in lost.gaps], dtype=np.int64)
    gap_inside = np.array([g.index in inside_ids for g in lost.gaps], dtype=bool)
    beyond_rows = _beyond_rows(timeline.effort, limits, th.effort_rel_tol)

    outcomes = []
    kills = 0  # recorder kills before this fault
    for k, fault in enumerate(faults):
        until = faults[k + 1].start if k + 1 < len(faults) else end_of_run
        in_state = (timeline.state_wall >= fault.start) & (timeline.state_wall < until)
        in_js = (timeline.js_wall >= fault.start) & (timeline.js_wall < until)
        in_gap = (gap_wall >= fault.start) & (gap_wall < until)
        errors = timeline.error[in_state]
        outcomes.append(
            FaultOutcome(
                index=fault.index,
                kind=fault.kind,
                start=fault.start,
                end=fault.end,
                until=until,
                recovery_s=recovery_time(
                    timeline.state_wall,
                    timeline.error,
                    fault.end,
                    th.tracking_bound,
                    th.hold_s,
                    until,
                    th.max_gap_s,
                ),
                peak_error=_nanmax(errors),
                motion=(
                    largest_motion(timeline.js_wall, timeline.position, fault.start, fault.end)
                    if fault.kind in th.motion_kinds
                    else None
                ),
                efforts_beyond=int(np.count_nonzero(beyond_rows[in_js])),
                lost=int(gap_missing[in_gap].sum()),
                lost_inside=int(gap_missing[in_gap & gap_inside].sum()),
                lost_at_kill=(
                    _lost_at_kill(fault, timeline.bags, kills, 1e9 / th.period_ns)
                    if fault.kind == "kill_recorder"
                    else None
                ),
                detail=fault.detail,
            )
        )
        kills += fault.kind == "kill_recorder"
    first = faults[0].start if faults else math.inf
    inside_total = int(gap_missing[gap_inside].sum())
    return Assessment(
        outcomes=outcomes,
        lost=lost,
        lost_inside=inside_total,
        lost_between=lost.total - inside_total,
        efforts_beyond=int(np.count_nonzero(beyond_rows)),
        peak_effort_ratio=peak_effort_ratio(timeline.effort, limits),
        lost_before_faults=int(gap_missing[gap_wall < first].sum()),
        gaps_inside=inside,
    )


def _beyond_rows(effort: np.ndarray, limits: np.ndarray | float, rel_tol: float) -> np.ndarray:
    """Row mask of :func:`efforts_beyond`."""
    effort = np.asarray(effort, dtype=float)
    if effort.size == 0:
        return np.zeros(effort.shape[0], dtype=bool)
    return (np.abs(effort) > np.asarray(limits, dtype=float) * (1.0 + rel_tol)).any(axis=1)


def _nanmax(x: np.ndarray) -> float:
    finite = x[~np.isnan(x)]
    return float(finite.max()) if finite.size else math.nan


def _lost_at_kill(
    fault: FaultRecord, bags: Sequence[BagSpan], kills: int, rate_hz: float
) -> int | None:
    """:func:`states_lost_at_kill` of the bag the killed recorder was writing (the plant
    publishing at ``rate_hz``): with the bags in recording order, one per recorder
    incarnation, the m-th kill (from 0) ends bag m. None when there is no such bag or it
    holds no message."""
    if kills >= len(bags) or not math.isfinite(bags[kills].last):
        return None
    return states_lost_at_kill(fault.start, bags[kills].last, rate_hz)


# --------------------------------------------------------------------------- per kind


@dataclass(frozen=True)
class KindSummary:
    """The faults of one kind: how many, the worst arm motion [rad] (NaN: not judged), the
    longest recovery among those that recovered [s] (NaN: none did), how many did not
    recover, states lost (in total and inside bags), plant states beyond the effort
    limits."""

    kind: str
    count: int
    worst_motion: float
    worst_recovery_s: float
    not_recovered: int
    lost: int
    lost_inside: int
    efforts_beyond: int


def summarize(outcomes: Sequence[FaultOutcome]) -> list[KindSummary]:
    """One :class:`KindSummary` per kind, in :data:`KINDS` order (unknown kinds after)."""
    kinds = sorted(
        {o.kind for o in outcomes},
        key=lambda k: (KINDS.index(k) if k in KINDS else len(KINDS), k),
    )
    out = []
    for kind in kinds:
        group = [o for o in outcomes if o.kind == kind]
        motions = np.array([o.motion for o in group if o.motion is not None], dtype=float)
        recovered = np.array([o.recovery_s for o in group if not math.isnan(o.recovery_s)])
        out.append(
            KindSummary(
                kind=kind,
                count=len(group),
                worst_motion=_nanmax(motions),
                worst_recovery_s=float(recovered.max()) if recovered.size else math.nan,
                not_recovered=len(group) - recovered.size,
                lost=sum(o.lost for o in group),
                lost_inside=sum(o.lost_inside for o in group),
                efforts_beyond=sum(o.efforts_beyond for o in group),
            )
        )
    return out


def format_summary(summaries: Sequence[KindSummary]) -> str:
    """The per-kind table as text (one line per kind, ``-`` where nothing was judged)."""

    def num(x: float, fmt: str) -> str:
        return "-" if math.isnan(x) else format(x, fmt)

    lines = [
        f"{'fault':<20} {'n':>3} {'motion[rad]':>11} {'recovery[s]':>11} {'not back':>8} "
        f"{'lost':>6} {'in bag':>6} {'τ>lim':>6}"
    ]
    for s in summaries:
        lines.append(
            f"{s.kind:<20} {s.count:>3} {num(s.worst_motion, '.4f'):>11} "
            f"{num(s.worst_recovery_s, '.2f'):>11} {s.not_recovered:>8} {s.lost:>6} "
            f"{s.lost_inside:>6} {s.efforts_beyond:>6}"
        )
    return "\n".join(lines)


# --------------------------------------------------------------------------- memory


@dataclass(frozen=True)
class MemorySeries:
    """RSS samples of one incarnation of a process (a killed and restarted node is a new
    incarnation): ``times`` [s] (any origin, e.g. wall clock), ``rss`` [bytes]."""

    name: str
    incarnation: int
    times: Sequence[float]
    rss: Sequence[float]


def incarnation_memory(series: Sequence[MemorySeries], warmup_s: float) -> list[dict[str, Any]]:
    """:func:`.soak_metrics.memory_summary` of each incarnation, its times counted from its
    own first sample (so the warm-up of ``warmup_s`` [s] follows every restart), plus the
    growth slopes per hour [MB/h]: ``slope_mb_per_hour`` (least squares),
    ``median_slope_mb_per_hour`` (Theil–Sen) and ``steady_slope_mb_per_hour`` (Theil–Sen
    between steps, the one judged)."""
    rows = []
    for s in series:
        t = np.asarray(s.times, dtype=float)
        summary = memory_summary(t - t[0] if t.size else t, s.rss, warmup_s)
        rows.append(
            {
                "name": s.name,
                "incarnation": s.incarnation,
                **summary,
                "slope_mb_per_hour": summary["slope_mb_per_min"] * 60.0,
                "median_slope_mb_per_hour": summary["median_slope_mb_per_min"] * 60.0,
                "steady_slope_mb_per_hour": summary["steady_slope_mb_per_min"] * 60.0,
            }
        )
    return rows


def run_growth(series: Sequence[MemorySeries], warmup_s: float) -> dict[str, dict[str, Any]]:
    """Per process name, the growth of its memory over the whole run [MB/h]: the Theil–Sen
    slope of all its incarnations' samples after their warm-ups together (the times share
    one origin), with the span they cover [min] and the number of incarnations. A process
    whose every restart or fault leaves it higher grows here, whatever each incarnation
    does between its steps."""
    samples: dict[str, tuple[list[float], list[float], int]] = {}
    for s in series:
        t = np.asarray(s.times, dtype=float)
        y = np.asarray(s.rss, dtype=float) / MB
        keep = t >= t[0] + warmup_s if t.size else np.zeros(0, dtype=bool)
        times, values, count = samples.get(s.name, ([], [], 0))
        samples[s.name] = (times + t[keep].tolist(), values + y[keep].tolist(), count + 1)
    out = {}
    for name, (times, values, count) in samples.items():
        order = np.argsort(times, kind="stable")
        t, y = np.asarray(times)[order], np.asarray(values)[order]
        out[name] = {
            "name": name,
            "incarnations": count,
            "samples": int(t.size),
            "span_min": float(t[-1] - t[0]) / 60.0 if t.size else 0.0,
            "slope_mb_per_hour": median_slope_per_minute(t, y) * 60.0,
        }
    return out


def worst_growth(
    rows: Sequence[dict[str, Any]], min_span_min: float
) -> dict[str, dict[str, Any] | None]:
    """Per process name, its incarnation with the steepest growth between steps (Theil–Sen)
    among those whose samples after the warm-up span at least ``min_span_min`` [min] (None
    when none does)."""
    out: dict[str, dict[str, Any] | None] = {}
    for row in rows:
        out.setdefault(row["name"], None)
        slope = row["steady_slope_mb_per_hour"]
        if row["span_min"] < min_span_min or math.isnan(slope):
            continue
        best = out[row["name"]]
        if best is None or slope > best["steady_slope_mb_per_hour"]:
            out[row["name"]] = row
    return out


# --------------------------------------------------------------------------- verdict


def fault_verdict(
    faults: Sequence[FaultRecord],
    assessment: Assessment,
    bags: Sequence[BagSpan],
    thresholds: FaultThresholds = FaultThresholds(),
    memory: Sequence[dict[str, Any]] = (),
    run_memory: Mapping[str, dict[str, Any]] | None = None,
) -> list[Criterion]:
    """The criteria of a fault soak (judge with :func:`.soak_metrics.passed`):

    - per kind of :attr:`FaultThresholds.motion_kinds` injected: the arm moved at most
      ``max_motion`` during every such fault (not judged without plant states);
    - per kind injected: tracking back within ``tracking_bound`` (held ``hold_s``) at most
      ``max_recovery_s`` after every such fault's end;
    - no plant state with an applied torque beyond the effort limits;
    - at most ``max_lost_inside`` states missing inside the bags;
    - every bag complete or recovered, and one bag per recorder incarnation;
    - per process (``memory``: rows of :func:`incarnation_memory`): the steepest growth
      between steps of its incarnations long enough to judge at most
      ``max_slope_mb_per_hour``, and (``run_memory``: :func:`run_growth`) its growth over
      the run at most that too.
    """
    th = thresholds
    out = []
    summaries = {s.kind: s for s in summarize(assessment.outcomes)}
    for kind in th.motion_kinds:
        if kind not in summaries:
            continue
        motions = [o.motion for o in assessment.outcomes if o.kind == kind]
        judged = [m for m in motions if m is not None and not math.isnan(m)]
        missing = len(motions) - len(judged)
        if not judged:
            met, detail = None, f"not judged: no plant state during the {len(motions)} faults"
        else:
            met = missing == 0 and max(judged) <= th.max_motion
            detail = f"largest {max(judged):.4f} rad (limit {th.max_motion:g})" + (
                f", {missing} without plant states" if missing else ""
            )
        out.append(Criterion(f"arm still during {kind}", met, detail))
    for kind, s in summaries.items():
        worst = "-" if math.isnan(s.worst_recovery_s) else f"{s.worst_recovery_s:.2f} s"
        out.append(
            Criterion(
                f"tracking back after {kind}",
                s.not_recovered == 0 and s.worst_recovery_s <= th.max_recovery_s,
                f"{s.count - s.not_recovered}/{s.count} back below {th.tracking_bound:g} rad "
                f"for {th.hold_s:g} s, slowest {worst} (limit {th.max_recovery_s:g} s)",
            )
        )
    out.append(
        Criterion(
            "applied efforts within the limits",
            assessment.efforts_beyond == 0,
            f"{assessment.efforts_beyond} states beyond, largest |τ|/limit "
            f"{assessment.peak_effort_ratio:.4f}",
        )
    )
    inside = assessment.gaps_inside
    out.append(
        Criterion(
            "no state lost inside a bag",
            assessment.lost_inside <= th.max_lost_inside,
            f"{assessment.lost_inside} missing in {len(inside)} gaps "
            f"({assessment.lost_between} between bags, {assessment.lost.restarts} restarts)",
        )
    )
    bad = [b for b in bags if b.status not in ("complete", "recovered")]
    recovered = sum(b.status == "recovered" for b in bags)
    out.append(
        Criterion(
            "every bag complete or recovered",
            bool(bags) and not bad,
            f"{len(bags) - recovered - len(bad)} complete, {recovered} recovered"
            + "".join(f"; {b.path}: {b.detail}" for b in bad),
        )
    )
    kills = sum(f.kind == "kill_recorder" for f in faults)
    out.append(
        Criterion(
            "one bag per recorder incarnation",
            len(bags) == kills + 1,
            f"{len(bags)} bags, {kills} recorder kills",
        )
    )
    for name, row in worst_growth(memory, th.min_span_min).items():
        if row is None:
            met, detail = None, f"not judged: no incarnation spans {th.min_span_min:g} min"
        else:
            met = row["steady_slope_mb_per_hour"] <= th.max_slope_mb_per_hour
            detail = (
                f"{row['steady_slope_mb_per_hour']:+.2f} MB/h over {row['span_min']:.1f} min "
                f"(incarnation {row['incarnation']}; limit {th.max_slope_mb_per_hour:g}; "
                f"{row['steps']} steps, {row['steps_mb']:+.1f} MB, the largest "
                f"{row['largest_step_mb']:+.1f} MB at {row['largest_step_s']:.0f} s; "
                f"Theil-Sen across them {row['median_slope_mb_per_hour']:+.1f} MB/h)"
            )
        out.append(Criterion(f"memory growth of {name} between steps", met, detail))
    for name, row in (run_memory or {}).items():
        if row["span_min"] < th.min_span_min or math.isnan(row["slope_mb_per_hour"]):
            met = None
            detail = f"not judged: {row['span_min']:.1f} min after the warm-ups"
        else:
            met = row["slope_mb_per_hour"] <= th.max_slope_mb_per_hour
            detail = (
                f"{row['slope_mb_per_hour']:+.2f} MB/h over {row['span_min']:.1f} min, "
                f"{row['incarnations']} incarnations (limit {th.max_slope_mb_per_hour:g})"
            )
        out.append(Criterion(f"memory growth of {name} over the run", met, detail))
    return out
