"""What the theory checks see of a run (:class:`RunView`), and what they say of it
(:class:`Outcome`): shared by the §5 checks (judging/theory.py) and the §4 ones
(judging/practical.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from joint_space_control.analysis.bag import ControllerState, JointStates
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.workbench.experiments.execution import values


@dataclass
class Outcome:
    """One check's verdict: ``passed`` True or False where the theory makes a claim, None
    where it does not; ``text`` the measured numbers beside the prediction and the tolerance,
    as the summary prints them; ``numbers`` what an experiment's figures draw, so that what
    is drawn is what was checked."""

    check: str
    passed: bool | None
    text: str
    numbers: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunView:
    """What a check needs of one run (see execution.runner.RunResult). ``parameters`` and
    ``plant`` are the values the nodes ran with: the scenario's over the declared defaults
    (:mod:`~joint_space_control.workbench.experiments.execution.values`), so a check reads
    ``r.parameters["rate"]`` and never types a default of its own."""

    label: str
    robot: str
    controller: dict  # the controller's metrics (metrics.json)
    events: list[dict]
    parameters: dict  # the controller's parameter values
    plant: dict = field(default_factory=dict)  # the run's sim_bridge parameter values
    executable: str = ""  # the controller executable
    state: ControllerState | None = None  # its recorded ~/state, for signal checks
    truth: JointStates | None = None  # the plant's true state (imperfect measurement only)
    reference: dict = field(default_factory=dict)  # the scenario's reference

    def __post_init__(self) -> None:
        self.given = dict(self.parameters)  # the scenario's own, for the models
        self.plant_given = dict(self.plant)
        if self.executable:
            self.parameters = values.controller_values(self.executable, self.robot, self.given)
        self.plant = values.plant_values(self.robot, self.plant_given)

    def plant_model(self, payload: bool = False) -> RobotModel:
        """The plant's robot in Pinocchio (with the plant's ``payload_mass`` if ``payload``)."""
        return values.plant_model(self.robot, self.plant_given, payload)

    def controller_model(self) -> RobotModel:
        """The controller's own model B̂, ĝ, as its node builds it."""
        return values.controller_model(self.executable, self.robot, self.given)


def verdict_word(passed: bool | None) -> str:
    """How a page says a check's verdict."""
    return {True: "agrees", False: "DISAGREES", None: "no claim"}[passed]


def joints(c: dict) -> list[str]:
    return list(c["joints"])


def vec(d: dict, names: Sequence[str]) -> np.ndarray:
    return np.array([math.nan if d.get(j) is None else d[j] for j in names], dtype=float)


def fmt(x: float | None) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.3g}"
