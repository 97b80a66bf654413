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


#: ``robot:=topic`` reads the description from the latched ``robot_description`` topic.
ROBOT_FROM_TOPIC = "topic"

#: What every node takes to know its robot (INTERFACES.md): URDF text, a URDF/xacro file or a
#: built-in robot (in that order of precedence), and the joints in the node's order.
ROBOT_PARAMETERS = (
    ParamSpec(
        "robot",
        "planar_2dof",
        "Built-in robot: planar_2dof | iiwa | panda; 'topic': the description published on "
        "the latched robot_description topic (robot_state_publisher)",
        read_only=True,
    ),
    ParamSpec("urdf_path", "", "A .urdf or .xacro file (wins over 'robot')", read_only=True),
    ParamSpec(
        "robot_description",
        "",
        "The URDF text itself, as robot_state_publisher takes it (wins over 'urdf_path')",
        read_only=True,
    ),
    ParamSpec("xacro_args", "", "xacro arguments 'name:=value name2:=value2'", read_only=True),
    ParamSpec(
        "package_paths",
        [],
        "Extra folders for package:// URIs (a package folder or a folder of packages), "
        "searched after the ament index and ROS_PACKAGE_PATH",
        read_only=True,
        dynamic=True,
    ),
    ParamSpec(
        "description_timeout",
        10.0,
        "robot:=topic: how long to wait for the robot_description topic [s], > 0",
        read_only=True,
    ),
    ParamSpec(
        "joints",
        [],
        "Joints in the node's order (default: the robot's actuated joints)",
        read_only=True,
        dynamic=True,
    ),
    ParamSpec(
        "effort_limits",
        [],
        "Effort limits [N·m or N], one value or one per joint, > 0; overrides the URDF "
        "(needed where it says 0 or nothing); empty: the URDF's",
        read_only=True,
        dynamic=True,
    ),
)


def robot_model(
    values: Mapping[str, Any], perturbation: Any = None, node: Node | None = None
) -> RobotModel:
    """The model of the robot the parameters name, for the ``joints`` given, with its
    warnings logged by ``node`` (which also reads the ``robot_description`` topic for
    ``robot:=topic``)."""
    text = values["robot_description"]
    urdf = values["urdf_path"]
    robot = values["robot"] if not (text or urdf) else ""
    if robot == ROBOT_FROM_TOPIC:
        if node is None:
            raise ValueError("robot:=topic needs a node to read the robot_description topic")
        text, robot = description_from_topic(node, positive(values, "description_timeout")), ""
    if not isinstance(values["xacro_args"], str):
        raise ValueError(f"'xacro_args' must be a string, got {values['xacro_args']!r}")
    spec = resolve_robot(
        robot,
        urdf if not text else "",
        robot_description=text,
        xacro_args=values["xacro_args"],
        package_paths=names(values, "package_paths"),
    )
    limits = values["effort_limits"]
    model = RobotModel(
        spec,
        names(values, "joints") or None,
        perturbation,
        effort_limits=numbers(values, "effort_limits") if np.size(limits) else None,
    )
    if node is not None:
        for warning in (*spec.warnings, *model.warnings):
            node.get_logger().warning(warning)
    return model


def description_from_topic(node: Node, timeout: float) -> str:
    """The URDF text on the latched ``robot_description`` topic (std_msgs/String, transient
    local, as robot_state_publisher publishes it)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.wait_for_message import wait_for_message
    from std_msgs.msg import String

    qos = QoSProfile(
        depth=1,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
        reliability=ReliabilityPolicy.RELIABLE,
    )
    topic = node.resolve_topic_name("robot_description")
    node.get_logger().info(f"robot:=topic: waiting up to {timeout:g} s for {topic}")
    ok, msg = wait_for_message(
        String, node, "robot_description", qos_profile=qos, time_to_wait=timeout
    )
    if not ok or not msg.data:
        raise ValueError(
            f"no robot description on {topic} within {timeout:g} s (robot:=topic): start "
            "robot_state_publisher, or give 'robot_description', 'urdf_path' or 'robot'"
        )
    return msg.data
