"""``jsc experiment``: run named scenarios end to end and report against the theory."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from joint_space_control.cli.interrupt import cancel_pool
from joint_space_control.workbench.experiments.scenarios import format as scenarios
from joint_space_control.workbench.experiments.scenarios.params_file import with_params_file
from sim_bridge.engines import ENGINES


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc experiment``."""
    p = subparsers.add_parser(
        "experiment",
        help="run scenarios of THEORY.md §5 end to end (nodes, bag, analysis, theory checks)",
    )
    p.add_argument("names", nargs="*", help="scenario names or YAML files")
    p.add_argument("--list", action="store_true", help="list the installed scenarios")
    p.add_argument("--all", action="store_true", help="run every installed scenario")
    p.add_argument("--out", type=Path, default=Path("out/experiments"), help="output dir")
    p.add_argument(
        "--short", action="store_true", help="CI form: short durations, first and last variant"
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=2,
        help="runs at a time: the LocalCluster's workers, or the threads (default 2; "
        "ignored with a scheduler address, whose cluster has its own workers)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS|threads",
        help="where the runs execute: a Dask LocalCluster of --jobs workers (the default "
        "with --engine ros), an existing Dask scheduler tcp://HOST:PORT (--out must then be "
        "a directory every worker reaches at the same path), or 'threads' (threads of this "
        "process, no Dask: the default with --engine inprocess, whose runs take less time "
        "than a cluster takes to start)",
    )
    p.add_argument(
        "--engine",
        choices=("ros", "inprocess"),
        default="ros",
        help="ros (default): the nodes as processes over ROS 2, as users run them; "
        "inprocess: the same plant and controller objects in the worker's process, no ROS "
        "graph (lockstep only; the same metrics and check texts, much faster)",
    )
    p.add_argument(
        "--record",
        action="store_true",
        help="with --engine inprocess, also write each run's bag (RUN/bag/, as the recorder "
        "records the nodes); runs on ROS are always recorded",
    )
    p.add_argument(
        "--plant-engine",
        default="pybullet",
        metavar="ENGINE[,ENGINE]",
        help="the plant's physics engine: pybullet (default) or mujoco, or both, comma "
        "separated: every scenario on each (outputs in OUT/<engine>/, and the results page "
        "gets a table of each check's figures engine by engine)",
    )
    p.add_argument(
        "--report", type=Path, default=None, help="also write DIR/results.md (e.g. docs/)"
    )
    p.add_argument(
        "--params-file",
        type=Path,
        default=None,
        help="ROS parameter file whose entry for the scenario's controller overrides the "
        "scenario's parameters (e.g. the best_params.yaml of jsc tune)",
    )
    p.set_defaults(handler=_handle)


def _handle(args: argparse.Namespace) -> int:
    if args.list:
        return list_scenarios()
    return run(
        args.names,
        args.all,
        args.out,
        args.short,
        args.jobs,
        args.report,
        args.scheduler,
        args.params_file,
        args.engine,
        args.plant_engine,
        args.record,
    )


def list_scenarios() -> int:
    for name, path in scenarios.available().items():
        try:
            s = scenarios.load(str(path))
            runs = s.variants.describe() if s.variants else "1 run"
            print(f"{name:32s} Q{s.question}  {s.robot:12s} {runs:18s} {s.title}")
        except ValueError as err:
            print(f"{name:32s} INVALID: {err}")
    return 0


def _bar(done: int, total: int, width: int = 24) -> str:
    filled = round(width * done / max(total, 1))
    return f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


