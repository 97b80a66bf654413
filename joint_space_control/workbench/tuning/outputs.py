"""What ``jsc tune`` leaves in its output directory, as text: the best gains as a parameter
file for the controller node, the step-response scenario with them, and the report. Pure
(yaml and strings), no ROS.

- ``best_params.yaml``: ``<controller>: {ros__parameters: {...}}``, the node's own name as the
  key (``inverse_dynamics_controller --ros-args --params-file best_params.yaml``, or
  ``jsc experiment ... --params-file``): the robot parameters, the law and the gains;
- ``scenario.yaml``: the trials' step response with the best gains and a ``spec`` check
  (``jsc experiment <out>/scenario.yaml`` confirms the specification);
- ``report.md``: settings, the best trial with its gains and measured values, every trial,
  the figures.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from joint_space_control.analysis.spec import fmt_value
from joint_space_control.workbench.tuning.problem import TuneProblem


@dataclass(frozen=True)
class TrialRow:
    """One trial as the report shows it (from the study's stored trials)."""

    number: int
    state: str  # "met" | "missed" | "failed" | "interrupted" | "running"
    objective: float | None
    omega_n: list[float]
    zeta: list[float]
    values: list[float] | None = None
    joints: list[str | None] | None = None
    seconds: float | None = None
    error: str | None = None
    params: dict[str, float] | None = None
    origin: str | None = None  # "theory's design" for the first trial, else TPE's


def _header(lines: Sequence[str]) -> str:
    return "".join(f"# {line}\n" for line in lines)


def params_yaml(problem: TuneProblem, gains: dict[str, Any], header: Sequence[str] = ()) -> str:
    """The controller's parameter file of ``gains``."""
    body = {problem.controller: {"ros__parameters": problem.node_parameters(gains)}}
    return _header(header) + yaml.safe_dump(body, sort_keys=False, default_flow_style=None)


def scenario_yaml(problem: TuneProblem, gains: dict[str, Any], header: Sequence[str] = ()) -> str:
    """The step-response scenario of ``gains`` with its ``spec`` check."""
    data = problem.scenario_data(
        gains,
        title=f"Tuned gains on {problem.robot}: step response against the spec",
        notes=f"Gains found by jsc tune for: {problem.spec}.",
    )
    return _header(header) + yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def _vector(xs: Sequence[float] | None, digits: int = 4) -> str:
    if xs is None:
        return "–"
    return "[" + ", ".join(f"{x:.{digits}g}" for x in xs) + "]"


def _clause_rows(problem: TuneProblem, row: TrialRow) -> list[str]:
    out = ["| clause | worst joint | measured | met |", "|---|---|---|---|"]
    for k, clause in enumerate(problem.spec.clauses):
        value = row.values[k] if row.values else math.nan
        joint = (row.joints[k] if row.joints else None) or "–"
        out.append(
            f"| `{clause}` | {joint} | {fmt_value(value, clause.unit)} | "
            f"{'yes' if clause.met(value) else '**no**'} |"
        )
    return out


def report_markdown(
    problem: TuneProblem,
    rows: Sequence[TrialRow],
    best: TrialRow | None,
    kp_kd: tuple[list[float], list[float]] | None,
    settings: dict[str, str],
    closest: str | None,
    figures: Sequence[tuple[str, str]],
) -> str:
    """``report.md``: what was tuned, the best trial (or the closest one), every trial."""
    met = [r for r in rows if r.state == "met"]
    failed = [r for r in rows if r.state == "failed"]
    lines = [
        f"# jsc tune: {problem.robot}, {problem.controller}",
        "",
        "| setting | value |",
        "|---|---|",
    ]
    lines += [f"| {k} | {v} |" for k, v in settings.items()]
    lines += [
        "",
        f"Trials: {len(rows)} ({len(met)} {'meets' if len(met) == 1 else 'meet'} the spec, "
        f"{len(rows) - len(met) - len(failed)} miss it, {len(failed)} "
        f"{'run' if len(failed) == 1 else 'runs'} failed).",
        "",
    ]
    if best is None:
        lines += ["No trial completed: no gains to report.", ""]
    else:
        verdict = "meets the spec" if best.state == "met" else "**does not meet the spec**"
        lines += [
            f"## Best trial: {best.number} ({verdict})",
            "",
            f"Objective {best.objective:+.4g} (minimised: ≤ 0 is minus the smallest normalised "
            "margin; > 0 the sum of the normalised violations over clauses and joints).",
            "",
            "| joint | ω_n [rad/s] | ζ | K_P | K_D |",
            "|---|---|---|---|---|",
        ]
        kp, kd = kp_kd or ([math.nan] * len(problem.joints), [math.nan] * len(problem.joints))
        for j, name in enumerate(problem.joints):
            lines.append(
                f"| {name} | {best.omega_n[j]:.4g} | {best.zeta[j]:.4g} | {kp[j]:.4g} | "
                f"{kd[j]:.4g} |"
            )
        lines += [""] + _clause_rows(problem, best) + [""]
        if closest:
            lines += [f"No trial met the spec; the closest clause: {closest}.", ""]
    for caption, file in figures:
        lines += [f"![{caption}]({file})", "", f"*{caption}*", ""]
    lines += [
        "## Every trial",
        "",
        "| trial | state | objective | ω_n [rad/s] | ζ | "
        + " | ".join(f"`{c}`" for c in problem.spec.clauses)
        + " | time [s] |",
        "|---|---|---|---|---|" + "---|" * len(problem.spec.clauses) + "---|",
    ]
    for r in rows:
        cells = [
            fmt_value(r.values[k]) if r.values else "–" for k in range(len(problem.spec.clauses))
        ]
        objective = "–" if r.objective is None else f"{r.objective:+.3g}"
        state = r.state if r.error is None else f"{r.state}: {r.error[:80]}"
        if r.origin:
            state += f" ({r.origin})"
        seconds = "–" if r.seconds is None else f"{r.seconds:.0f}"
        lines.append(
            f"| {r.number} | {state} | {objective} | {_vector(r.omega_n, 3)} | "
            f"{_vector(r.zeta, 3)} | " + " | ".join(cells) + f" | {seconds} |"
        )
    lines.append("")
    return "\n".join(lines)


def write_text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path
