"""``jsc tune``: gains that meet a step-response specification, found by an Optuna study
whose trials are lockstep runs on a pool of workers (wiring only: workbench/tuning/)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from joint_space_control.analysis.spec import allowed
from joint_space_control.cli.interrupt import cancel_pool
from joint_space_control.workbench.tuning.problem import (
    CONTROLLERS,
    DEFAULT_DURATION,
    DEFAULT_STEP,
)
from joint_space_control.workbench.tuning.space import (
    GAINS,
    OMEGA_N_RANGE,
    ZETA_RANGE,
    parse_range,
)
from joint_space_control.workbench.tuning.study import BATCH

PROG = "jsc tune"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc tune``."""
    p = subparsers.add_parser(
        "tune",
        help="find gains meeting a step-response spec (Optuna TPE over lockstep runs)",
        description=(
            "Tune a controller's gains on a robot until its step response meets a "
            "specification. Each trial is a lockstep run: the robot starts at q0 (0 inside "
            "the limits) and steps by --step on every joint; its metrics (jsc analyze) are "
            "judged against --spec, each clause over the worst joint. Writes best_params.yaml "
            "(a --params-file for the controller), scenario.yaml (jsc experiment confirms it), "
            "report.md, history.png and best_step.png into --out; the study is stored in "
            "--out/study.db and the same command resumes it. Exit 0 when a trial meets the "
            "spec, 1 when none does, 2 on bad input, 130 when interrupted."
        ),
    )
    p.error = _error  # one line, exit 2, as the other errors of this command
    _problem_arguments(p)
    _search_arguments(p)
    _where_arguments(p)
    p.set_defaults(handler=_handle)


def _problem_arguments(p: argparse.ArgumentParser) -> None:
    """The trial: the robot, the controller and its law, the specification, the step."""
    p.add_argument("robot", help="built-in robot (planar_2dof, iiwa, panda) or a .urdf/.xacro")
    p.add_argument(
        "--controller", required=True, choices=sorted(CONTROLLERS), help="controller to tune"
    )
    p.add_argument(
        "--law",
        default=None,
        help="inverse_dynamics: law (inverse_dynamics | feedforward_pd | "
        "precomputed_feedforward); pd_gravity: gravity_compensation (full | none | desired); "
        "default: the node's",
    )
    p.add_argument(
        "--spec",
        required=True,
        help="comma-separated 'metric<=value' / 'metric>=value', metrics: "
        + allowed().replace("%", "%%")
        + "; "
        "e.g. 'overshoot<=5, settling_2pct<=0.8, peak_torque_ratio<=0.8'",
    )
    p.add_argument(
        "--step", type=float, default=DEFAULT_STEP, help=f"step per joint [rad] ({DEFAULT_STEP})"
    )
    p.add_argument(
        "--duration",
        type=float,
        default=DEFAULT_DURATION,
        help=f"simulated time per trial [s] ({DEFAULT_DURATION})",
    )
    p.add_argument(
        "--q0",
        default=None,
        help="start, comma-separated per joint [rad] (default: 0, moved 10 %% of a joint's "
        "range inside its limits)",
    )
    p.add_argument(
        "--package-path",
        action="append",
        default=[],
        help="folder for package:// URIs of the description (repeatable)",
    )
    p.add_argument("--xacro-args", default="", help="'name:=value ...' for a .xacro file")


