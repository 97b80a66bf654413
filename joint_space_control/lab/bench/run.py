"""``jsc bench``: every benchmark in one run, a table on stdout and ``bench.json``.

Sections (all by default): ``compute`` (laws and Pinocchio calls per tick, no ROS),
``in_process`` (plant + law in one process, no ROS), ``simulate`` (``simulate()`` of 1 s
of the iiwa under inverse dynamics with its Response and metrics, on each engine),
``physics`` (one physics step of the plant per robot and engine, PyBullet and MuJoCo, in
process), ``pingpong`` (plain rclpy),
``lockstep`` (sim_bridge + controller over ROS 2; the bench's own loop also with
``engine:=mujoco``), ``realtime`` (1 kHz on the wall clock, with the
machine's floor: a bare Python thread paced the same way), ``analyze`` (``jsc analyze``
per million messages) and ``sweep`` (runs per minute of a fixed sweep on a Dask LocalCluster
of 1 and then 2 workers, and where a run's wall time goes; skipped by ``--quick``) and
``dashboard`` (lockstep steps/s and realtime on-time without and with the dashboard and its
page open in a browser, in alternating pairs, with each process's CPU; bench.dashboard) and
``watched`` (the realtime loop while Chromium opens its page, and beside three CPU hogs,
with the middleware threads at normal and at the default scheduling; bench.watched; skipped
by ``--quick``).
Ping-pong and lockstep (its loops on both engines) alternate in ``rounds`` (each row is the
median round, ``rounds`` keeps them all). ``ratios`` and ``goals`` are derived; the CPU time
the hypervisor took during each part (``cpu_steal_fraction``) says how much the machine
itself was disturbed.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from joint_space_control import machine, scheduling
from joint_space_control.json_values import jsonable
from joint_space_control.lab.bench import compute
from joint_space_control.lab.bench.load import cpu_hog

SECTIONS = (
    "compute",
    "in_process",
    "simulate",
    "physics",
    "pingpong",
    "lockstep",
    "realtime",
    "analyze",
    "sweep",
    "dashboard",
    "watched",
)
#: The realtime runs (and their floors): quiet and with a CPU hog on every core
#: (bench.load), each at normal scheduling and at the nodes' default thread_priority.
REALTIME_PRIORITIES = (0, 50)
REALTIME_CASES = tuple((load, p) for load in ("quiet", "hog") for p in REALTIME_PRIORITIES)
#: Not a section of its own: runs with ``realtime`` (the machine's floor for it).
FLOOR = "realtime_floor"
ROBOTS = ("planar_2dof", "iiwa")
LAWS = tuple(compute.LAWS)
ENGINES = ("pybullet", "mujoco")  # sim_bridge.engines.ENGINES, the default first


@dataclass(frozen=True)
class LockstepKind:
    """One of the lockstep loops of a round: the bench's own or as users run it
    (``as_used``: ros.AS_USERS_RUN_IT, with a recorder), on sim_bridge's ``engine``."""

    as_used: bool = False
    engine: str = "pybullet"


#: The lockstep loops measured in each round, in this order, by result key: the bench's own,
#: the same on MuJoCo right after it (the engines' ratio is paired within the round), and
#: the loop as users run it.
LOCKSTEP_KINDS = {
    "lockstep": LockstepKind(),
    "lockstep_mujoco": LockstepKind(engine="mujoco"),
    "lockstep_as_used": LockstepKind(as_used=True),
}


