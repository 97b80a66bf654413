"""One ``jsc tune`` session: the options checked into a problem and a search space, the
study run through a pool, and the outputs written. The pool and its task come from the
caller (the CLI: Dask's RunPool with ``execute_run``), so this runs without ROS in tests.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import optuna
from optuna.trial import FrozenTrial, TrialState

from joint_space_control.analysis.spec import fmt_value, judge, parse_spec
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import builtin_robots, resolve_robot
from joint_space_control.workbench.experiments.execution.equivalence import differences
from joint_space_control.workbench.tuning import figures, outputs
from joint_space_control.workbench.tuning.design import (
    ZETA_LADDER,
    effective_inertia,
    theory_design,
    time_scale,
    zeta_ladder,
)
from joint_space_control.workbench.tuning.problem import (
    CONTROLLERS,
    DEFAULT_DURATION,
    DEFAULT_STEP,
    LAW_PARAMETERS,
    TuneProblem,
    step_inside_limits,
)
from joint_space_control.workbench.tuning.space import OMEGA_N_RANGE, ZETA_RANGE, SearchSpace
from joint_space_control.workbench.tuning.study import (
    BATCH,
    INTERRUPTED,
    best_trial,
    fail_stale,
    is_feasible,
    is_finished,
    open_study,
    run_trials,
)


@dataclass(frozen=True)
class TuneOptions:
    robot: str
    controller: str  # "pd_gravity" | "inverse_dynamics"
    spec: str
    law: str | None = None
    trials: int = 30
    jobs: int = 2
    scheduler: str | None = None
    out: Path | None = None
    step: float = DEFAULT_STEP
    duration: float = DEFAULT_DURATION
    seed: int = 0
    study: str | None = None
    gains: str = "omega_zeta"
    omega_n: tuple[float, float] = OMEGA_N_RANGE
    zeta: tuple[float, float] = ZETA_RANGE
    package_paths: tuple[str, ...] = ()
    xacro_args: str = ""
    q0: tuple[float, ...] | None = None
    """The start [rad] (None: 0 inside the limits)."""
    design: bool = True
    """A new study's first trial is the theory's design for the spec
    (workbench/tuning/design.py)."""
    batch: int = BATCH
    """Trials asked, run and told together: the study depends on it, not on ``jobs``
    (workbench/tuning/study.py)."""
    engine: str = "inprocess"
    """Where the trials run: ``inprocess`` (the plant and controller objects in the worker,
    no ROS graph; the best trial is then confirmed on the ROS engine) or ``ros`` (the
    nodes as processes, every trial)."""


@dataclass
class Prepared:
    """The checked options: what to tune, where, under which study name."""

    options: TuneOptions
    problem: TuneProblem
    space: SearchSpace
    out: Path
    study_name: str
    storage: str
    settings: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    design: dict[str, float] | None = None
    """The theory's point for the spec (the first trial of a new study), or None."""
    stage: list[dict[str, float]] = field(default_factory=list)
    """The shared stage's other points, run after the design (PD + g(q)); each of them and
    the design is then run again time-scaled where it missed only time bounds."""


def _is_file(robot: str) -> bool:
    return robot.endswith((".urdf", ".xacro")) or "/" in robot or Path(robot).is_file()