def _search_arguments(p: argparse.ArgumentParser) -> None:
    """The study: how many trials, the sampler and its space, the first design."""
    p.add_argument("--trials", type=int, default=30, help="finished trials in all (default 30)")
    p.add_argument(
        "--batch",
        type=int,
        default=BATCH,
        help=f"trials asked, run and told together (default {BATCH}): a seeded study "
        "depends on it, not on --jobs or the order runs finish in; workers beyond it idle",
    )
    p.add_argument("--seed", type=int, default=0, help="sampler seed (0)")
    p.add_argument("--study", default=None, help="study name (<robot>_<controller>)")
    p.add_argument(
        "--gains",
        choices=GAINS,
        default="omega_zeta",
        help="search per-joint ω_n, ζ (default; the nodes' omega_n/zeta) or kp, kd directly "
        "(K_P in b·[ω_lo², ω_hi²], K_D in b·[2ζ_lo ω_lo, 2ζ_hi ω_hi], b the inertia each "
        "joint sees along the step, B̂_ii(q0) + |Σ_j≠i B̂_ij Δq_j / Δq_i|, for pd_gravity, 1 "
        "for inverse_dynamics)",
    )
    p.add_argument(
        "--omega-n",
        default=f"{OMEGA_N_RANGE[0]:g}:{OMEGA_N_RANGE[1]:g}",
        help="ω_n range LO:HI [rad/s], log-uniform (default %(default)s)",
    )
    p.add_argument(
        "--zeta",
        default=f"{ZETA_RANGE[0]:g}:{ZETA_RANGE[1]:g}",
        help="ζ range LO:HI, uniform (default %(default)s)",
    )
    p.add_argument(
        "--no-design",
        action="store_true",
        help="start a new study from TPE's random trials, not from the second-order "
        "theory's design for the spec (the default first trial)",
    )


def _where_arguments(p: argparse.ArgumentParser) -> None:
    """Where the trials run and where the results go."""
    p.add_argument("--jobs", type=int, default=2, help="workers of the local pool (default 2)")
    p.add_argument(
        "--engine",
        choices=("inprocess", "ros"),
        default="inprocess",
        help="where the trials run: inprocess (default; the plant and controller objects in "
        "the worker, no ROS graph, the same numbers; the best trial is then confirmed on the "
        "nodes before the parameter file is written) or ros (the nodes as processes)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        help="a Dask scheduler tcp://HOST:PORT, or 'threads' (default: threads with "
        "--engine inprocess, a local cluster with --engine ros)",
    )
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (out/tune/<robot>_<controller>)"
    )


def _error(message: str) -> None:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    sys.exit(2)


def _handle(args: argparse.Namespace) -> int:
    from joint_space_control.workbench.tuning.session import TuneOptions

    try:
        options = TuneOptions(
            robot=args.robot,
            controller=args.controller,
            spec=args.spec,
            law=args.law,
            trials=args.trials,
            jobs=args.jobs,
            batch=args.batch,
            engine=args.engine,
            scheduler=args.scheduler,
            out=args.out,
            step=args.step,
            duration=args.duration,
            seed=args.seed,
            study=args.study,
            gains=args.gains,
            omega_n=parse_range(args.omega_n, "--omega-n"),
            zeta=parse_range(args.zeta, "--zeta", positive=False),
            package_paths=tuple(args.package_path),
            xacro_args=args.xacro_args,
            q0=None if args.q0 is None else _numbers(args.q0, "--q0"),
            design=not args.no_design,
        )
    except ValueError as err:
        return _fail(err)
    return run(options)


def _numbers(text: str, what: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.replace(" ", "").split(","))
    except ValueError:
        raise ValueError(f"{what} must be numbers separated by commas, got {text!r}") from None


def _fail(err: BaseException) -> int:
    print(f"{PROG}: error: {str(err).splitlines()[0]}", file=sys.stderr)
    return 2


