"""Parameter declaration with descriptors, and conversion of raw values with reasons."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node

from joint_space_control.arrays import per_joint
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import RobotSpec, resolve_robot


@dataclass(frozen=True)
class ParamSpec:
    """One parameter, declared once: default, description, unit, range, shape, mutability.

    From it follow the ROS descriptor (:func:`declare`: read-only, dynamic typing, the
    numeric range and the constraints text), the validation of every value (:meth:`check`,
    through :func:`value`) and the documented defaults (tests/unit/test_parameter_docs.py).

    - numbers: ``minimum`` (with ``exclusive``: strictly above it), ``maximum`` (inclusive)
      and ``step`` (non-zero: the values lie on the grid minimum + k·step, to rclpy's
      relative tolerance 1e-6; only for integer-valued things such as counts); ``dynamic``
      numbers take one value or one per joint (``kp:=100`` or ``kp:=[100, 50]``). The range
      applies to each value of a per-joint list (or of a vector). With both a minimum and a
      maximum the descriptor carries it as ``floating_point_range`` (``integer_range`` for
      an int default), which rqt_reconfigure and the dashboard draw as a slider; rclpy
      enforces it on a single double (inclusive, so an exclusive minimum is left to
      :meth:`check`), never on an array: :meth:`check`, called by every node's on-set
      callback and at start, enforces all of it;
    - ``choices``: the allowed strings;
    - ``length``: a list of numbers with exactly this many values (a vector, say a force's
      3 components) instead of one value or one per joint;
    - ``kind`` is inferred from the default (bool, number, string) except for lists, where it
      must be ``"numbers"`` or ``"names"``.
    """

    name: str
    default: Any
    description: str
    read_only: bool = False
    dynamic: bool = False
    unit: str = ""
    minimum: float | None = None
    exclusive: bool = False
    maximum: float | None = None
    step: float = 0.0
    choices: tuple[str, ...] = ()
    kind: str = ""
    length: int = 0
    empty_ok: bool = False  # a list of numbers that may be empty (checked as an empty array)

    @property
    def type(self) -> str:
        """ "flag" | "number" | "numbers" | "text" | "names"."""
        if self.kind:
            return self.kind
        if isinstance(self.default, bool):
            return "flag"
        if isinstance(self.default, int | float):
            return "numbers" if self.dynamic else "number"
        if isinstance(self.default, str):
            return "text"
        raise TypeError(f"parameter '{self.name}': give kind='numbers' or 'names'")

    @property
    def bound(self) -> str:
        """The declared range in words ("> 0", ">= 1", ">= 0, <= 500", with its step
        ", step 1"), "" when there is none."""
        return ", ".join(self._bounds())

    def _bounds(self) -> list[str]:
        parts = []
        if self.minimum is not None:
            parts.append(f"{'>' if self.exclusive else '>='} {_number(self.minimum)}")
        if self.maximum is not None:
            parts.append(f"<= {_number(self.maximum)}")
        if self.step:
            parts.append(f"step {_number(self.step)}")
        return parts

    @property
    def ranged(self) -> bool:
        """Both ends declared: the descriptor carries the range (a slider's ends)."""
        return self.minimum is not None and self.maximum is not None

    def descriptor_range(self) -> dict[str, list[Any]]:
        """``floating_point_range`` (``integer_range`` for an int default) of the
        descriptor, for a number with both ends declared; empty otherwise."""
        if not self.ranged or self.type not in ("number", "numbers"):
            return {}
        if isinstance(self.default, int) and not isinstance(self.default, bool):
            ends = int(self.minimum), int(self.maximum), int(self.step)
            return {
                "integer_range": [IntegerRange(from_value=ends[0], to_value=ends[1], step=ends[2])]
            }
        return {
            "floating_point_range": [
                FloatingPointRange(
                    from_value=float(self.minimum),
                    to_value=float(self.maximum),
                    step=float(self.step),
                )
            ]
        }

    @property
    def constraints(self) -> str:
        """The declared range, shape and unit, in words (the descriptor's constraints)."""
        parts = []
        if self.choices:  # ROS has no field for them: generic tools read "one of: a | b"
            parts.append("one of: " + " | ".join(self.choices))
        if self.bound:
            parts.append(self.bound)
        if self.length:
            parts.append(f"{self.length} values")
        elif self.type == "numbers":
            parts.append("one value or one per joint")
        if self.unit:
            parts.append(f"[{self.unit}]")
        return ", ".join(parts)

    def check(self, value: Any, n: int | None = None) -> Any:
        """``value`` converted and checked against this declaration: a float, a per-joint
        array (with ``n``: broadcast to n joints; without: the list as given), a string, a
        bool or a tuple of names. Raises ValueError with the reason."""
        name, kind = self.name, self.type
        if kind == "flag":
            if not isinstance(value, bool):
                raise ValueError(f"'{name}' must be true or false, got {value!r}")
            return value
        if kind == "text":
            if not isinstance(value, str):
                raise ValueError(f"'{name}' must be a string, got {value!r}")
            if self.choices and value not in self.choices:
                raise ValueError(f"'{name}' is '{value}'; allowed: {', '.join(self.choices)}")
            return value
        if kind == "names":
            return names({name: value}, name)
        if kind == "number":
            bound = f" {self._range_text()}" if self.bound else ""
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"'{name}' must be a number{bound}, got {value!r}")
            if not math.isinf(value) and not self._within(np.array([value])):
                raise ValueError(f"'{name}' must be a number{bound}, got {value!r}")
            if not np.isfinite(value):
                raise ValueError(f"'{name}' must be finite")
            return float(value)
        if self.empty_ok and isinstance(value, list | tuple) and not value:
            return np.array([])
        items = numbers({name: value}, name)
        if self.length and len(items) != self.length:
            raise ValueError(f"'{name}' must have {self.length} values, got {len(items)}")
        arr = per_joint(items, n, name) if n is not None and not self.length else np.array(items)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"'{name}' must be finite, got {arr.tolist()}")
        if not self._within(arr):
            raise ValueError(f"'{name}' must be {self._range_text()}, got {arr.tolist()}")
        return arr

    def _range_text(self) -> str:
        """The range as a check's reason says it: ">= 0 and <= 10 (on a step of 1)"."""
        parts = self._bounds()
        step = f" on a step of {_number(self.step)}" if self.step else ""
        return " and ".join(parts[:-1] if self.step else parts) + step

    def _within(self, arr: np.ndarray) -> bool:
        """Every value in the range (NaN is not; it is refused as non-finite after)."""
        ok = True
        if self.minimum is not None:
            ok = bool(np.all(arr > self.minimum if self.exclusive else arr >= self.minimum))
        if ok and self.maximum is not None:
            ok = bool(np.all(arr <= self.maximum))
        if ok and self.step:
            ok = all(self._on_step(float(v)) for v in np.ravel(arr))
        return ok

    def _on_step(self, v: float) -> bool:
        """On the grid minimum + k·step, as rclpy judges a floating_point_range's step."""
        start = self.minimum or 0.0
        k = round((v - start) / self.step)
        return math.isclose(start + k * self.step, v, rel_tol=STEP_TOLERANCE)