def prepare(options: TuneOptions) -> Prepared:
    """Check the options and load the robot; ValueError (one line) on bad input."""
    spec = parse_spec(options.spec)
    if options.controller not in CONTROLLERS:
        raise ValueError(
            f"--controller must be one of {', '.join(CONTROLLERS)}, got {options.controller!r}"
        )
    controller = CONTROLLERS[options.controller]
    law_name, laws = LAW_PARAMETERS[controller]
    if options.law is not None and options.law not in laws:
        raise ValueError(
            f"--law for {options.controller} sets '{law_name}': one of {', '.join(laws)}, "
            f"got {options.law!r}"
        )
    for what, value, low in (
        ("--trials", options.trials, 1),
        ("--jobs", options.jobs, 1),
        ("--batch", options.batch, 1),
    ):
        if value < low:
            raise ValueError(f"{what} must be >= {low}, got {value}")
    if not (options.duration > 0 and math.isfinite(options.duration)):
        raise ValueError(f"--duration must be > 0 s, got {options.duration}")
    if options.robot in builtin_robots():
        robot_spec = resolve_robot(options.robot)
        robot, robot_parameters = options.robot, {}
    elif _is_file(options.robot):
        path = Path(options.robot).expanduser().resolve()
        if not path.is_file():
            raise ValueError(f"no such robot description file: {options.robot}")
        robot_spec = resolve_robot(
            urdf_path=str(path),
            xacro_args=options.xacro_args,
            package_paths=list(options.package_paths),
        )
        robot = robot_spec.name
        robot_parameters = {"urdf_path": str(path)}
        if options.package_paths:
            robot_parameters["package_paths"] = [str(p) for p in options.package_paths]
        if options.xacro_args:
            robot_parameters["xacro_args"] = options.xacro_args
    else:
        raise ValueError(
            f"unknown robot {options.robot!r}: a built-in robot "
            f"({', '.join(builtin_robots())}) or a .urdf/.xacro file"
        )
    model = RobotModel(robot_spec)
    q0, target = step_inside_limits(
        *model.position_limits,
        options.step,
        None if options.q0 is None else np.array(options.q0, dtype=float),
    )
    pd = controller == "pd_gravity_controller"
    inertia_q0 = model.inertia(q0)
    # PD + g(q): gains scaled by the inertia each joint sees along the step, not diag B̂(q0)
    inertia: tuple[float, ...] = ()
    if pd:
        inertia = tuple(float(b) for b in effective_inertia(inertia_q0, target - q0))
    space = SearchSpace(
        tuple(model.joint_names), options.gains, options.omega_n, options.zeta, inertia
    )
    problem = TuneProblem(
        robot,
        controller,
        tuple(model.joint_names),
        q0,
        target,
        float(options.duration),
        spec,
        options.law or laws[0],  # written out: the file says which law the gains are for
        robot_parameters,
    )
    name = f"{robot}_{options.controller}"
    out = Path(options.out) if options.out is not None else Path("out/tune") / name
    out = out.absolute()  # the path the workers are given
    out.mkdir(parents=True, exist_ok=True)
    settings = {
        "robot": robot,
        "robot_parameters": robot_parameters,
        "controller": controller,
        "law": options.law or laws[0],
        "spec": str(spec),
        "gains": options.gains,
        "omega_n": list(options.omega_n),
        "zeta": list(options.zeta),
        "q0": q0.tolist(),
        "target": target.tolist(),
        "duration": float(options.duration),
    }
    if pd:
        settings["inertia"] = list(inertia)
    design, stage = None, []
    if options.design:
        design = theory_design(
            spec,
            space,
            inertia or np.diag(inertia_q0),
            model.gravity(q0),
            model.effort_limits,
            target - q0,
        )
        stage = zeta_ladder(design, space) if pd else []
    return Prepared(
        options,
        problem,
        space,
        out,
        options.study or name,
        f"sqlite:///{(out / 'study.db').resolve()}",
        settings,
        list(robot_spec.warnings) + list(model.warnings),
        design,
        stage,
    )


Submit = Callable[[str, Any, Path], Future]


