"""The results page's table of the same experiments on several plant engines
(``jsc experiment --plant-engine pybullet,mujoco --report DIR``): for each check of each
experiment, its verdict and figures on every engine, and how far apart the engines' runs
are (the largest difference of the published joint positions at the same instants).

The check texts round to three or four digits, where the engines agree; the last column says
by how much they do not: both integrate the same equations with the same scheme
(semi-implicit Euler at ``1 / physics_rate``), so what is left is their arithmetic (each
engine's own algorithm for B(q)⁻¹ and the bias forces) and their constraint solvers (joint
limits, Coulomb friction, brakes: soft on MuJoCo, docs/plant.md).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from joint_space_control.analysis.bag import BagError, joint_states, read_bag
from joint_space_control.workbench.experiments.judging.outcome import verdict_word

if TYPE_CHECKING:
    from joint_space_control.workbench.experiments.execution.runner import RunResult
    from joint_space_control.workbench.experiments.experiment import ExperimentResult

#: The engines' names as the page prints them.
ENGINE_NAMES = {"pybullet": "PyBullet", "mujoco": "MuJoCo"}


def _cell(text: str) -> str:
    """``text`` as one Markdown table cell (no pipes, no line breaks)."""
    return " ".join(text.replace("|", "\\|").split())


def published_positions(run: RunResult) -> tuple[np.ndarray, np.ndarray]:
    """(stamps [ns], positions) of the states the plant published in ``run``: kept in
    memory (in process) or read from its bag."""
    if run.response is not None:
        return np.round(run.response.t * 1e9).astype(np.int64), run.response.q
    topic = f"/{run.namespace}/joint_states" if run.namespace else "/joint_states"
    states = joint_states(read_bag(run.out / "bag", [topic]).data[topic])
    return np.round(states.stamp * 1e9).astype(np.int64), states.position


def position_difference(a: ExperimentResult, b: ExperimentResult) -> float:
    """The largest |q_b − q_a| [rad or m] over every run both have, at the instants both
    published (NaN when no run can be compared)."""
    runs_b = {(r.label, r.namespace): r for r in b.runs if r.error is None}
    worst = math.nan
    for run in a.runs:
        other = runs_b.get((run.label, run.namespace))
        if run.error is not None or other is None:
            continue
        try:
            (ta, qa), (tb, qb) = published_positions(run), published_positions(other)
        except (BagError, KeyError):
            continue
        _, ia, ib = np.intersect1d(ta, tb, assume_unique=False, return_indices=True)
        if ia.size:
            d = float(np.nanmax(np.abs(qb[ib] - qa[ia])))
            worst = d if math.isnan(worst) else max(worst, d)
    return worst


def engine_table(by_engine: dict[str, list[ExperimentResult]]) -> list[str]:
    """The section of each check's figures engine by engine: a row per check of every
    experiment run on all of them, a column per engine (verdict and the check's text), and
    the largest difference of the positions between the first engine and each other."""
    engines = list(by_engine)
    heads = [ENGINE_NAMES.get(e, e) for e in engines]
    first_name = heads[0]
    diffs = [f"max \\|q_{h} − q_{first_name}\\|" for h in heads[1:]]
    lines = [
        "## Engine by engine: the same checks on " + " and ".join(heads),
        "",
        "Every experiment above run again with the plant on each physics engine "
        f"(`--plant-engine {','.join(engines)}`), from the same URDF and the same "
        "parameters (docs/plant.md, Engines). A row is one check; each cell its verdict and "
        "the figures it measured on that engine. The last column: the largest difference of "
        "the published joint positions between the engines, over the experiment's runs, at "
        "the same instants [rad or m]: what the rounded figures do not show.",
        "",
        "| Experiment | " + " | ".join([*heads, *diffs]) + " |",
        "|---" * (1 + len(heads) + len(diffs)) + "|",
    ]
    first = sorted(by_engine[engines[0]], key=lambda r: (r.scenario.question, r.scenario.name))
    others = [{r.scenario.name: r for r in by_engine[e]} for e in engines[1:]]
    for result in first:
        name = result.scenario.name
        same = [o.get(name) for o in others]
        if any(r is None for r in same):
            continue
        row_results = [result, *same]
        apart = [f"{position_difference(result, r):.2g}" for r in same]
        n = max(len(r.outcomes) for r in row_results)
        for k in range(max(n, 1)):
            cells = []
            for r in row_results:
                if r.errors:
                    cells.append("run failed: " + "; ".join(r.errors) if k == 0 else "")
                elif k < len(r.outcomes):
                    o = r.outcomes[k]
                    cells.append(f"*{verdict_word(o.passed)}*: {o.text}")
                else:
                    cells.append("")
            label = f"Q{result.scenario.question} `{name}`" if k == 0 else ""
            extra = apart if k == 0 else [""] * len(apart)
            lines.append("| " + " | ".join([label, *(_cell(c) for c in cells), *extra]) + " |")
    return [*lines, "", WHAT_DIFFERS, ""]


#: What the table's last column shows, said under it.
WHAT_DIFFERS = (
    "What makes the engines differ: both integrate the same model (the URDF's inertias, "
    "mass matrix and bias forces equal to Pinocchio's to 1e-12 on both) with the same "
    "scheme, semi-implicit Euler at 1/`physics_rate`, so a frictionless loop differs by "
    "rounding (~1e-16 rad). Above rounding: a constraint acting (Coulomb friction, "
    "stiction, the brakes, a joint limit), which MuJoCo solves as a soft constraint and "
    "Bullet as a velocity motor (`coulomb_friction`: ~6e-5 rad); and a loop near the edge "
    "of its stability, which amplifies rounding (`sampling_period`'s slowest sampling)."
)
