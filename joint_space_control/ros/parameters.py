"""Parameters on a ROS node: the descriptors of the declarations, the values a node holds.

The declarations themselves and the checks of their values are ROS-free
(:mod:`joint_space_control.control.parameters`, re-exported here for the nodes); this module
turns a :class:`ParamSpec` into a ``ParameterDescriptor``, reads a node's values, and reads
the description of ``robot:=topic`` from the latched topic.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from joint_space_control.control import parameters as pure
from joint_space_control.control.parameters import (  # noqa: F401  (re-exported)
    LONGEST,
    REALTIME_PARAMETERS,
    REJECT_FACTOR,
    ROBOT_FROM_TOPIC,
    ROBOT_PARAMETERS,
    STEP_TOLERANCE,
    ParamSpec,
    ParamValues,
    defaults,
    names,
    numbers,
    value,
)
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import RobotSpec


def descriptor_range(spec: ParamSpec) -> dict[str, list[Any]]:
    """``floating_point_range`` (``integer_range`` for an int default) of the descriptor,
    for a number with both ends declared; empty otherwise."""
    if not spec.ranged or spec.type not in ("number", "numbers"):
        return {}
    if isinstance(spec.default, int) and not isinstance(spec.default, bool):
        ends = int(spec.minimum), int(spec.maximum), int(spec.step)
        return {
            "integer_range": [IntegerRange(from_value=ends[0], to_value=ends[1], step=ends[2])]
        }
    return {
        "floating_point_range": [
            FloatingPointRange(
                from_value=float(spec.minimum), to_value=float(spec.maximum), step=float(spec.step)
            )
        ]
    }


#: Parameters every node has besides its own (rclpy's).
_ROS_PARAMETERS = ("use_sim_time", "start_type_description_service")


def doubles(specs: Iterable[ParamSpec]) -> frozenset[str]:
    """The names of the parameters typed DOUBLE (one number with a float default)."""
    return frozenset(
        spec.name for spec in specs if spec.type == "number" and isinstance(spec.default, float)
    )


def as_declared(parameter: Parameter, double_names: frozenset[str]) -> Parameter:
    """``parameter`` with an integer value as the double a DOUBLE parameter holds: a params
    file's ``publish_rate: 250`` and ``ros2 param set ... publish_rate 250`` are typed
    INTEGER, which rclpy refuses for a DOUBLE parameter (a user writes 250, not 250.0)."""
    if parameter.name in double_names and parameter.type_ == Parameter.Type.INTEGER:
        return Parameter(parameter.name, Parameter.Type.DOUBLE, float(parameter.value))
    return parameter


def declare(node: Node, specs: Iterable[ParamSpec]) -> None:
    """Declare the node's parameters; a value given for a parameter the node does not have
    (a typo in a params file or a ``-p``: ROS ignores it silently) gets one WARN line. An
    integer given for a DOUBLE parameter, at start or at runtime, is taken as its double
    (:func:`as_declared`)."""
    specs = tuple(specs)
    double_names = doubles(specs)
    overrides = getattr(node, "_parameter_overrides", None)
    if overrides is not None:
        for name in double_names & set(overrides):
            overrides[name] = as_declared(overrides[name], double_names)
    node.add_pre_set_parameters_callback(
        lambda changes: [as_declared(p, double_names) for p in changes]
    )
    for spec in specs:
        node.declare_parameter(
            spec.name,
            spec.default,
            ParameterDescriptor(
                description=spec.description,
                additional_constraints=spec.constraints,
                read_only=spec.read_only,
                dynamic_typing=spec.dynamic or spec.type in ("numbers", "names"),
                **descriptor_range(spec),
            ),
        )
    unknown = unknown_overrides(getattr(node, "_parameter_overrides", {}), specs)
    if unknown:
        node.get_logger().warning(
            f"ignored parameter(s) {', '.join(unknown)}: {node.get_name()} has no such "
            "parameter (docs/parameters.md lists them)"
        )


def unknown_overrides(overrides: Iterable[str], specs: Iterable[ParamSpec]) -> list[str]:
    """The names among ``overrides`` (values given at start) that are none of ``specs``, of
    rclpy's own parameters or of its ``qos_overrides.``, in name order."""
    known = {spec.name for spec in specs} | set(_ROS_PARAMETERS)
    return sorted(
        name for name in overrides if name not in known and not name.startswith("qos_overrides.")
    )


def current_values(node: Node, specs: Iterable[ParamSpec]) -> ParamValues:
    specs = tuple(specs)
    return ParamValues(specs, {spec.name: node.get_parameter(spec.name).value for spec in specs})


def with_changes(node: Node, specs: Iterable[ParamSpec], changes: Iterable[Any]) -> ParamValues:
    """The values the node would have after a parameter update (not applied yet)."""
    values = current_values(node, specs)
    for p in changes:
        if p.name in values:
            values[p.name] = p.value
    return values


def robot_model(
    values: Mapping[str, Any],
    perturbation: Any = None,
    node: Node | None = None,
    description_topic: str = "robot_description",
) -> RobotModel:
    """:func:`joint_space_control.control.parameters.robot_model` on a node: its warnings
    logged by ``node``, which also reads ``description_topic`` for ``robot:=topic``."""
    model = pure.robot_model(values, perturbation, _topic_reader(node, description_topic))
    if node is not None:
        for warning in (*model.spec.warnings, *model.warnings):
            node.get_logger().warning(warning)
    return model


def robot_spec(
    values: Mapping[str, Any],
    node: Node | None = None,
    description_topic: str = "robot_description",
) -> RobotSpec:
    """:func:`joint_space_control.control.parameters.robot_spec`, ``robot:=topic`` read
    through ``node``."""
    return pure.robot_spec(values, _topic_reader(node, description_topic))


def _topic_reader(node: Node | None, topic: str) -> pure.DescriptionSource | None:
    if node is None:
        return None
    return lambda timeout: description_from_topic(node, timeout, topic)


def description_from_topic(node: Node, timeout: float, name: str = "robot_description") -> str:
    """The URDF text on the latched topic ``name`` (std_msgs/String, transient local, as
    robot_state_publisher publishes ``robot_description``)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.wait_for_message import wait_for_message
    from std_msgs.msg import String

    qos = QoSProfile(
        depth=1,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
        reliability=ReliabilityPolicy.RELIABLE,
    )
    topic = node.resolve_topic_name(name)
    node.get_logger().info(f"robot:=topic: waiting up to {timeout:g} s for {topic}")
    ok, msg = wait_for_message(String, node, name, qos_profile=qos, time_to_wait=timeout)
    if not ok or not msg.data:
        raise ValueError(
            f"no robot description on {topic} within {timeout:g} s (robot:=topic): start "
            "robot_state_publisher, or give 'robot_description', 'urdf_path' or 'robot'"
        )
    return msg.data