@dataclass(frozen=True)
class Options:
    """How long each part runs; :meth:`quick` is the < 1 min form (for tests, CI)."""

    ticks: int = 20_000  # law timings per (robot, law)
    in_process_steps: int = 5_000
    simulate_repeats: int = 7  # simulate() calls of 1 s per (engine): the median
    physics_steps: int = 2_000  # physics steps per (robot, engine) in each of physics_repeats
    physics_repeats: int = 5
    pingpong_seconds: float = 6.0
    lockstep_seconds: float = 6.0
    # ping-pong and lockstep alternate this many times, each run for its seconds / rounds:
    # the ratio is the median of ratios measured minutes apart at most, not one of two
    # numbers taken at different moments of a shared, drifting machine
    rounds: int = 3
    realtime_seconds: float = 30.0
    analyze_seconds: float = 20.0  # simulated time recorded for jsc analyze
    floor_seconds: float = 10.0  # 1 kHz pacing without ROS
    realtime_robot: str = "iiwa"
    realtime_law: str = "inverse_dynamics"
    sweep_runs: int = 6  # runs of the sweep (0: the section is skipped)
    sweep_seconds: float = 1.0  # simulated time of each
    sweep_workers: tuple[int, ...] = (1, 2)  # LocalCluster sizes, in this order
    # the dashboard beside the loop: pairs without / with, each run this long
    dashboard_pairs: int = 3
    dashboard_lockstep_seconds: float = 5.0
    dashboard_realtime_seconds: float = 10.0
    dashboard_browser_nice: int = 0  # the page's browser niceness (0: as users run one)
    # the loop watched: pairs (middleware normal / default) of each case, each run this long
    watched_pairs: int = 3
    watched_seconds: float = 20.0

    @classmethod
    def quick(cls) -> Options:
        return cls(
            ticks=1000,
            in_process_steps=500,
            simulate_repeats=2,
            physics_steps=500,
            physics_repeats=3,
            pingpong_seconds=0.5,
            lockstep_seconds=0.5,
            rounds=1,
            realtime_seconds=1.0,
            analyze_seconds=0.5,
            floor_seconds=1.0,
            sweep_runs=0,  # minutes, not seconds: `jsc bench --sections sweep` measures it
            dashboard_pairs=1,
            dashboard_lockstep_seconds=1.0,
            dashboard_realtime_seconds=1.0,
            watched_pairs=0,  # minutes: `jsc bench --sections watched` measures it
        )


