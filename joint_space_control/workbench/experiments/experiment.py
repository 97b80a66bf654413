"""One experiment end to end: its runs, their checks, its figures and summary.

Files per experiment ``<out>/<name>/``: one run directory per variant (``bag/``,
``report/``, ``logs/``, ``events.json``), ``result.json`` (the checks with their numbers),
``summary.md``, ``sweep.png`` for a sweep (bars, or heat maps of a grid:
:mod:`~joint_space_control.workbench.experiments.presentation.sweep_figures`), and the figures the
scenario names (``figures``,
:mod:`~joint_space_control.workbench.experiments.presentation.figures`).
A world of several robots is one run (one bag, one ``report/`` with every controller) judged
per robot: each check sees each robot as a run of its own, labelled with the robot's name.

This module only orders the work of the subpackages: the runs are made by
:mod:`~joint_space_control.workbench.experiments.execution`, judged by
:mod:`~joint_space_control.workbench.experiments.judging`, and drawn and written up by
:mod:`~joint_space_control.workbench.experiments.presentation` (the figures, ``summary.md`` and
``result.json`` here; the results page of many experiments, which ``jsc experiment --report``
asks for, in :mod:`~joint_space_control.workbench.experiments.presentation.results`).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from joint_space_control.analysis.report import write_metrics
from joint_space_control.workbench.experiments.execution.distributed import RunPool
from joint_space_control.workbench.experiments.execution.runner import RunResult, run_scenario
from joint_space_control.workbench.experiments.judging.outcome import Outcome, RunView
from joint_space_control.workbench.experiments.judging.theory import evaluate
from joint_space_control.workbench.experiments.presentation import figures, sweep_figures
from joint_space_control.workbench.experiments.presentation.results import (
    result_json,
    summary_markdown,
)
from joint_space_control.workbench.experiments.scenarios.format import Scenario


@dataclass
class ExperimentResult:
    scenario: Scenario
    out: Path
    runs: list[RunResult]
    outcomes: list[Outcome]
    errors: list[str]
    figures: list[Path] = field(default_factory=list)
    """The scenario's own figures (presentation/figures.py), drawn first on the page."""

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
    record: bool = False,
) -> ExperimentResult:
    """The scenario's runs (tasks of ``pool``; None: two threads here), its checks, its
    figures and summary, in ``out/<name>/``. The runs write their bags and reports there
    and this process draws the figures from them: with workers on other machines, ``out``
    must be a directory they all reach at the same path."""
    out = out / scenario.name
    if out.exists():
        shutil.rmtree(out)  # the experiment's own directory: a rerun replaces it
    runs = run_scenario(scenario, out, short, pool, log, engine, record)
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
    write_metrics(result_json(result, short), out / "result.json")
    (out / "summary.md").write_text(summary_markdown(result, out))
    return result
