"""Parameter declaration with descriptors, and conversion of raw values with reasons."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: default value, description (with units and range), mutability.

    ``dynamic`` parameters accept either one number or a list (``kp:=100`` or
    ``kp:=[100, 50]``); their range is checked by the node's validator.
    """

    name: str
    default: Any
    description: str
    read_only: bool = False
    dynamic: bool = False


def declare(node: Node, specs: Iterable[ParamSpec]) -> None:
    for spec in specs:
        node.declare_parameter(
            spec.name,
            spec.default,
            ParameterDescriptor(
                description=spec.description,
                read_only=spec.read_only,
                dynamic_typing=spec.dynamic,
            ),
        )


def current_values(node: Node, specs: Iterable[ParamSpec]) -> dict[str, Any]:
    return {spec.name: node.get_parameter(spec.name).value for spec in specs}


def with_changes(node: Node, specs: Iterable[ParamSpec], changes: Iterable[Any]) -> dict[str, Any]:
    """The values the node would have after a parameter update (not applied yet)."""
    values = current_values(node, specs)
    for p in changes:
        if p.name in values:
            values[p.name] = p.value
    return values


def numbers(values: Mapping[str, Any], name: str) -> list[float]:
    """A number or a list of numbers (no booleans, no strings) as a list of floats."""
    value = values[name]
    items = list(value) if isinstance(value, list | tuple) or hasattr(value, "tolist") else [value]
    if isinstance(value, bytes | str) or any(
        isinstance(v, bool | str | bytes) or not isinstance(v, int | float | np.number)
        for v in items
    ):
        raise ValueError(f"'{name}' must be a number or a list of numbers, got {value!r}")
    if not items:
        raise ValueError(f"'{name}' is empty")
    return [float(v) for v in items]


def names(values: Mapping[str, Any], name: str) -> tuple[str, ...]:
    """A list of strings; an empty list (any array type) means 'use the default'."""
    value = values[name]
    items = list(value) if value is not None else []
    if any(not isinstance(v, str) for v in items):
        raise ValueError(f"'{name}' must be a list of names, got {value!r}")
    return tuple(items)


def choice(values: Mapping[str, Any], name: str, allowed: Iterable[str]) -> str:
    allowed = tuple(allowed)
    value = values[name]
    if value not in allowed:
        raise ValueError(f"'{name}' is '{value}'; allowed: {', '.join(allowed)}")
    return value


def positive(values: Mapping[str, Any], name: str) -> float:
    value = values[name]
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise ValueError(f"'{name}' must be a number > 0, got {value!r}")
    if not np.isfinite(value):
        raise ValueError(f"'{name}' must be finite")
    return float(value)


def nonnegative_number(values: Mapping[str, Any], name: str) -> float:
    value = values[name]
    if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
        raise ValueError(f"'{name}' must be a number >= 0, got {value!r}")
    if not np.isfinite(value):
        raise ValueError(f"'{name}' must be finite")
    return float(value)


#: What every node takes to know its robot (INTERFACES.md): a built-in robot or any URDF, and
#: the joints in the node's order.
ROBOT_PARAMETERS = (
    ParamSpec(
        "robot", "planar_2dof", "Built-in robot: planar_2dof | iiwa | panda", read_only=True
    ),
    ParamSpec("urdf_path", "", "Any URDF file (instead of 'robot')", read_only=True),
    ParamSpec(
        "joints",
        [],
        "Joints in the node's order (default: the robot's actuated joints)",
        read_only=True,
        dynamic=True,
    ),
)


def robot_model(values: Mapping[str, Any], perturbation: Any = None) -> RobotModel:
    """The model of the robot named by ``robot``/``urdf_path``, for the ``joints`` given."""
    urdf = values["urdf_path"]
    spec = resolve_robot(values["robot"] if not urdf else "", urdf)
    return RobotModel(spec, names(values, "joints") or None, perturbation)
