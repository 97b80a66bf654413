"""``jsc bench`` section ``sweep``: how many runs a minute a sweep gets through on a Dask
LocalCluster of 1 and then 2 workers, and where a run's wall time goes.

One fixed sweep (short lockstep step responses of the planar arm under inverse dynamics,
one run per ω_n) runs twice in one invocation, on a fresh LocalCluster each time, so the
two rates are measured minutes apart at most on the same machine. Per run, the runner
times its phases (:attr:`RunResult.timings`): ``start`` (the node processes started,
imported and connected), ``run`` (the simulated time, lockstep), ``stop`` (the recorder's
tail taken, the nodes stopped) and ``analysis`` (bag → report and figures); what remains of
a worker's time per run (``other``) is the task's own cost (dispatch, a worker's first
imports, results sent back). The CPU time of the sweep's processes (workers and nodes) per
run gives the rate the machine's cores allow at most (``cpu_bound_runs_per_minute``), and
how busy the machine was (all its processes) says how much of them the sweep had.
"""

from __future__ import annotations

import math
import os
import resource
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from joint_space_control import machine
from joint_space_control.workbench.experiments.execution.distributed import RunPool
from joint_space_control.workbench.experiments.execution.runner import run_scenario
from joint_space_control.workbench.experiments.scenarios.format import Scenario, parse

#: The phases of a run, in order (runner.run_once).
PHASES = ("start", "run", "stop", "analysis")
#: Runs of the in-process sweep per run of the ROS one: its runs take a tenth of a second,
#: so that a worker's first imports and the last run's figures weigh as in a real sweep.
INPROCESS_RUNS = 5
#: The swept natural frequencies [rad/s] (as many as the sweep has runs, cycled).
OMEGAS = (6.0, 8.0, 10.0, 12.0, 14.0, 16.0)


def sweep_scenario(runs: int, duration: float) -> Scenario:
    """The benchmark's sweep: ``runs`` step responses of ``duration`` simulated seconds."""
    data = {
        "title": "jsc bench sweep",
        "question": 0,
        "robot": "planar_2dof",
        "duration": duration,
        "short_duration": duration,
        "plant": {"initial_positions": [-1.0, 0.5]},
        "controller": "inverse_dynamics_controller",
        "parameters": {"law": "inverse_dynamics", "zeta": 1.0},
        "reference": {"shape": "step", "target": [-0.9, 0.35]},
        "variants": {
            "name": "omega_n",
            "runs": [
                {"label": f"run{k}", "set": {"parameters.omega_n": OMEGAS[k % len(OMEGAS)]}}
                for k in range(runs)
            ],
        },
    }
    return parse(data, "bench_sweep", Path("bench_sweep.yaml"))


