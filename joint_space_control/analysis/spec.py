r"""Step-response specifications: ``"overshoot<=5, settling_2pct<=0.8"`` parsed, measured on
a controller's metrics (``jsc analyze``'s ``metrics.json``, :mod:`.run_metrics`) and judged.

One place for ``jsc tune`` (the constraints of its study) and the ``spec`` check of
``jsc experiment`` (workbench/experiments/judging/theory.py), so that what was tuned is what is
confirmed.
Pure: strings and metric dictionaries in, numbers out.

A specification is a comma-separated list of clauses ``metric<=value`` or ``metric>=value``.
Every metric is taken over the worst joint of the run's first step (the largest value for
``<=``, the smallest for ``>=``), over the joints the step moves:

=====================  ======  =================================================================
metric                 unit    what (per joint)
=====================  ======  =================================================================
``overshoot``          %       largest excursion past the target, in % of the step
``settling_2pct``      s       time after the step from which q stays within ±2 % of the step
``settling_5pct``      s       the same within ±5 %
``rise_time``          s       10 % → 90 % of the way to the final value
``steady_state_error`` rad     \|q_d − q\| at the end (mean of the last 0.1 s)
``peak_torque_ratio``  –       peak \|τ_i\| over the effort limit of joint i (every joint)
``saturated_fraction`` –       fraction of the run at the effort limit (every joint)
=====================  ======  =================================================================

A response that never enters its band (or never reaches 90 %) within the run has an infinite
settling (rise) time: it fails every ``<=`` bound.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Metric:
    name: str
    unit: str
    meaning: str
    key: str
    """Its key in a joint's step entry (``steps[k]['joints'][j]``), or in ``torque_demand``."""
    source: str  # "step" | "torque"


METRICS: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric("overshoot", "%", "overshoot past the target", "overshoot_percent", "step"),
        Metric("settling_2pct", "s", "2 % settling time", "settling_time_2", "step"),
        Metric("settling_5pct", "s", "5 % settling time", "settling_time_5", "step"),
        Metric("rise_time", "s", "10-90 % rise time", "rise_time", "step"),
        Metric("steady_state_error", "rad", "|steady-state error|", "steady_state_error", "step"),
        Metric("peak_torque_ratio", "", "peak |τ| / effort limit", "peak_abs", "torque"),
        Metric("saturated_fraction", "", "time at the limit", "saturated_fraction", "torque"),
    )
}

#: A normalised violation is capped here (a metric that cannot be measured, say): large
#: enough to be the worst clause of any trial, finite so that an optimiser can rank it.
VIOLATION_CAP = 10.0

_CLAUSE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=)\s*(\S+)\s*$")


class SpecError(ValueError):
    """A specification that cannot be parsed; the message is one line."""


def allowed() -> str:
    """The metrics a specification may use, with units, for error messages and help."""
    return ", ".join(f"{m.name} [{m.unit}]" if m.unit else m.name for m in METRICS.values())


@dataclass(frozen=True)
class Clause:
    metric: str
    op: str  # "<=" | ">="
    bound: float

    @property
    def unit(self) -> str:
        return METRICS[self.metric].unit

    @property
    def scale(self) -> float:
        """What one unit of normalised violation is: |bound|, or 1 for a bound of 0."""
        return abs(self.bound) if self.bound != 0.0 else 1.0

    def __str__(self) -> str:
        return f"{self.metric}{self.op}{self.bound:g}"

    def met(self, value: float) -> bool:
        if math.isnan(value):
            return False
        return value <= self.bound if self.op == "<=" else value >= self.bound

    def violation(self, value: float) -> float:
        """(value − bound)/scale for ``<=``, (bound − value)/scale for ``>=``: ≤ 0 when met
        (its magnitude is then the margin), capped at ±:data:`VIOLATION_CAP`; NaN (not
        measured) counts as the cap."""
        if math.isnan(value):
            return VIOLATION_CAP
        excess = value - self.bound if self.op == "<=" else self.bound - value
        return max(-VIOLATION_CAP, min(VIOLATION_CAP, excess / self.scale))


@dataclass(frozen=True)
class Spec:
    clauses: tuple[Clause, ...]

    def __str__(self) -> str:
        return ", ".join(str(c) for c in self.clauses)

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(c.metric for c in self.clauses))


def parse_spec(text: str) -> Spec:
    """``"overshoot<=5, settling_2pct<=0.8"`` → :class:`Spec`. Raises :class:`SpecError`
    naming the clause and the allowed metrics."""
    if not isinstance(text, str) or not text.strip():
        raise SpecError(f"empty specification; give clauses 'metric<=value', metrics: {allowed()}")
    clauses = []
    for raw in text.split(","):
        match = _CLAUSE.match(raw)
        if match is None:
            raise SpecError(
                f"malformed clause {raw.strip()!r}: write 'metric<=value' or 'metric>=value', "
                f"metrics: {allowed()}"
            )
        name, op, number = match.groups()
        if name not in METRICS:
            raise SpecError(f"unknown metric {name!r} in {raw.strip()!r}; allowed: {allowed()}")
        try:
            bound = float(number)
        except ValueError:
            bound = math.nan
        if not math.isfinite(bound):
            raise SpecError(f"{raw.strip()!r}: the bound must be a finite number, got {number!r}")
        clauses.append(Clause(name, op, bound))
    return Spec(tuple(clauses))


