"""What ``jsc tune`` tunes for: one robot, one controller, a step response and a
specification. Pure: numbers, dictionaries and the scenario file's contents, no ROS.

Every trial is the same lockstep run with other gains: the robot starts at q0 and is given a
step to q0 + Δ on every joint at t = 0 (the reference ``{shape: step}`` of a scenario), for
``duration`` seconds of simulated time; its ``jsc analyze`` metrics are judged against the
specification (analysis/spec.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from joint_space_control.analysis.spec import Spec
from joint_space_control.workbench.experiments.scenarios.format import Scenario, parse

#: ``--controller`` → the controller's executable (and node name).
CONTROLLERS = {
    "pd_gravity": "pd_gravity_controller",
    "inverse_dynamics": "inverse_dynamics_controller",
}
#: ``--law`` sets this parameter of the controller, one of these values (the first: default).
LAW_PARAMETERS = {
    "pd_gravity_controller": ("gravity_compensation", ("full", "none", "desired")),
    "inverse_dynamics_controller": (
        "law",
        ("inverse_dynamics", "feedforward_pd", "precomputed_feedforward"),
    ),
}
#: THEORY.md §5 question each controller's design answers (1: PD + g(q), 6: inverse dynamics).
QUESTIONS = {"pd_gravity_controller": 1, "inverse_dynamics_controller": 6}

DEFAULT_STEP = 0.2  # [rad] per joint
DEFAULT_DURATION = 2.0  # [s] of simulated time per trial
#: The start stays this fraction of a joint's range inside its limits; a step is at most a
#: quarter of the range.
LIMIT_MARGIN = 0.1
MAX_STEP_FRACTION = 0.25


def step_inside_limits(
    lower: np.ndarray,
    upper: np.ndarray,
    step: float = DEFAULT_STEP,
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(q0, target) of the step response. q0 = ``start``, or 0 where that lies at least
    10 % of the range inside the limits (else the nearest such point); target = q0 + Δ with
    Δ = ``step`` (at most a quarter of the range: a gripper finger), downwards where upwards
    would leave that inner range. Unbounded (continuous) joints: 0 and ``step``. ValueError
    for a step ≤ 0 or a start outside the limits."""
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if not step > 0 or not np.isfinite(step):
        raise ValueError(f"the step must be a number > 0 [rad], got {step!r}")
    span = np.where(np.isfinite(upper - lower), upper - lower, 2 * np.pi)
    lo_in = np.where(np.isfinite(lower), lower + LIMIT_MARGIN * span, -np.inf)
    hi_in = np.where(np.isfinite(upper), upper - LIMIT_MARGIN * span, np.inf)
    if start is None:
        q0 = np.clip(0.0, lo_in, hi_in)
    else:
        q0 = np.asarray(start, dtype=float).reshape(-1)
        if q0.size != lower.size or not np.all(np.isfinite(q0)):
            raise ValueError(f"the start needs {lower.size} finite values, got {q0.tolist()}")
        if np.any(q0 < lower) or np.any(q0 > upper):
            raise ValueError(
                f"the start {q0.tolist()} is outside the joint limits "
                f"{lower.tolist()} .. {upper.tolist()}"
            )
    delta = np.minimum(step, MAX_STEP_FRACTION * span)
    delta = np.where(q0 + delta <= hi_in, delta, -delta)
    return q0, q0 + delta


@dataclass(frozen=True)
class TuneProblem:
    """One robot (``robot``: a built-in name or the URDF's stem; ``robot_parameters``: how
    the nodes load it), one controller executable with its ``law``, the step and the spec."""

    robot: str
    controller: str
    joints: tuple[str, ...]
    q0: np.ndarray
    target: np.ndarray
    duration: float
    spec: Spec
    law: str | None = None
    robot_parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def short_controller(self) -> str:
        return next(k for k, v in CONTROLLERS.items() if v == self.controller)

    def node_parameters(self, gains: dict[str, Any]) -> dict[str, Any]:
        """The controller's parameters of a trial: its robot, its law, the gains."""
        values: dict[str, Any] = dict(self.robot_parameters)
        if self.law is not None:
            values[LAW_PARAMETERS[self.controller][0]] = self.law
        values.update(gains)
        return values

    def scenario_data(self, gains: dict[str, Any], title: str = "", notes: str = "") -> dict:
        """The step-response scenario with ``gains`` (what ``scenario.parse`` takes and
        ``scenario.yaml`` holds), with a ``spec`` check judging the specification."""
        return {
            "title": title or f"Step response of {self.robot} under {self.controller}",
            "question": QUESTIONS[self.controller],
            "notes": notes,
            "robot": self.robot,
            "mode": "lockstep",
            "duration": float(self.duration),
            "short_duration": float(self.duration),
            "plant": {**self.robot_parameters, "initial_positions": _floats(self.q0)},
            "controller": self.controller,
            "parameters": self.node_parameters(gains),
            "reference": {"shape": "step", "target": _floats(self.target)},
            "checks": [{"check": "spec", "spec": str(self.spec)}],
        }

    def scenario(self, gains: dict[str, Any], name: str, path: Path) -> Scenario:
        """The trial's scenario, checked as a scenario file would be."""
        return parse(self.scenario_data(gains), name, path)


def _floats(x: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(x, dtype=float).reshape(-1)]