def _cpu_seconds() -> float:
    """CPU time [s] of this process and of its reaped descendants (the cluster's workers,
    once closed, and the node processes they waited for)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def throughput(
    out: Path,
    runs: int,
    duration: float,
    workers: Sequence[int] = (1, 2),
    log: Callable[[str], None] = print,
    engines: Sequence[str] = ("ros",),
) -> dict[str, Any]:
    """The sweep on each engine (``ros``: the nodes as processes; ``inprocess``: the same
    objects in the worker) on a LocalCluster of each of ``workers`` workers in turn: one
    row each (runs per minute, the phases of a run, CPU use), the rate of the last over the
    first per engine (``speedups``; ``speedup``: the first engine's), and with both engines
    the in-process rate over the ROS one on the same workers (``inprocess_over_ros``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    cores = cores or 1
    rows = []
    asked = runs
    for engine, n in [(e, n) for e in engines for n in workers]:
        runs = asked * (INPROCESS_RUNS if engine == "inprocess" else 1)
        scenario = sweep_scenario(runs, duration)
        target = out / f"{engine}_workers_{n}"
        shutil.rmtree(target, ignore_errors=True)
        log(f"sweep: {runs} runs of {duration:g} s, {engine} engine, {n} worker(s)")
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
        cpu0, meter, opened = _cpu_seconds(), machine.CpuMeter(), time.monotonic()
        with RunPool(n, None, log) as pool:
            started = time.monotonic()
            results = run_scenario(scenario, target, pool=pool, log=lambda _: None, engine=engine)
            elapsed = time.monotonic() - started
        total = time.monotonic() - opened
        cpu = _cpu_seconds() - cpu0
        ok = [r for r in results if r.error is None]
        phases = {p: _mean([r.timings.get(p, math.nan) for r in ok]) for p in PHASES}
        lane = elapsed * n / runs  # a worker's wall time per run
        rows.append(
            {
                "engine": engine,
                "workers": n,
                "runs": runs,
                "failed": runs - len(ok),
                "simulated_s": duration,
                "seconds": elapsed,
                "runs_per_minute": 60.0 * runs / elapsed,
                "cluster_start_and_close_s": total - elapsed,
                "worker_seconds_per_run": lane,
                "phases_s": phases,
                "other_s": lane - sum(phases.values()),
                "cpu_seconds": cpu,
                "cpu_seconds_per_run": cpu / runs,
                # the rate if the machine's cores did nothing else: what CPU alone allows
                "cpu_bound_runs_per_minute": 60.0 * cores * runs / cpu if cpu > 0 else math.nan,
                "cpu_cores_used": cpu / total,
                "machine_busy_fraction": meter.busy(),
                "load_average_1min_before": load,
            }
        )
    rate = {(r["engine"], r["workers"]): r["runs_per_minute"] for r in rows}
    speedups = {e: rate[(e, workers[-1])] / rate[(e, workers[0])] for e in engines}
    result = {
        "robot": "planar_2dof",
        "law": "inverse_dynamics",
        "cores": cores,
        "rows": rows,
        "speedups": speedups,
        "speedup": speedups[engines[0]],
    }
    if {"ros", "inprocess"} <= set(engines):
        result["inprocess_over_ros"] = {
            n: rate[("inprocess", n)] / rate[("ros", n)] for n in workers
        }
    return result


def _mean(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return sum(finite) / len(finite) if finite else math.nan


def format_sweep(sweep: dict[str, Any]) -> list[str]:
    """The section's lines of the bench table."""
    if "skipped" in sweep:
        return [f"sweep: skipped ({sweep['skipped']})", ""]
    rows = sweep["rows"]
    first = rows[0]
    lines = [
        f"sweep on a Dask LocalCluster: runs of {first['simulated_s']:g} s simulated, "
        f"{sweep['robot']} {sweep['law']}, lockstep ({sweep['cores']} cores)",
        "     engine  workers  runs  runs/min  worker s/run   start    run   stop  analysis  "
        "other  CPU s/run  CPU cores used  machine busy  failed",
    ]
    for row in rows:
        p = row["phases_s"]
        busy = row["machine_busy_fraction"]
        lines.append(
            f"  {row.get('engine', 'ros'):>9}  {row['workers']:>7}  {row['runs']:>4}"
            f"  {row['runs_per_minute']:>8.1f}"
            f"  {row['worker_seconds_per_run']:>12.1f}"
            f"  {p['start']:>6.1f} {p['run']:>6.1f} {p['stop']:>6.1f} {p['analysis']:>9.1f}"
            f"  {row['other_s']:>5.1f}  {row['cpu_seconds_per_run']:>9.1f}"
            f"  {row['cpu_cores_used']:>14.2f}"
            f"  {'-' if busy is None else f'{100 * busy:.0f} %':>12}  {row['failed']:>6}"
        )
    lines.append(
        f"  {rows[-1]['workers']} workers / {first['workers']}: "
        f"{sweep['speedup']:.2f}x the runs per minute; the CPU time per run allows at most "
        f"{rows[-1]['cpu_bound_runs_per_minute']:.1f} runs/min on {sweep['cores']} idle cores"
    )
    for n, ratio in sweep.get("inprocess_over_ros", {}).items():
        lines.append(f"  in process / over ROS, {n} worker(s): {ratio:.1f}x the runs per minute")
    lines.append("")
    return lines