def run(
    out: Path,
    options: Options,
    sections: Sequence[str] = SECTIONS,
    log: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Run the sections, write ``out/bench.json`` and ``out/bench.txt``; returns the result."""
    from joint_space_control.lab.bench import ros  # rclpy only when the ROS parts run

    out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    result: dict[str, Any] = {
        "started": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine.machine(),
        "versions": machine.versions(),
        "options": options.__dict__,
        "sections": list(sections),
    }
    steal: dict[str, float | None] = {}
    result["cpu_steal_fraction"] = steal  # CPU time the hypervisor took, per part
    steal_rounds: dict[str, list[float]] = {}

    def measured(name: str, run_part: Callable[[], Any]) -> Any:
        meter = machine.CpuMeter()
        value = run_part()
        fraction = meter.steal()
        if fraction is not None:  # parts run in rounds: the mean over them
            steal_rounds.setdefault(name, []).append(fraction)
            steal[name] = sum(steal_rounds[name]) / len(steal_rounds[name])
        else:
            steal.setdefault(name, None)
        return value

    if "compute" in sections:
        log("compute: laws and Pinocchio calls per tick")
        result["compute"] = measured(
            "compute",
            lambda: [
                compute.law_timings(robot, law, options.ticks) for robot in ROBOTS for law in LAWS
            ],
        )
    if "in_process" in sections:
        log("in_process: plant + law in one process")
        result["in_process"] = measured(
            "in_process",
            lambda: [
                compute.in_process_loop(robot, law, options.in_process_steps)
                for robot in ROBOTS
                for law in LAWS
            ],
        )
    if "simulate" in sections:
        log("simulate: 1 s of the iiwa under inverse dynamics with its Response, per engine")
        result["simulate"] = measured(
            "simulate",
            lambda: [
                compute.simulate_call(
                    "iiwa", "inverse_dynamics", engine, 1.0, options.simulate_repeats
                )
                for engine in ENGINES
                if compute.engine_missing(engine) is None
            ],
        )
    if "physics" in sections:
        log("physics: one plant step per robot and engine, in process")
        physics = measured(
            "physics",
            lambda: compute.physics_steps(
                compute.PHYSICS_ROBOTS, ENGINES, options.physics_steps, options.physics_repeats
            ),
        )
        result["physics"] = {**physics, "ratios": physics_ratios(physics["rows"])}
    # per round and robot, the ping-pong right before the loops it is compared with
    rounds = max(1, options.rounds)
    pingpongs: list[dict[str, Any]] = []
    kinds = dict(LOCKSTEP_KINDS)
    if "lockstep" in sections:
        for key, kind in LOCKSTEP_KINDS.items():
            why = compute.engine_missing(kind.engine)
            if why is not None:
                log(f"{key}: left out: {why}")
                result.setdefault("skipped", {})[key] = why
                del kinds[key]
    loops: dict[str, list[dict[str, Any]]] = {key: [] for key in kinds}
    for k in range(rounds):
        for robot in ROBOTS:
            if "pingpong" in sections:
                row = measured(
                    f"pingpong_{robot}",
                    lambda robot=robot: ros.pingpong(
                        robot, options.pingpong_seconds / rounds, log
                    ),
                )
                pingpongs.append({**row, "round": k})
            if "lockstep" in sections:
                for key, kind in kinds.items():
                    rows = measured(
                        f"{key}_{robot}",
                        lambda robot=robot, k=k, key=key, kind=kind: ros.lockstep(
                            out / "runs" / f"{key}_{robot}_{k}",
                            robot,
                            LAWS,
                            options.lockstep_seconds / rounds,
                            log,
                            controller_params=ros.AS_USERS_RUN_IT if kind.as_used else None,
                            recorded=kind.as_used,
                            engine=kind.engine,
                        ),
                    )
                    loops[key].extend({**row, "round": k} for row in rows)
    if pingpongs:
        result["pingpong"] = [
            median_row([r for r in pingpongs if r["robot"] == robot], "round_trips_per_s")
            for robot in ROBOTS
        ]
    for key, rows in loops.items():
        if rows:
            result[key] = [
                median_row(
                    [r for r in rows if r["robot"] == robot and r["law"] == law], "steps_per_s"
                )
                for robot in ROBOTS
                for law in LAWS
            ]
    result["rounds"] = {"pingpong": pingpongs, **loops}
    if "realtime" in sections:
        result["fifo_permitted"] = scheduling.fifo_permitted(max(REALTIME_PRIORITIES))
        floors, rows = [], []
        for load, priority in REALTIME_CASES:
            with load_of(load):
                log(
                    f"realtime floor, {load}, thread_priority {priority}: "
                    f"{options.floor_seconds:g} s"
                )
                floor = measured(
                    f"{FLOOR}_{load}_{priority}",
                    lambda p=priority: compute.pacing_floor(options.floor_seconds, p),
                )
                floors.append({**floor, "load": load})
                rows.append(
                    measured(
                        f"realtime_{load}_{priority}",
                        lambda load=load, p=priority: ros.realtime(
                            out / "runs" / f"realtime_{load}_{p}",
                            options.realtime_robot,
                            options.realtime_law,
                            options.realtime_seconds,
                            log,
                            thread_priority=p,
                            load=load,
                        ),
                    )
                )
        result[FLOOR] = floors
        result["realtime"] = rows
    if "analyze" in sections:
        result["analyze"] = measured(
            "analyze",
            lambda: ros.analyze_time(out / "runs" / "analyze", options.analyze_seconds, log),
        )
    if "sweep" in sections:
        if options.sweep_runs > 0:
            from joint_space_control.lab.bench import sweep  # Dask only for this section

            result["sweep"] = measured(
                "sweep",
                lambda: sweep.throughput(
                    out / "runs" / "sweep",
                    options.sweep_runs,
                    options.sweep_seconds,
                    options.sweep_workers,
                    log,
                    engines=("ros", "inprocess"),
                ),
            )
        else:
            result["sweep"] = {"skipped": "--quick: run `jsc bench --sections sweep`"}
    if "dashboard" in sections:
        from joint_space_control.lab.bench import dashboard

        log("dashboard: the loop without and with the dashboard and its page open")
        result["dashboard"] = dashboard.side_by_side(
            out,
            options.dashboard_pairs,
            options.dashboard_lockstep_seconds,
            options.dashboard_realtime_seconds,
            options.realtime_robot,
            options.realtime_law,
            log,
            measured,
            browser_nice=options.dashboard_browser_nice,
        )
    if "watched" in sections:
        if options.watched_pairs > 0:
            from joint_space_control.lab.bench import watched

            log("watched: the realtime loop while Chromium opens its page, and under hogs")
            result["watched"] = watched.watched(
                out,
                options.watched_pairs,
                options.watched_seconds,
                log,
                measured,
            )
        else:
            result["watched"] = {"skipped": "--quick: run `jsc bench --sections watched`"}
    result["ratios"] = ratios(result)
    result["goals"] = goals(result)
    result["duration_s"] = time.monotonic() - started
    (out / "bench.json").write_text(json.dumps(jsonable(result), indent=2, allow_nan=False) + "\n")
    table = format_table(result)
    (out / "bench.txt").write_text(table + "\n")
    return result


def load_of(load: str) -> AbstractContextManager[object]:
    """The load a realtime case runs under."""
    return cpu_hog() if load == "hog" else nullcontext()


def _find(rows: Sequence[dict[str, Any]], **match: Any) -> dict[str, Any] | None:
    for row in rows:
        if all(row.get(k) == v for k, v in match.items()):
            return row
    return None


def median_row(rows: Sequence[dict[str, Any]], key: str) -> dict[str, Any]:
    """The row with the median ``key`` (the lower middle one for an even count), with every
    row's value under ``<key>_rounds``."""
    ordered = sorted(rows, key=lambda r: r[key])
    row = dict(ordered[(len(ordered) - 1) // 2])
    row.pop("round", None)
    row[f"{key}_rounds"] = [r[key] for r in rows]
    return row


def _by_round(rows: Sequence[dict[str, Any]], key: str, **match: Any) -> dict[int, float]:
    """``key`` of each round's row matching ``match``, by round."""
    return {r["round"]: r[key] for r in rows if all(r.get(k) == v for k, v in match.items())}


def _median_of_ratios(
    numerator: dict[int, float], denominator: dict[int, float]
) -> tuple[float, list[float]]:
    """Median (the lower middle one) of numerator / denominator of the same round, and
    each, in the rounds' order; NaN and none without a round in both."""
    each = [value / denominator[k] for k, value in numerator.items() if k in denominator]
    if not each:
        return math.nan, []
    ordered = sorted(each)
    return ordered[(len(ordered) - 1) // 2], each


def _paired_ratio(
    result: dict[str, Any], robot: str, law: str, loop: str = "lockstep"
) -> tuple[float, list[float]]:
    """Median over the rounds of ``loop`` (the rounds' key: ``lockstep``, or
    ``lockstep_as_used``) / ping-pong measured in the same round, and each."""
    rounds = result.get("rounds", {})
    return _median_of_ratios(
        _by_round(rounds.get(loop, []), "steps_per_s", robot=robot, law=law),
        _by_round(rounds.get("pingpong", []), "round_trips_per_s", robot=robot),
    )


def _engine_ratio(result: dict[str, Any], robot: str, law: str) -> tuple[float, list[float]]:
    """Median over the rounds of the loop on MuJoCo / the same loop on PyBullet measured
    right before it in the same round, and each."""
    rounds = result.get("rounds", {})
    return _median_of_ratios(
        *(
            _by_round(rounds.get(key, []), "steps_per_s", robot=robot, law=law)
            for key in ("lockstep_mujoco", "lockstep")
        )
    )


def physics_ratios(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per robot with both engines' rows: MuJoCo's physics step / PyBullet's (< 1: MuJoCo
    steps faster)."""
    out = []
    for robot in dict.fromkeys(r["robot"] for r in rows):
        bullet = _find(rows, robot=robot, engine="pybullet")
        mujoco = _find(rows, robot=robot, engine="mujoco")
        if bullet and mujoco:
            out.append(
                {
                    "robot": robot,
                    "mujoco_over_pybullet": mujoco["us_per_step"] / bullet["us_per_step"],
                }
            )
    return out


def ratios(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The lockstep loop against the plain ping-pong (the median of the ratios of each round),
    against the in-process ceiling, and on MuJoCo against PyBullet (the median of the ratios
    of each round)."""
    out = []
    for loop in result.get("lockstep", []):
        robot, law = loop["robot"], loop["law"]
        ceiling = _find(result.get("in_process", []), robot=robot, law=law)
        over_pingpong, each = _paired_ratio(result, robot, law)
        as_used, as_used_each = _paired_ratio(result, robot, law, "lockstep_as_used")
        engines, engines_each = _engine_ratio(result, robot, law)
        out.append(
            {
                "robot": robot,
                "law": law,
                "loop_over_pingpong": over_pingpong,
                "loop_over_pingpong_rounds": each,
                "as_used_over_pingpong": as_used,
                "as_used_over_pingpong_rounds": as_used_each,
                "loop_over_in_process": loop["steps_per_s"] / ceiling["steps_per_s"]
                if ceiling
                else math.nan,
                "mujoco_over_pybullet": engines,
                "mujoco_over_pybullet_rounds": engines_each,
            }
        )
    return out


def goals(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The issue's goals, each with the measured value and whether it is met (None when the
    section did not run)."""
    law = _find(result.get("compute", []), robot="iiwa", law="inverse_dynamics")
    loop = _find(result.get("lockstep", []), robot="iiwa", law="inverse_dynamics")
    ratio = _find(result.get("ratios", []), robot="iiwa", law="inverse_dynamics")
    rt = _find(result.get("realtime", []), load="quiet", thread_priority=50)
    hog = _find(result.get("realtime", []), load="hog", thread_priority=50)
    if hog is not None and hog["policy"] != "SCHED_FIFO":
        hog = None  # SCHED_FIFO refused: the goal is about a prioritised loop

    def goal(name: str, value: float | None, ok: Callable[[float], bool]) -> dict[str, Any]:
        met = None if value is None or math.isnan(value) else bool(ok(value))
        return {"goal": name, "measured": value, "met": met}

    from joint_space_control.lab.bench.dashboard import goals as dashboard_goals
    from joint_space_control.lab.bench.watched import goals as watched_goals

    return [
        goal(
            "inverse dynamics on iiwa <= 20 us median per tick",
            law["law_per_tick"]["p50_us"] if law else None,
            lambda v: v <= 20.0,
        ),
        goal(
            "lockstep over ROS 2, iiwa + inverse dynamics >= 2000 steps/s",
            loop["steps_per_s"] if loop else None,
            lambda v: v >= 2000.0,
        ),
        goal(
            "lockstep at least as fast as the plain rclpy ping-pong (ratio >= 1)",
            ratio["loop_over_pingpong"] if ratio else None,
            lambda v: v >= 1.0,
        ),
        goal(
            "lockstep as users run it (use_sim_time, a recorder), iiwa + inverse dynamics: "
            ">= 0.9 of the plain rclpy ping-pong",
            ratio.get("as_used_over_pingpong") if ratio else None,
            lambda v: v >= 0.9,
        ),
        goal(
            "realtime 1 kHz: >= 99 % of ticks on time (<= 200 us late)",
            rt["on_time_fraction"] if rt else None,
            lambda v: v >= 0.99,
        ),
        goal(
            "realtime 1 kHz: latency p99 <= 1 ms",
            rt["latency"]["p99_us"] if rt else None,
            lambda v: v <= 1000.0,
        ),
        goal(
            "realtime 1 kHz: no tick later than 5 ms",
            rt["lateness"]["max_us"] if rt else None,
            lambda v: v <= 5000.0,
        ),
        goal(
            "realtime 1 kHz under a CPU hog on every core, SCHED_FIFO: >= 99.8 % on time",
            hog["on_time_fraction"] if hog else None,
            lambda v: v >= 0.998,
        ),
        goal(
            "realtime 1 kHz under a CPU hog on every core, SCHED_FIFO: no brake",
            hog["brakes"] if hog else None,
            lambda v: v == 0,
        ),
        goal(
            "sweep of 1 s runs in process with their metrics, 1 worker: >= 300 runs/min",
            _sweep_rate(result.get("sweep"), "inprocess", 1),
            lambda v: v >= 300.0,
        ),
        goal(
            "simulate() of 1 s of the iiwa under inverse dynamics with its Response: <= 60 ms "
            "(the slower engine)",
            max((r["total_ms"] for r in result.get("simulate") or []), default=None),
            lambda v: v <= 60.0,
        ),
        *(goal(*row) for row in dashboard_goals(result.get("dashboard"))),
        *(goal(*row) for row in watched_goals(result.get("watched"))),
    ]


def _sweep_rate(sweep: dict[str, Any] | None, engine: str, workers: int) -> float | None:
    """Runs per minute of the sweep section's row for ``engine`` on ``workers`` workers."""
    rows = (sweep or {}).get("rows", [])
    row = next(
        (r for r in rows if r.get("engine") == engine and r.get("workers") == workers), None
    )
    return row["runs_per_minute"] if row else None


def _f(value: Any, digits: int = 0) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{value:,.{digits}f}"


def _pct(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return f"{100 * value:.2f}%"


def format_physics(physics: dict[str, Any]) -> list[str]:
    """The physics section's lines: a robot a line, both engines (the median round's mean
    step, and the median step of all rounds: the one a busy moment barely moves) and their
    ratio."""
    rows = physics["rows"]
    first = rows[0] if rows else {"steps": 0, "repeats": 0}
    lines = [
        "physics step in process [us] (sim_bridge's plant at 1 kHz, one step under gravity "
        f"compensation; the median of {first['repeats']} rounds' mean of "
        f"{first['steps']:,} steps)",
        "  robot        joints  pybullet    mujoco  mujoco/pybullet  p50 pybullet / mujoco",
    ]
    for robot in dict.fromkeys(r["robot"] for r in rows):
        bullet = _find(rows, robot=robot, engine="pybullet") or {}
        mujoco = _find(rows, robot=robot, engine="mujoco") or {}
        ratio = _find(physics.get("ratios", []), robot=robot) or {}
        joints = (bullet or mujoco)["joints"]
        lines.append(
            f"  {robot:12s} {joints:>6} {_f(bullet.get('us_per_step'), 1):>9}"
            f" {_f(mujoco.get('us_per_step'), 1):>9}"
            f" {_f(ratio.get('mujoco_over_pybullet'), 2):>16}"
            f" {_f(bullet.get('per_step', {}).get('p50_us'), 1):>12}"
            f" / {_f(mujoco.get('per_step', {}).get('p50_us'), 1)}"
        )
    lines += [f"  left out: {why}" for why in physics.get("skipped", [])]
    return [*lines, ""]


def format_engines(result: dict[str, Any]) -> list[str]:
    """The lockstep loop's lines on both of sim_bridge's engines."""
    lines = [
        "  sim_bridge engine:=mujoco against engine:=pybullet (the bench's loop above, the "
        "same controllers; sim step: sim_bridge's physics step and state published, p50):",
        "  robot        law                pybullet    mujoco  mujoco/pybullet  "
        "sim step p50 [us] pybullet / mujoco  rounds",
    ]
    for robot in ROBOTS:
        for law in LAWS:
            bullet = _find(result.get("lockstep", []), robot=robot, law=law) or {}
            mujoco = _find(result["lockstep_mujoco"], robot=robot, law=law) or {}
            ratio = _find(result.get("ratios", []), robot=robot, law=law) or {}
            lines.append(
                f"  {robot:12s} {law:18s} {_f(bullet.get('steps_per_s')):>8}"
                f" {_f(mujoco.get('steps_per_s')):>9}"
                f" {_f(ratio.get('mujoco_over_pybullet'), 2):>16}"
                f" {_f(bullet.get('sim_step_p50_us')):>22}"
                f" / {_f(mujoco.get('sim_step_p50_us')):<12}"
                + " ".join(_f(x, 2) for x in ratio.get("mujoco_over_pybullet_rounds", []))
            )
    return lines


def format_table(result: dict[str, Any]) -> str:
    """The human-readable summary of a result."""
    m, v = result["machine"], result["versions"]
    lines = [
        f"jsc bench  {result['started']}  ({result.get('duration_s', 0):.0f} s)",
        f"machine: {machine.describe(m)}",
        "versions: " + ", ".join(f"{k} {val}" for k, val in v.items()),
        "",
    ]
    if "compute" in result:
        lines += [
            "control law per tick [us]             law p50   law p99   pinocchio p50   p99",
        ]
        for row in result["compute"]:
            lines.append(
                f"  {row['robot']:12s} {row['law']:18s} {_f(row['law_per_tick']['p50_us'], 1):>9}"
                f" {_f(row['law_per_tick']['p99_us'], 1):>9}"
                f" {_f(row['pinocchio_per_tick']['p50_us'], 1):>15}"
                f" {_f(row['pinocchio_per_tick']['p99_us'], 1):>5}"
            )
        lines.append("")
    if result.get("simulate"):
        lines.append(
            "simulate() 1 s, iiwa, inverse dynamics   total [ms]  build  loop  response  runs/min"
        )
        for row in result["simulate"]:
            lines.append(
                f"  {row['engine']:36s} {_f(row['total_ms'], 1):>10} {_f(row['build_ms'], 1):>6}"
                f" {_f(row['loop_ms'], 1):>5} {_f(row['response_ms'], 1):>9}"
                f" {_f(row['runs_per_minute']):>9}"
            )
        lines.append("")
    if "physics" in result:
        lines += format_physics(result["physics"])
    if "lockstep" in result or "in_process" in result or "pingpong" in result:
        lines.append(
            "lockstep [steps/s]                 over ROS  in-process  ping-pong  "
            "loop/pp  loop/in-proc  callback p50/p99 [us]  latency p50/p99 [us]"
        )
        for robot in ROBOTS:
            pp = _find(result.get("pingpong", []), robot=robot)
            for law in LAWS:
                loop = _find(result.get("lockstep", []), robot=robot, law=law) or {}
                ceiling = _find(result.get("in_process", []), robot=robot, law=law) or {}
                ratio = _find(result.get("ratios", []), robot=robot, law=law) or {}
                cb, lat = loop.get("callback", {}), loop.get("latency", {})
                lines.append(
                    f"  {robot:12s} {law:18s} {_f(loop.get('steps_per_s')):>9}"
                    f" {_f(ceiling.get('steps_per_s')):>11}"
                    f" {_f(pp['round_trips_per_s'] if pp else None):>10}"
                    f" {_f(ratio.get('loop_over_pingpong'), 2):>8}"
                    f" {_f(ratio.get('loop_over_in_process'), 2):>13}"
                    f" {_f(cb.get('p50_us')):>12} / {_f(cb.get('p99_us')):<8}"
                    f" {_f(lat.get('p50_us')):>10} / {_f(lat.get('p99_us'))}"
                )
        rounds = max(
            (len(r.get("loop_over_pingpong_rounds", [])) for r in result["ratios"]), default=0
        )
        if rounds > 1:
            lines.append(
                f"  (medians of {rounds} alternating rounds; loop/pp is the median of the ratios "
                "of each round: "
                + "; ".join(
                    f"{r['robot']} {r['law']} "
                    + " ".join(_f(x, 2) for x in r["loop_over_pingpong_rounds"])
                    for r in result["ratios"]
                )
                + ")"
            )
        if result.get("lockstep_as_used"):
            lines += [
                "  as users run it (the controller and a recorder with use_sim_time, the "
                "recorder matched with /clock, joint_states and effort_command):",
                "  robot        law                 steps/s  as-used/pp  as-used/loop  rounds/pp",
            ]
            for robot in ROBOTS:
                for law in LAWS:
                    used = _find(result["lockstep_as_used"], robot=robot, law=law) or {}
                    loop = _find(result.get("lockstep", []), robot=robot, law=law) or {}
                    ratio = _find(result.get("ratios", []), robot=robot, law=law) or {}
                    over_loop = (
                        used["steps_per_s"] / loop["steps_per_s"] if used and loop else math.nan
                    )
                    lines.append(
                        f"  {robot:12s} {law:18s} {_f(used.get('steps_per_s')):>8}"
                        f" {_f(ratio.get('as_used_over_pingpong'), 2):>11}"
                        f" {_f(over_loop, 2):>13}  "
                        + " ".join(_f(x, 2) for x in ratio.get("as_used_over_pingpong_rounds", []))
                    )
        if result.get("lockstep_mujoco"):
            lines += format_engines(result)
        lines += [f"  {key} left out: {why}" for key, why in result.get("skipped", {}).items()]
        lines.append("")
    if result.get("realtime"):
        rows = result["realtime"]
        first = rows[0]
        fifo = result.get("fifo_permitted")
        lines += [
            f"realtime 1 kHz, {first['robot']} {first['law']}, {first['seconds']:.1f} s per run "
            "(plant and controller at thread_priority; floor: a bare Python thread paced the "
            "same way, no ROS)",
            "  SCHED_FIFO "
            + (
                "permitted: the priority-50 rows ran at FIFO"
                if fifo
                else "REFUSED here: the "
                "priority-50 rows ran at normal scheduling (docs/performance.md, Thread priority)"
            ),
            "  load   prio policy       on time  >1 ms   lateness p99/max [us]  "
            "latency p99/max [us]  brakes  poll | floor: on time  >1 ms  lateness p99/max",
        ]
        for row in rows:
            floor = _find(
                result.get(FLOOR, []), load=row["load"], thread_priority=row["thread_priority"]
            ) or {"lateness": {}}
            lines.append(
                f"  {row['load']:6s} {row['thread_priority']:>4} {row['policy'] or '-':11s}"
                f" {_pct(row['on_time_fraction']):>8} {_pct(row['too_late_fraction']):>6}"
                f" {_f(row['lateness']['p99_us']):>10} / {_f(row['lateness']['max_us']):<8}"
                f" {_f(row['latency']['p99_us']):>9} / {_f(row['latency']['max_us']):<8}"
                f" {row['brakes']:>6} {_pct(row.get('poll_fraction')):>5}"
                f" | {_pct(floor.get('on_time_fraction')):>15}"
                f" {_pct(floor.get('too_late_fraction')):>6}"
                f" {_f(floor['lateness'].get('p99_us')):>9}"
                f" / {_f(floor['lateness'].get('max_us'))}"
            )
        lines.append("")
    an = result.get("analyze")
    if an:
        lines += [
            f"jsc analyze: {an['messages']:,} messages in {an['seconds']:.2f} s = "
            f"{an['seconds_per_million_messages']:.1f} s per million messages",
            "",
        ]
    if "sweep" in result:
        from joint_space_control.lab.bench.sweep import format_sweep

        lines += format_sweep(result["sweep"])
    if "dashboard" in result:
        from joint_space_control.lab.bench.dashboard import format_dashboard

        lines += format_dashboard(result["dashboard"])
    if "watched" in result:
        from joint_space_control.lab.bench.watched import format_watched

        lines += format_watched(result["watched"])
    steal = {k: v for k, v in result.get("cpu_steal_fraction", {}).items() if v is not None}
    if steal:
        lines += [
            "CPU time taken by the hypervisor (steal): "
            + ", ".join(f"{k} {100 * v:.1f} %" for k, v in steal.items()),
            "",
        ]
    lines.append("goals:")
    for g in result.get("goals", []):
        mark = {True: "met", False: "NOT met", None: "not measured"}[g["met"]]
        lines.append(f"  [{mark:>12}] {g['goal']}: {_f(g['measured'], 3)}")
    return "\n".join(lines)
