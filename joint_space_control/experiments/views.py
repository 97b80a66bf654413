"""What the theory checks see of a run, and what they say (shared by experiments/checks.py
and experiments/practice.py)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from joint_space_control.analysis.bag import ControllerState, JointStates
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot


@dataclass
class Outcome:
    check: str
    passed: bool | None
    text: str
    numbers: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunView:
    """What a check needs of one run (see runner.RunResult)."""

    label: str
    robot: str
    controller: dict  # the controller's metrics (metrics.json)
    events: list[dict]
    parameters: dict
    plant: dict = field(default_factory=dict)  # the run's sim_bridge parameters
    executable: str = ""  # the controller executable
    state: ControllerState | None = None  # its recorded ~/state, for signal checks
    truth: JointStates | None = None  # the plant's true state (imperfect measurement only)
    reference: dict = field(default_factory=dict)  # the scenario's reference


def joints(c: dict) -> list[str]:
    return list(c["joints"])


def vec(d: dict, names: Sequence[str]) -> np.ndarray:
    return np.array([math.nan if d.get(j) is None else d[j] for j in names], dtype=float)


def fmt(x: float | None) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.3g}"


def model(robot: str, **pert: Any) -> RobotModel:
    return RobotModel(resolve_robot(robot), perturbation=ModelPerturbation(**pert))
