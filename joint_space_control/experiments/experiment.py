"""One experiment end to end (runs → checks → summary), and the results page of many.

Files per experiment ``<out>/<name>/``: one run directory per variant (``bag/``,
``report/``, ``logs/``, ``events.json``), ``result.json`` (the checks with their numbers),
``summary.md``, ``sweep.png`` for a sweep (bars, or heat maps of a grid:
:mod:`~joint_space_control.experiments.sweep_figures`), and the figures the scenario names
(``figures``, :mod:`~joint_space_control.experiments.figures`). A world of several robots is
one run (one bag, one ``report/`` with every controller) judged per robot: each check sees
each robot as a run of its own, labelled with the robot's name.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from joint_space_control.analysis.report import write_metrics
from joint_space_control.experiments import figures, sweep_figures
from joint_space_control.experiments.execution.distributed import RunPool
from joint_space_control.experiments.execution.runner import RunResult, run_scenario
from joint_space_control.experiments.judging.outcome import Outcome, RunView
from joint_space_control.experiments.judging.theory import evaluate
from joint_space_control.experiments.scenarios.format import Scenario
from joint_space_control.json_values import jsonable

#: Questions 1–8 are THEORY.md §5's experiments; 9–14 §4's practical specifications; from
#: 15 on, practice beyond the theory (several robots in one world).
LAST_SECTION5_QUESTION = 8
LAST_SECTION4_QUESTION = 14


@dataclass
class ExperimentResult:
    scenario: Scenario
    out: Path
    runs: list[RunResult]
    outcomes: list[Outcome]
    errors: list[str]
    figures: list[Path] = field(default_factory=list)
    """The scenario's own figures (experiments/figures.py), drawn first on the page."""

    @property
    def passed(self) -> bool | None:
        """False if a run failed or a check failed; None if no check makes a claim."""
        if self.errors or any(o.passed is False for o in self.outcomes):
            return False
        claims = [o.passed for o in self.outcomes if o.passed is not None]
        return all(claims) if claims else None


def run_experiment(
    scenario: Scenario,
    out: Path,
    short: bool = False,
    pool: RunPool | None = None,
    log: Callable[[str], None] = print,
    engine: str = "ros",
) -> ExperimentResult:
    """The scenario's runs (tasks of ``pool``; None: two threads here), its checks, its
    figures and summary, in ``out/<name>/``. The runs write their bags and reports there
    and this process draws the figures from them: with workers on other machines, ``out``
    must be a directory they all reach at the same path."""
    out = out / scenario.name
    if out.exists():
        shutil.rmtree(out)  # the experiment's own directory: a rerun replaces it
    runs = run_scenario(scenario, out, short, pool, log, engine)
    errors = [f"{r.label}: {r.error}" for r in runs if r.error]
    views = [
        RunView(
            r.label,
            r.scenario.robot,
            r.controller,
            r.events,
            r.scenario.parameters,
            r.scenario.plant,
            r.scenario.controller,
            r.state,
            r.truth,
            r.scenario.reference,
        )
        for r in runs
        if r.error is None
    ]
    outcomes: list[Outcome] = []
    if views:
        for spec in scenario.checks:
            try:
                outcomes += evaluate(spec, views)
            except (KeyError, ValueError, TypeError, IndexError) as err:
                errors.append(f"check {spec.get('check')}: {type(err).__name__}: {err}")
    result = ExperimentResult(scenario, out, runs, outcomes, errors)
    if scenario.variants is not None and views:
        sweep_figures.draw(result, out / "sweep.png")
    if views:
        result.figures = figures.draw(result)
    write_metrics(_result_json(result, short), out / "result.json")
    (out / "summary.md").write_text(summary_markdown(result, out))
    return result


def _result_json(result: ExperimentResult, short: bool) -> dict:
    s = result.scenario
    v = s.variants
    grid_axes = v.axes if v is not None else ()
    index = {label: v.grid_index[k] for k, (label, _) in enumerate(v.runs)} if grid_axes else {}
    runs = []
    for r in result.runs:
        run = {"label": r.label, "dir": str(r.out), "error": r.error, "events": r.events}
        if r.namespace:  # a robot of a world of several
            run.update(robot=r.scenario.robot, controller=r.scenario.controller)
        if r.label in index:  # where the run sits in its grid
            run["grid_index"] = list(index[r.label])
        runs.append(run)
    grid = {}
    if grid_axes:
        axes = [{"key": a.key, "name": a.name, "values": list(a.values)} for a in grid_axes]
        grid = {"grid": {"axes": axes, "boundary": v.boundary}}
    return {
        "scenario": s.name,
        "title": s.title,
        "question": s.question,
        "robot": s.robot,
        "controller": s.controller,
        "short": short,
        "passed": result.passed,
        "errors": result.errors,
        "runs": runs,
        "checks": [jsonable(o.__dict__) for o in result.outcomes],  # NaN, ±inf: null
        **grid,
    }


def _verdict(passed: bool | None) -> str:
    return {True: "agrees", False: "DISAGREES", None: "no claim"}[passed]


