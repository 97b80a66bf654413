"""A run's parameter values as its nodes hold them: the declared defaults with the scenario's
values over them, and the models they give (no ROS, no default typed twice).

The checks, the boundaries and the in-process engine read a run's settings through these, so
that ``r.parameters["velocity_cutoff"]`` is the value the controller ran with whether or not
the scenario gave it, and the controller's model is built by
:meth:`~joint_space_control.control.configure.ControllerKind.model`, as its node builds it
(``urdf_path``, ``joints``, ``effort_limits`` and the ``model_*`` perturbations included).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from typing import Any

from joint_space_control.control import parameters as params
from joint_space_control.control.configure import controller_kind
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from sim_bridge.parameters import PARAMETERS as PLANT_PARAMETERS


def controller_values(executable: str, robot: str, given: Mapping[str, Any]) -> params.ParamValues:
    """The controller's values: its defaults, ``robot``, then the scenario's ``parameters``
    (a name the controller does not have is a ValueError naming it)."""
    return controller_kind(executable).values(**{"robot": robot, **given})


def plant_values(robot: str, given: Mapping[str, Any]) -> params.ParamValues:
    """sim_bridge's values for one robot: its defaults, ``robot``, then the scenario's
    ``plant`` (of a world, the world's and the robot's own, merged: Scenario.of_robot)."""
    known = {spec.name for spec in PLANT_PARAMETERS}
    return params.defaults(
        PLANT_PARAMETERS, **{"robot": robot, **{k: v for k, v in given.items() if k in known}}
    )


def _key(given: Mapping[str, Any]) -> str:
    return json.dumps(dict(given), sort_keys=True, default=lambda x: list(x))


def controller_model(executable: str, robot: str, given: Mapping[str, Any]) -> RobotModel:
    """The controller's own model B̂, Ĉ, ĝ, as its node builds it from its parameters."""
    return _controller_model(executable, robot, _key(given))


@functools.lru_cache(maxsize=64)
def _controller_model(executable: str, robot: str, key: str) -> RobotModel:
    values = controller_values(executable, robot, json.loads(key))
    return controller_kind(executable).model(values)


def plant_model(robot: str, given: Mapping[str, Any], payload: bool = False) -> RobotModel:
    """The plant's robot as Pinocchio models it (the description sim_bridge loads, its
    ``joints``), carrying the plant's ``payload_mass`` when ``payload``."""
    return _plant_model(robot, _key(given), payload)


@functools.lru_cache(maxsize=64)
def _plant_model(robot: str, key: str, payload: bool) -> RobotModel:
    values = plant_values(robot, json.loads(key))
    mass = params.value(values, "payload_mass") if payload else 0.0
    return params.robot_model(values, ModelPerturbation(payload_mass=mass))
