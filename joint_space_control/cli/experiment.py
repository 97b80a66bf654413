"""``jsc experiment``: run named scenarios end to end and report against the theory."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

from joint_space_control.experiments.scenarios import format as scenarios
from joint_space_control.experiments.scenarios.params_file import with_params_file


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
        help="where the runs execute: a Dask LocalCluster of --jobs workers (default), an "
        "existing Dask scheduler tcp://HOST:PORT (--out must then be a directory every "
        "worker reaches at the same path), or 'threads' (threads of this process, no Dask)",
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
) -> int:
    """Run the scenarios, all on one pool (:class:`RunPool`: ``scheduler`` None, a
    LocalCluster of ``jobs`` workers; an address; or ``"threads"``). Ctrl-C cancels the
    whole sweep (no node or worker process is left) and exits with 130."""
    # deferred: the library (ROS, Pinocchio, Dask) loads only for this command, not for
    # `jsc --help`
    from joint_space_control.experiments.execution.distributed import RunPool
    from joint_space_control.experiments.experiment import ExperimentResult, run_experiment
    from joint_space_control.experiments.presentation.results import results_page

    def error(message: str) -> int:
        print(f"jsc experiment: error: {message}", file=sys.stderr)
        return 2

    if run_all:
        names = list(scenarios.available())
    if not names:
        return error("name a scenario, or use --all / --list")
    if jobs < 1:
        return error(f"--jobs must be >= 1, got {jobs}")
    try:
        loaded = [scenarios.load(n) for n in names]
        if params_file is not None:
            loaded = [with_params_file(s, params_file) for s in loaded]
    except ValueError as err:
        return error(str(err))
    out = out.absolute()  # the path the workers are given

    def log(message: str) -> None:
        print(message, flush=True)

    try:
        pool = RunPool(jobs, scheduler, log)
    except ValueError as err:
        return error(str(err))
    except KeyboardInterrupt:
        print("\njsc experiment: interrupted", file=sys.stderr)
        return 130
    results: list[ExperimentResult] = []
    started = time.monotonic()
    try:
        print(f"runs on: {pool.description}, engine {engine}", flush=True)
        out.mkdir(parents=True, exist_ok=True)
        if missing := pool.missing(out):
            return error(
                f"--out {out} is not a directory on the workers {', '.join(missing)}: give "
                "one on a file system every worker mounts at the same path"
            )
        for k, scenario in enumerate(loaded):
            print(f"{_bar(k, len(loaded))} {scenario.name}: {scenario.title}", flush=True)
            result = run_experiment(scenario, out, short, pool, log, engine)
            results.append(result)
            verdict = {True: "agrees with the theory", False: "FAILED", None: "ran"}[result.passed]
            print(f"  -> {verdict}: {result.out / 'summary.md'}", flush=True)
            for o in result.outcomes:
                print(
                    f"     {'ok ' if o.passed else '?? ' if o.passed is None else 'NO '}{o.text}"
                )
            for e in result.errors:
                print(f"     run failed: {e}")
    except KeyboardInterrupt:
        # a second Ctrl-C must not cut the stopping short (nodes and workers would be left)
        previous = _ignore_sigint()
        print("\njsc experiment: interrupted, stopping the runs", file=sys.stderr, flush=True)
        try:
            pool.cancel()
            pool.close()
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        return 130
    finally:
        pool.close()
    print(f"{_bar(len(loaded), len(loaded))} done in {time.monotonic() - started:.0f} s")
    if report is not None:
        page = results_page(results, report, short)
        print(f"results page: {page}")
    if short:  # cut runs cannot be judged against the theory: only broken runs fail
        failed = [r.scenario.name for r in results if r.errors]
    else:
        failed = [r.scenario.name for r in results if r.passed is False]
    if failed:
        print(f"jsc experiment: {len(failed)} failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


def _ignore_sigint():
    """Ignore SIGINT from now on (main thread only); the handler it replaced, or None."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGINT, signal.SIG_IGN)