def run(
    names: list[str],
    run_all: bool,
    out: Path,
    short: bool,
    jobs: int,
    report: Path | None,
    scheduler: str | None = None,
    params_file: Path | None = None,
    engine: str = "ros",
    plant_engine: str = "pybullet",
    record: bool = False,
) -> int:
    """Run the scenarios, all on one pool (:class:`RunPool`: ``scheduler`` None, a
    LocalCluster of ``jobs`` workers; an address; or ``"threads"``). Ctrl-C cancels the
    whole sweep (no node or worker process is left) and exits with 130."""
    # deferred: the library (ROS, Pinocchio, Dask) loads only for this command, not for
    # `jsc --help`
    from joint_space_control.workbench.experiments.execution.distributed import RunPool
    from joint_space_control.workbench.experiments.experiment import (
        ExperimentResult,
        run_experiment,
    )
    from joint_space_control.workbench.experiments.presentation.results import results_page

    def error(message: str) -> int:
        print(f"jsc experiment: error: {message}", file=sys.stderr)
        return 2

    if jobs < 1:
        return error(f"--jobs must be >= 1, got {jobs}")
    try:
        loaded = _scenarios(list(scenarios.available()) if run_all else names, params_file)
        plant_engines = _plant_engines(plant_engine)
    except ValueError as err:
        return error(str(err))
    out = out.absolute()  # the path the workers are given

    def log(message: str) -> None:
        print(message, flush=True)

    if scheduler is None and engine == "inprocess":
        scheduler = "threads"  # runs of a second or less: no cluster to start for them
    try:
        pool = RunPool(jobs, scheduler, log)
    except ValueError as err:
        return error(str(err))
    except KeyboardInterrupt:
        print("\njsc experiment: interrupted", file=sys.stderr)
        return 130
    by_engine: dict[str, list[ExperimentResult]] = {e: [] for e in plant_engines}
    # one engine: as always; several: each scenario on each, in OUT/<engine>/
    runs = [
        (e, scenario.on_engine(e), out / e if len(plant_engines) > 1 else out)
        for scenario in loaded
        for e in plant_engines
    ]
    started = time.monotonic()
    try:
        print(
            f"runs on: {pool.description}, engine {engine}, plant {', '.join(plant_engines)}",
            flush=True,
        )
        out.mkdir(parents=True, exist_ok=True)
        if missing := pool.missing(out):
            return error(
                f"--out {out} is not a directory on the workers {', '.join(missing)}: give "
                "one on a file system every worker mounts at the same path"
            )
        for k, (plant, scenario, where) in enumerate(runs):
            on = f" [{plant}]" if len(plant_engines) > 1 else ""
            print(f"{_bar(k, len(runs))} {scenario.name}{on}: {scenario.title}", flush=True)
            result = run_experiment(scenario, where, short, pool, log, engine, record)
            by_engine[plant].append(result)
            _print_result(result)
    except KeyboardInterrupt:
        return cancel_pool(pool, "\njsc experiment: interrupted, stopping the runs")
    finally:
        pool.close()
    print(f"{_bar(len(runs), len(runs))} done in {time.monotonic() - started:.0f} s")
    if report is not None:
        engines = by_engine if len(plant_engines) > 1 else None
        page = results_page(by_engine[plant_engines[0]], report, short, engines)
        print(f"results page: {page}")
    return _verdict(by_engine, short)


def _scenarios(names: list[str], params_file: Path | None) -> list[Any]:
    """The scenarios by name or file, with the parameter file's entries over them
    (ValueError naming what is wrong)."""
    if not names:
        raise ValueError("name a scenario, or use --all / --list")
    loaded = [scenarios.load(n) for n in names]
    if params_file is not None:
        loaded = [with_params_file(s, params_file) for s in loaded]
    return loaded


def _plant_engines(given: str) -> list[str]:
    """``--plant-engine``: engines of sim_bridge, comma separated, each once."""
    engines = [e.strip() for e in given.split(",") if e.strip()]
    unknown = [e for e in engines if e not in ENGINES]
    if unknown or not engines or len(set(engines)) != len(engines):
        raise ValueError(
            f"--plant-engine must name engines of {', '.join(ENGINES)}, each once; got {given!r}"
        )
    return engines


def _print_result(result: Any) -> None:
    verdict = {True: "agrees with the theory", False: "FAILED", None: "ran"}[result.passed]
    print(f"  -> {verdict}: {result.out / 'summary.md'}", flush=True)
    for o in result.outcomes:
        print(f"     {'ok ' if o.passed else '?? ' if o.passed is None else 'NO '}{o.text}")
    for e in result.errors:
        print(f"     run failed: {e}")


def _verdict(by_engine: dict[str, list[Any]], short: bool) -> int:
    """0, or 1 naming the experiments that failed (of a short run: only broken runs, cut
    runs cannot be judged against the theory)."""
    every = [(e, r) for e, rs in by_engine.items() for r in rs]
    named = (
        (lambda e, r: f"{r.scenario.name} [{e}]")
        if len(by_engine) > 1
        else (lambda e, r: r.scenario.name)
    )
    if short:
        failed = [named(e, r) for e, r in every if r.errors]
    else:
        failed = [named(e, r) for e, r in every if r.passed is False]
    if failed:
        print(f"jsc experiment: {len(failed)} failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0