def _number(x: float) -> str:
    """``x`` short (``%g``: 0.1, 1e+06) where that is exact, else with all its digits."""
    short = f"{x:g}"
    return short if float(short) == x else f"{x:.15g}"


#: Relative tolerance of a value on its step grid (rclpy's Node.PARAM_REL_TOL).
STEP_TOLERANCE = 1e-6


class ParamValues(dict):
    """Parameter values by name, with the declarations they are checked against."""

    def __init__(self, specs: Iterable[ParamSpec], items: Mapping[str, Any]) -> None:
        super().__init__(items)
        self.specs = {spec.name: spec for spec in specs}


def value(values: ParamValues, name: str, n: int | None = None) -> Any:
    """The value of ``name`` checked against its declaration (:meth:`ParamSpec.check`)."""
    return values.specs[name].check(values[name], n)


#: Parameters every node has besides its own (rclpy's).
_ROS_PARAMETERS = ("use_sim_time", "start_type_description_service")


def declare(node: Node, specs: Iterable[ParamSpec]) -> None:
    """Declare the node's parameters; a value given for a parameter the node does not have
    (a typo in a params file or a ``-p``: ROS ignores it silently) gets one WARN line."""
    specs = tuple(specs)
    for spec in specs:
        node.declare_parameter(
            spec.name,
            spec.default,
            ParameterDescriptor(
                description=spec.description,
                additional_constraints=spec.constraints,
                read_only=spec.read_only,
                dynamic_typing=spec.dynamic or spec.type in ("numbers", "names"),
                **spec.descriptor_range(),
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


#: [s] The upper end of a parameter that is a duration (a move, a pulse, a delay): one day,
#: generous; the end of its slider, not a limit any run comes near.
LONGEST = 86400.0

#: Torques beyond this multiple of the effort limits are faults (sim_bridge rejects such a
#: command; a controller counts such a computed torque, which it still clamps and sends).
REJECT_FACTOR = ParamSpec(
    "reject_factor",
    2.0,
    "A torque beyond this multiple of the effort limit is a fault: sim_bridge rejects the "
    "command (between the limit and the bound it is clamped), a controller counts it",
    minimum=1.0,
    maximum=100.0,
)

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
        kind="names",
    ),
    ParamSpec(
        "description_timeout",
        10.0,
        "robot:=topic: how long to wait for the robot_description topic",
        read_only=True,
        unit="s",
        minimum=0.0,
        exclusive=True,
        maximum=3600.0,
    ),
    ParamSpec(
        "joints",
        [],
        "Joints in the node's order (default: the robot's actuated joints)",
        read_only=True,
        kind="names",
    ),
    ParamSpec(
        "effort_limits",
        [],
        "Effort limits; override the URDF (needed where it says 0 or nothing); empty: the URDF's",
        read_only=True,
        kind="numbers",
        unit="N·m or N",
        minimum=0.0,
        exclusive=True,
        maximum=1e6,
    ),
)