def summary_markdown(result: ExperimentResult, base: Path, figures: Path | None = None) -> str:
    """The experiment in a few lines: question, checks with numbers, figures. Links are
    relative to ``base``; with ``figures``, the plots are copied there first."""
    s = result.scenario
    lines = [f"### {s.question}. {s.title}", ""]
    if s.notes:
        lines += [s.notes.strip(), ""]
    if s.robots:
        world = ", ".join(f"`{r.name}` ({r.robot}, `{r.controller}`)" for r in s.robots)
        lines += [f"`{s.name}`: {len(s.robots)} robots in one world, one run: {world}", ""]
    else:
        lines += [
            f"`{s.name}`: {s.robot}, `{s.controller}`, " + _runs_text(result),
            "",
        ]
    for o in result.outcomes:
        lines.append(f"- **{_verdict(o.passed)}** ({o.check}): {o.text}")
    for e in result.errors:
        lines.append(f"- **run failed**: {e}")
    lines.append("")
    for plot in _key_plots(result):
        if figures is not None:
            figures.mkdir(parents=True, exist_ok=True)
            run_dir = plot.parent.parent  # <experiment>/<run>/report/x.png, or <experiment>/
            target = figures / f"{s.name}_{run_dir.name}_{plot.name}"
            if plot.parent == result.out or run_dir == result.out:
                target = figures / f"{s.name}_{plot.name}"
            shutil.copyfile(plot, target)
            plot = target
        rel = _relative(plot, base)
        lines += [f"![{s.name} {plot.stem}]({rel})", ""]
    return "\n".join(lines)


def _runs_text(result: ExperimentResult) -> str:
    """``one run``, ``4 runs over mismatch``, or ``4 runs of a 5×5 grid (model_mass_scale ×
    omega_n)`` (the short form runs some of the grid)."""
    v = result.scenario.variants
    if v is None:
        return "one run"
    if v.axes:
        shape = "×".join(str(n) for n in v.shape)
        runs = len({r.label for r in result.runs})
        return f"{runs} runs of a {shape} grid ({' × '.join(a.name for a in v.axes)})"
    return f"{len(result.runs)} runs over {v.name}"


def _relative(path: Path, base: Path) -> str:
    try:
        return str(path.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(path.resolve())


def _key_plots(result: ExperimentResult) -> list[Path]:
    ok = [r for r in result.runs if r.error is None]
    sweep = result.out / "sweep.png"
    grid = result.scenario.variants is not None and bool(result.scenario.variants.axes)
    if result.figures:  # the scenario's own figures say what its runs show (a grid: after
        # its heat maps, which are its answer)
        return ([sweep] if grid and sweep.is_file() else []) + list(result.figures)
    if sweep.is_file():  # and the last run's positions
        standard, shown = [sweep], ok[-1:]
    else:  # the run's positions: of its one robot, or of each robot of its world
        standard, shown = [], ok
    return standard + [r.figures["positions"] for r in shown if "positions" in r.figures]


#: The tuning example's page and figure beside the results page (docs/tuning.md, made with
#: `jsc tune`: a study is not a scenario, so its numbers stay on that page).
TUNING_PAGE = "tuning.md"
TUNING_EXAMPLE = "#example-a-ur5-from-example-robot-data"
TUNING_FIGURE = "figures/tune_ur5_best_step.png"


def tuning_section(docs: Path) -> list[str]:
    """The results page's pointer to the tuning example on a real description, when the
    page goes beside ``tuning.md`` (docs/); nothing elsewhere."""
    if not (docs / TUNING_PAGE).is_file() or not (docs / TUNING_FIGURE).is_file():
        return []
    return [
        "## In practice: gains that meet a specification, on a robot nobody here wrote",
        "",
        "`jsc tune` searches a controller's gains (an Optuna study of lockstep step-response "
        "runs on the Dask cluster) until a step response meets a specification. The example "
        "is the UR5 of example-robot-data with inverse dynamics and `overshoot<=5, "
        "settling_2pct<=0.8, peak_torque_ratio<=0.8`; the study, its numbers and the "
        f"confirming `jsc experiment --params-file` run are in [Gain tuning]({TUNING_PAGE}"
        f"{TUNING_EXAMPLE}).",
        "",
        f"![UR5 step response with the tuned gains against the specification]({TUNING_FIGURE})",
        "",
    ]


def results_page(results: list[ExperimentResult], docs: Path, short: bool) -> Path:
    """``docs/results.md``: every experiment's answer with its numbers and plots."""
    docs.mkdir(parents=True, exist_ok=True)
    figures = docs / "figures"
    lines = [
        "# Results: the experiments of THEORY.md §5 and the specifications of §4",
        "",
        "Generated by `jsc experiment --all --report docs/` (lockstep simulation: "
        "regenerating gives the same numbers). Every number below is measured by the package "
        "from a recorded run and set next to the theory's prediction; *agrees* / "
        "*DISAGREES* is the check's verdict with the tolerance it states, *no claim* where "
        "the theory predicts nothing.",
        "",
    ]
    if short:
        lines += ["**Short runs (CI form): durations cut, numbers not final.**", ""]
    sections = (
        (lambda q: q <= LAST_SECTION5_QUESTION, "## THEORY.md §5: the experiments"),
        (
            lambda q: LAST_SECTION5_QUESTION < q <= LAST_SECTION4_QUESTION,
            "## THEORY.md §4: the practical specifications (disturbances, sampling, bandwidth,"
            " noise, friction, repeatability)",
        ),
        (lambda q: q > LAST_SECTION4_QUESTION, "## In practice: several robots in one world"),
    )
    ordered = sorted(results, key=lambda r: (r.scenario.question, r.scenario.name))
    for belongs, heading in sections:
        chosen = [r for r in ordered if belongs(r.scenario.question)]
        if chosen:
            lines += [heading, ""]
        for result in chosen:
            lines.append(summary_markdown(result, docs, figures))
    lines += tuning_section(docs)
    path = docs / "results.md"
    path.write_text("\n".join(lines))
    summary = []
    for r in results:
        entry = _result_json(r, short)
        for run in entry["runs"]:
            run.pop("dir")  # machine-specific: keep the page reproducible
        summary.append(entry)
    write_metrics({"experiments": summary}, docs / "results.json")
    return path