def run(
    prepared: Prepared, submit: Submit, in_flight: int, log: Callable[[str], None] = print
) -> optuna.Study:
    """Open (or resume) the study and run it to ``--trials`` finished trials."""
    o = prepared.options
    study = open_study(prepared.storage, prepared.study_name, o.seed, o.trials, prepared.settings)
    stale = fail_stale(study)
    if not study.trials and prepared.design is not None:
        study.enqueue_trial(prepared.design, user_attrs={"origin": DESIGN, STAGE: True})
        omega, zeta = prepared.space.second_order(prepared.design)
        log(
            "trial 0 is the theory's design for the spec: ω_n = "
            + ", ".join(f"{w:.3g}" for w in omega)
            + " rad/s, ζ = "
            + ", ".join(f"{z:.3g}" for z in zeta)
        )
        for k, point in enumerate(prepared.stage, start=1):
            dz = ZETA_LADDER[k - 1]
            study.enqueue_trial(point, user_attrs={"origin": f"design, ζ + {dz:g}", STAGE: True})
        if prepared.stage:
            log(
                f"trials 1-{len(prepared.stage)}: the design with ζ raised by "
                + ", ".join(f"{dz:g}" for dz in ZETA_LADDER[: len(prepared.stage)])
                + "; then each of trials 0-"
                + f"{len(prepared.stage)} that is too slow, time-scaled"
            )
    done = sum(is_finished(t) for t in study.trials)
    if stale:
        log(f"{stale} trial(s) left running by an earlier session marked failed (interrupted)")
    if done:
        log(f"resuming study '{prepared.study_name}': {done} of {o.trials} trials finished")
    if in_flight > o.batch:
        log(
            f"note: {in_flight} workers, batches of {o.batch} trials: {in_flight - o.batch} "
            f"idle (--batch {in_flight} or more uses them all; another --batch is another "
            "study)"
        )
    run_trials(
        study,
        prepared.space,
        prepared.problem,
        submit,
        prepared.out,
        o.trials,
        in_flight,
        log,
        batch=o.batch,
        plan=partial(_time_scaled_stage, prepared, log=log) if prepared.stage else None,
    )
    return study


DESIGN = "theory's design"
STAGE = "shared_stage"
SCALED_FROM = "time_scaled_from"


def _time_scaled_stage(
    prepared: Prepared, study: optuna.Study, log: Callable[[str], None] = print
) -> None:
    """Once the shared stage's trials are told: enqueue each one whose overshoot is met but
    whose time bounds are missed, or met by less than the margin, again with ω_n × α
    (workbench/tuning/design.py ``time_scale``), once; in trial order, from the values told, so a
    seeded study enqueues the same."""
    stage = [t for t in study.trials if t.user_attrs.get(STAGE)]
    if not stage or any(not t.state.is_finished() for t in stage):
        return
    done = {t.user_attrs.get(SCALED_FROM) for t in study.trials}
    for t in sorted(stage, key=lambda t: t.number):
        if t.number in done or t.state != TrialState.COMPLETE:
            continue
        alpha = time_scale(
            prepared.problem.spec, t.user_attrs.get("values", []), prepared.problem.duration
        )
        if alpha is None:
            continue
        point = prepared.space.time_scaled(t.params, alpha)
        study.enqueue_trial(
            point,
            user_attrs={"origin": f"trial {t.number}, ω_n × {alpha:.3g}", SCALED_FROM: t.number},
        )
        log(f"trial {t.number} again, {alpha:.3g} times faster: ω_n × {alpha:.3g}, ζ kept")


def _state(t: FrozenTrial) -> str:
    if t.state == TrialState.COMPLETE:
        return "met" if is_feasible(t) else "missed"
    if t.state == TrialState.FAIL:
        return INTERRUPTED if t.user_attrs.get(INTERRUPTED) else "failed"
    return t.state.name.lower()


def row(t: FrozenTrial) -> outputs.TrialRow:
    a = t.user_attrs
    return outputs.TrialRow(
        t.number,
        _state(t),
        t.value if t.state == TrialState.COMPLETE else None,
        list(a.get("omega_n", [])),
        list(a.get("zeta", [])),
        a.get("values"),
        a.get("joints"),
        a.get("seconds"),
        a.get("error"),
        dict(t.params),
        a.get("origin"),
    )


@dataclass
class Summary:
    met: bool
    best: outputs.TrialRow | None
    closest: str | None
    files: list[Path]


