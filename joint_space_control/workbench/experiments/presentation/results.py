"""What an experiment's results say, written for people and for programs: an experiment's
``summary.md`` (its question, every check's verdict with its numbers, its key figures) and
``result.json`` (the same, machine-readable), and the results page of many experiments,
``docs/results.md`` with ``docs/results.json`` (``jsc experiment --all --report docs/``),
ordered as THEORY.md asks its questions: §5's experiments, §4's practical specifications,
then practice beyond the theory, and a pointer to the tuning example.

``result`` is an :class:`~joint_space_control.workbench.experiments.experiment.ExperimentResult`,
imported for type checking only (the experiment module imports this one). The page's
``results.json`` leaves out each run's directory, a path of the machine it ran on, so that
regenerating the page elsewhere gives the same file; its plots are copied under ``figures/``
with the names of their experiment and run.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import TYPE_CHECKING

from joint_space_control.analysis.report import write_metrics
from joint_space_control.json_values import jsonable
from joint_space_control.workbench.experiments.judging.outcome import verdict_word
from joint_space_control.workbench.experiments.presentation.engines import engine_table

if TYPE_CHECKING:
    from joint_space_control.workbench.experiments.experiment import ExperimentResult

#: Questions 1–8 are THEORY.md §5's experiments; 9–14 §4's practical specifications; from
#: 15 on, practice beyond the theory (several robots in one world).
LAST_SECTION5_QUESTION = 8
LAST_SECTION4_QUESTION = 14


def result_json(result: ExperimentResult, short: bool) -> dict:
    """``result.json``: the experiment's runs (where each sits in its grid), its verdict and
    every check with its numbers (NaN and ±inf as null)."""
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
        lines.append(f"- **{verdict_word(o.passed)}** ({o.check}): {o.text}")
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


def results_page(
    results: list[ExperimentResult],
    docs: Path,
    short: bool,
    by_engine: dict[str, list[ExperimentResult]] | None = None,
) -> Path:
    """``docs/results.md``: every experiment's answer with its numbers and plots (and,
    given ``by_engine``, the table of each check on each plant engine)."""
    docs.mkdir(parents=True, exist_ok=True)
    figures = docs / "figures"
    lines = [
        "# Results: the experiments of THEORY.md §5 and the specifications of §4",
        "",
        "Generated by `jsc experiment --all --report docs/` (lockstep simulation: "
        "regenerating gives the same numbers; with `--engine inprocess --plant-engine "
        "pybullet,mujoco`, the same numbers in minutes and the engine-by-engine table at the "
        "end). Every number below is measured by the package "
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
    if by_engine:
        lines += engine_table(by_engine)
    lines += tuning_section(docs)
    path = docs / "results.md"
    path.write_text("\n".join(lines))
    summary = []
    for r in results:
        entry = result_json(r, short)
        for run in entry["runs"]:
            run.pop("dir")  # machine-specific: keep the page reproducible
        summary.append(entry)
    write_metrics({"experiments": summary}, docs / "results.json")
    return path