def run(
    options: Any,
    pool_class: Callable[..., Any] | None = None,
    task: Callable[..., Any] | None = None,
    log: Callable[[str], None] = lambda m: print(m, flush=True),
    confirm: Callable[..., Any] | None = None,
) -> int:
    """The session: prepare, run the study on the pool, write the outputs; the exit code.
    ``pool_class``/``task`` replace RunPool/execute_run (tests), ``confirm`` the ROS run of
    the best trial (``confirm(scenario, target)``; default: ``task`` on the ROS engine).
    Ctrl-C fails the trials in flight, cancels the pool (their nodes stopped) and exits
    130."""
    from joint_space_control.workbench.tuning.session import confirm_best, prepare, write_outputs
    from joint_space_control.workbench.tuning.session import run as run_study
    from joint_space_control.workbench.tuning.study import SettingsMismatchError

    try:
        prepared = prepare(options)
    except ValueError as err:  # spec, options, robot description
        return _fail(err)
    for warning in prepared.warnings:
        log(f"warning: {warning}")
    pool_class, task, confirm = _runners(options.engine, pool_class, task, confirm)
    started = time.monotonic()
    problem = prepared.problem
    log(
        f"tuning {problem.controller} on {problem.robot}: {problem.spec}; "
        f"{prepared.space.describe()}; {options.trials} trials -> {prepared.out}"
    )
    scheduler = options.scheduler
    if scheduler is None and options.engine == "inprocess":
        scheduler = "threads"  # trials of a fraction of a second: no cluster to start
    try:
        pool = pool_class(options.jobs, scheduler, log)
    except ValueError as err:  # a bad scheduler address, say
        return _fail(err)
    except KeyboardInterrupt:
        print(f"\n{PROG}: interrupted", file=sys.stderr)
        return 130
    try:
        log(f"runs on {pool.description}")
        if missing := pool.missing(prepared.out):
            return _fail(
                ValueError(
                    f"--out {prepared.out} is not a directory on the workers "
                    f"{', '.join(missing)}: give one every worker mounts at the same path"
                )
            )

        def submit(label: str, scenario: Any, target: Path):
            return pool.submit(label, task, scenario, target, False)

        study = run_study(prepared, submit, pool.workers, log)
        description = pool.description
    except SettingsMismatchError as err:
        return _fail(err)
    except KeyboardInterrupt:
        return cancel_pool(
            pool,
            f"\n{PROG}: interrupted; the trials in flight are marked failed, stopping the "
            "runs. The same command resumes the study.",
        )
    finally:
        pool.close()
    confirmation = None
    if options.engine == "inprocess":
        log("confirming the best trial on the ROS engine (the nodes as processes)")
        try:
            confirmation = confirm_best(prepared, study, confirm)
        except KeyboardInterrupt:
            print(f"\n{PROG}: interrupted", file=sys.stderr)
            return 130
        if confirmation is not None:
            log(("" if confirmation.same else "warning: ") + confirmation.text)
    summary = write_outputs(prepared, study, description, time.monotonic() - started, confirmation)
    return _report(summary, problem.spec, prepared.out, log)


def _report(summary: Any, spec: Any, out: Path, log: Callable[[str], None]) -> int:
    """Say which trial is best and where the files are; the exit code (0: the spec met)."""
    best = summary.best
    if best is None:
        log(f"{PROG}: no trial completed; see {out / 'report.md'}")
        return 1
    if summary.met:
        log(
            f"best: trial {best.number} meets {spec}: ω_n = "
            + ", ".join(f"{w:.4g}" for w in best.omega_n)
            + " rad/s, ζ = "
            + ", ".join(f"{z:.3g}" for z in best.zeta)
        )
    else:
        log(f"{PROG}: no trial met {spec}; closest: {summary.closest}")
    for path in summary.files:
        log(f"  {path}")
    return 0 if summary.met else 1


def _runners(
    engine: str,
    pool_class: Callable[..., Any] | None,
    task: Callable[..., Any] | None,
    confirm: Callable[..., Any] | None,
) -> tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any]]:
    """The pool, the trial's task and the confirming run: RunPool and execute_run on
    ``engine`` (a trial recorded for the best step's figure, without its report's figures),
    confirmed on the ROS engine; or the stand-ins given (tests), their task its own ROS
    engine."""
    if pool_class is None or task is None:
        from joint_space_control.workbench.experiments.execution.distributed import RunPool
        from joint_space_control.workbench.experiments.execution.runner import execute_run

        pool_class = RunPool
        task = partial(execute_run, engine=engine, figures=False, record=True)
        if confirm is None:
            confirm = partial(execute_run, short=False, engine="ros")
    if confirm is None:
        confirm = partial(_confirm_with, task)
    return pool_class, task, confirm


def _confirm_with(task: Callable[..., Any], scenario: Any, target: Any) -> Any:
    return task(scenario, target, False)