def closest_clause(problem: TuneProblem, best: outputs.TrialRow) -> str:
    """The clause the best (least violating) trial misses by the least, in words."""
    values = best.values or [math.nan] * len(problem.spec.clauses)
    failing = [
        (abs(c.violation(v)), k, c, v)
        for k, (c, v) in enumerate(zip(problem.spec.clauses, values, strict=True))
        if not c.met(v)
    ]
    if not failing:
        return ""
    _, k, clause, value = min(failing, key=lambda x: x[0])
    joint = (best.joints or [None] * len(values))[k]
    where = f" on {joint}" if joint else ""
    return (
        f"{clause} (trial {best.number}: {fmt_value(value, clause.unit)}{where}, "
        f"{100 * abs(clause.violation(value)):.2g} % of the bound away)"
    )


@dataclass
class Confirmation:
    """The best trial run again on the ROS engine: whether it gave the same."""

    same: bool
    text: str


def confirm_best(
    prepared: Prepared, study: optuna.Study, run: Callable[[Any, Path], list[Any]]
) -> Confirmation | None:
    """Run the best trial's scenario again with ``run(scenario, target)`` (the ROS engine)
    into its ``ros_confirmation`` directory: the same values of every clause of the spec,
    bit for bit, and (where both runs wrote one) the same ``metrics.json`` apart from what
    only the recording's clock decides (workbench/experiments/execution/equivalence.py). None
    without a
    best trial."""
    best = best_trial(study)
    if best is None:
        return None
    run_dir = Path(best.user_attrs["run_dir"])
    gains = prepared.space.node_gains(best.params)
    scenario = prepared.problem.scenario(
        gains, f"trial_{best.number:04d}_ros", run_dir / "scenario.yaml"
    )
    target = run_dir / "ros_confirmation"
    shutil.rmtree(target, ignore_errors=True)
    results = run(scenario, target)
    errors = [r.error for r in results if r.error]
    if errors:
        return Confirmation(False, f"trial {best.number} failed on the ROS engine: {errors[0]}")
    judgement = judge(prepared.problem.spec, results[0].controller)
    found = differences([m.value for m in judgement.values], best.user_attrs["values"], "spec")
    ours, theirs = run_dir / "report" / "metrics.json", target / "report" / "metrics.json"
    if ours.is_file() and theirs.is_file():
        found += differences(
            json.loads(ours.read_text()), json.loads(theirs.read_text()), "metrics"
        )
    if found:
        return Confirmation(
            False,
            f"trial {best.number} on the ROS engine differs from its in-process run: "
            + "; ".join(found[:3]),
        )
    return Confirmation(
        True,
        f"trial {best.number} confirmed on the ROS engine (the nodes as processes): the "
        "same metrics, bit for bit",
    )