@dataclass(frozen=True)
class Measured:
    """A metric over the worst joint: its ``value`` (inf: never settled, NaN: not measured),
    the joint it comes from and, per joint, what was measured."""

    value: float
    joint: str | None
    per_joint: dict[str, float]
    note: str = ""


def _number(x: Any) -> float:
    return math.nan if x is None else float(x)


def per_joint_values(metric: str, controller: Mapping[str, Any]) -> tuple[dict[str, float], str]:
    """The metric on every joint it applies to (the joints the first step moves, or all for
    torques), and a note when it cannot be measured."""
    m = METRICS[metric]
    if m.source == "torque":
        td = controller["torque_demand"]
        values = {j: _number(v) for j, v in td[m.key].items()}
        if metric == "peak_torque_ratio":
            limits = td.get("effort_limits") or {}
            values = {
                j: v / _number(limits.get(j)) if _number(limits.get(j)) > 0 else math.nan
                for j, v in values.items()
            }
            if all(math.isnan(v) for v in values.values()):
                return values, "no effort limits known"
        return values, ""
    steps = controller.get("steps") or []
    if not steps:
        return {}, "no step in the run"
    joints = {j: e for j, e in steps[0]["joints"].items() if e.get("moving")}
    if not joints:
        return {}, "the step moves no joint"
    values = {}
    for j, entry in joints.items():
        v = _number(entry.get(m.key))
        if metric == "steady_state_error":
            v = abs(v)
        elif m.key in ("settling_time_2", "settling_time_5", "rise_time") and math.isnan(v):
            v = math.inf  # still outside the band (or short of 90 %) at the end of the run
        values[j] = v
    return values, ""


def measure(spec: Spec, controller: Mapping[str, Any]) -> dict[str, dict[str, Measured]]:
    """Every metric of ``spec`` on the controller's metrics, over the worst joint, by the
    direction of each clause: ``result[metric][op]``."""
    out: dict[str, dict[str, Measured]] = {}
    for clause in spec.clauses:
        values, note = per_joint_values(clause.metric, controller)
        known = {j: v for j, v in values.items() if not math.isnan(v)}
        if not known:
            worst = Measured(math.nan, None, values, note or "not measured")
        else:
            pick = max if clause.op == "<=" else min
            joint = pick(known, key=known.__getitem__)
            worst = Measured(known[joint], joint, values, note)
        out.setdefault(clause.metric, {})[clause.op] = worst
    return out


@dataclass(frozen=True)
class Judgement:
    """A spec judged on one run: per clause the worst joint's value and the normalised
    violation (≤ 0: met, its magnitude the margin)."""

    spec: Spec
    values: tuple[Measured, ...]
    violations: tuple[float, ...]
    by_joint: tuple[dict[str, float], ...] = ()
    """Per clause, each joint's normalised violation (a clause nothing measured: ``{"":
    cap}``): every joint must meet every clause."""

    @property
    def excess(self) -> float:
        """Σ over clauses and joints of the positive violations: how far the run is from the
        specification on every joint, not only the worst (0 when met)."""
        return sum(max(0.0, v) for clause in self.by_joint for v in clause.values())

    @property
    def met(self) -> bool:
        return all(c.met(v.value) for c, v in zip(self.spec.clauses, self.values, strict=True))

    @property
    def worst(self) -> float:
        """The largest normalised violation: ≤ 0 when every clause is met."""
        return max(self.violations)

    def closest(self) -> int:
        """Index of the clause closest to being met among those that are not (else the
        one with the smallest margin)."""
        failing = [k for k, c in enumerate(self.spec.clauses) if not c.met(self.values[k].value)]
        if failing:
            return min(failing, key=lambda k: self.violations[k])
        return max(range(len(self.violations)), key=lambda k: self.violations[k])

    def describe(self, k: int) -> str:
        c, m = self.spec.clauses[k], self.values[k]
        where = f" ({m.joint})" if m.joint else ""
        note = f" ({m.note})" if m.note else ""
        verdict = "met" if c.met(m.value) else "NOT met"
        value = fmt_value(m.value, c.unit)
        return f"{c.metric} {value}{where} {c.op} {c.bound:g}: {verdict}{note}"

    def text(self) -> str:
        return "; ".join(self.describe(k) for k in range(len(self.violations)))


def fmt_value(x: float, unit: str = "") -> str:
    """A measured value with its unit: "n/a" when not measured, "never" for a time that
    did not come within the run."""
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "never" if x > 0 else "-inf"
    return f"{x:.4g} {unit}" if unit else f"{x:.4g}"


def judge(spec: Spec, controller: Mapping[str, Any]) -> Judgement:
    """``spec`` judged on one controller's metrics (``RunResult.controller``).

    A settling or rise time that never came within the run is not met; its violation is
    that of the step's duration (a lower bound of the true time), so that the violation
    does not jump where a response settles just before the end."""
    measured = measure(spec, controller)
    steps = controller.get("steps") or []
    horizon = float(steps[0]["duration"]) if steps else math.inf
    values = tuple(measured[c.metric][c.op] for c in spec.clauses)

    def violation(c: Clause, value: float) -> float:
        return c.violation(min(value, horizon) if math.isinf(value) else value)

    pairs = list(zip(spec.clauses, values, strict=True))
    violations = tuple(violation(c, m.value) for c, m in pairs)
    by_joint = tuple(
        {j: violation(c, v) for j, v in m.per_joint.items() if not math.isnan(v)}
        or {"": VIOLATION_CAP}
        for c, m in pairs
    )
    return Judgement(spec, values, violations, by_joint)