def robot_model(
    values: Mapping[str, Any],
    perturbation: Any = None,
    node: Node | None = None,
    description_topic: str = "robot_description",
) -> RobotModel:
    """The model of the robot the parameters name, for the ``joints`` given, with its
    warnings logged by ``node`` (which also reads ``description_topic`` for
    ``robot:=topic``)."""
    spec = robot_spec(values, node, description_topic)
    limits = values["effort_limits"]
    model = RobotModel(
        spec,
        value(values, "joints") or None,
        perturbation,
        effort_limits=value(values, "effort_limits") if np.size(limits) else None,
    )
    if node is not None:
        for warning in (*spec.warnings, *model.warnings):
            node.get_logger().warning(warning)
    return model


def robot_spec(
    values: Mapping[str, Any],
    node: Node | None = None,
    description_topic: str = "robot_description",
) -> RobotSpec:
    """The description the robot parameters name (``robot_description``, else ``urdf_path``,
    else ``robot``; ``robot:=topic`` reads ``description_topic`` through ``node``)."""
    text = values["robot_description"]
    urdf = values["urdf_path"]
    robot = values["robot"] if not (text or urdf) else ""
    if robot == ROBOT_FROM_TOPIC:
        if node is None:
            raise ValueError("robot:=topic needs a node to read the robot_description topic")
        timeout = value(values, "description_timeout")
        text, robot = description_from_topic(node, timeout, description_topic), ""
    return resolve_robot(
        robot,
        urdf if not text else "",
        robot_description=text,
        xacro_args=value(values, "xacro_args"),
        package_paths=value(values, "package_paths"),
    )


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