def write_outputs(
    prepared: Prepared,
    study: optuna.Study,
    pool: str,
    elapsed: float,
    confirmation: Confirmation | None = None,
) -> Summary:
    """best_params.yaml, scenario.yaml, history.png, best_step.png and report.md."""
    problem, space, out = prepared.problem, prepared.space, prepared.out
    trials = sorted(study.trials, key=lambda t: t.number)
    rows = [row(t) for t in trials]
    best_frozen = best_trial(study)
    best = row(best_frozen) if best_frozen is not None else None
    met = best is not None and best.state == "met"
    files: list[Path] = []
    closest = None if best is None or met else closest_clause(problem, best)
    header: list[str] = []
    kp_kd = None
    confirmed = confirmation is None or confirmation.same
    if best is not None:
        gains = space.node_gains(best.params)
        kp, kd = space.kp_kd(best.params)
        kp_kd = (kp.tolist(), kd.tolist())
        header = [
            f"jsc tune {problem.robot} --controller {problem.short_controller}: trial "
            f"{best.number} of study '{prepared.study_name}' "
            f"({'meets' if met else 'does NOT meet'} the spec: {problem.spec})",
            "ω_n [rad/s] = "
            + ", ".join(f"{w:.4g}" for w in best.omega_n)
            + "; ζ = "
            + ", ".join(f"{z:.4g}" for z in best.zeta),
        ]
        if confirmed:  # never a parameter file the nodes have not been seen to agree with
            files.append(
                outputs.write_text(
                    out / "best_params.yaml", outputs.params_yaml(problem, gains, header)
                )
            )
        scenario = outputs.scenario_yaml(problem, gains, header)
        files.append(outputs.write_text(out / "scenario.yaml", scenario))
    met_count = sum(r.state == "met" for r in rows)
    title = (
        f"{problem.robot}, {problem.controller}\n{problem.spec}: {met_count} of "
        f"{len(rows)} trials {'meets' if met_count == 1 else 'meet'} it"
    )
    points = [
        figures.HistoryPoint(r.number, r.objective, r.state == "met")
        for r in rows
        if r.state in ("met", "missed", "failed")
    ]
    figs = [("Optimisation history: each trial's objective, best so far", "history.png")]
    files.append(figures.history_figure(points, out / "history.png", title))
    if best is not None and best_frozen is not None:
        drawn = _best_step(prepared, best, Path(best_frozen.user_attrs.get("run_dir", "")))
        if drawn is not None:
            files.append(drawn)
            figs.append((f"Step response of trial {best.number} against the spec", drawn.name))
    o = prepared.options
    settings = {
        "robot": problem.robot
        + (f" (`{problem.robot_parameters['urdf_path']}`)" if problem.robot_parameters else ""),
        "controller": f"`{problem.controller}`"
        + (f", {LAW_PARAMETERS[problem.controller][0]} = `{problem.law}`" if problem.law else ""),
        "spec": f"`{problem.spec}` (each over the worst joint)",
        "search space": space.describe(),
        "step": f"q0 = {_fmt(problem.q0)} → q_d = {_fmt(problem.target)} rad at t = 0, "
        f"{problem.duration:g} s simulated (lockstep)",
        "sampler": f"TPE, seed {o.seed}, {o.trials} trials in batches of {o.batch}",
        "engine": {
            "inprocess": "in process (the plant and controller objects, no ROS graph)",
            "ros": "ROS (the nodes as processes)",
        }[o.engine]
        + (f"; {confirmation.text}" if confirmation is not None else ""),
        "runs": pool,
        "study": f"`{prepared.study_name}` in `{prepared.storage}`",
        "this session": f"{elapsed:.0f} s",
    }
    report = outputs.report_markdown(problem, rows, best, kp_kd, settings, closest, figs)
    files.append(outputs.write_text(out / "report.md", report))
    return Summary(met and confirmed, best, closest, files)


def _fmt(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.3g}" for v in np.asarray(x).reshape(-1)) + "]"


def _best_step(prepared: Prepared, best: outputs.TrialRow, run_dir: Path) -> Path | None:
    """best_step.png from the best trial's bag (None when there is none: a fake run)."""
    bag = run_dir / "bag"
    if not bag.is_dir():
        return None
    from joint_space_control.analysis.run_metrics import analyze_bag

    analysis = analyze_bag(bag)
    node = "/" + prepared.problem.controller
    c = next((c for c in analysis.controllers if c.metrics["node"] == node), None)
    if c is None:
        return None
    state = c.state
    cols = [state.joints.index(j) for j in prepared.problem.joints]
    steps = c.metrics["steps"]
    notes = []
    for k, j in enumerate(prepared.problem.joints):
        entry = steps[0]["joints"][j] if steps else {}
        notes.append(
            f"ω_n = {best.omega_n[k]:.3g} rad/s, ζ = {best.zeta[k]:.3g}: overshoot "
            f"{fmt_value(_num(entry.get('overshoot_percent')), '%')}, 2 % settling "
            f"{fmt_value(_num(entry.get('settling_time_2'), math.inf), 's')}"
        )
    return figures.step_figure(
        state.stamp,
        state.rows["q"][:, cols],
        state.rows["q_d"][:, cols],
        prepared.problem.joints,
        prepared.problem.spec,
        prepared.out / "best_step.png",
        f"{prepared.problem.robot}, {prepared.problem.controller}, trial {best.number}: "
        f"{prepared.problem.spec}",
        notes,
    )


def _num(x: Any, missing: float = math.nan) -> float:
    return missing if x is None else float(x)
