"""Parameter declarations and the values checked against them: no ROS.

A :class:`ParamSpec` is written once, here or beside the thing it configures (a controller's
law, the plant), and everything follows from it: the ROS descriptor a node declares
(:mod:`joint_space_control.ros.parameters`), the check of every value (:func:`value`), the
documented defaults, and the configuration the experiments, the bench and the tests build
without a node (:mod:`joint_space_control.control.configure`). The robot parameters every
node takes (:data:`ROBOT_PARAMETERS`) give the robot's model through :func:`robot_model`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from joint_space_control import scheduling
from joint_space_control.arrays import per_joint
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import RobotSpec, resolve_robot


@dataclass(frozen=True)
class ParamSpec:
    """One parameter, declared once: default, description, unit, range, shape, mutability.

    From it follow the ROS descriptor (:func:`joint_space_control.ros.parameters.declare`:
    read-only, dynamic typing, the numeric range and the constraints text), the validation
    of every value (:meth:`check`, through :func:`value`) and the documented defaults
    (test/unit/test_parameter_docs.py).

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


#: A node's realtime threads (joint_space_control.ros.realtime_threads).
REALTIME_PARAMETERS = (
    ParamSpec(
        "thread_priority",
        50,
        "SCHED_FIFO priority (1-99) of the realtime threads when the system permits it "
        "(else one warning and normal scheduling); 0: normal scheduling",
        read_only=True,
        minimum=0.0,
        maximum=float(scheduling.MAX_PRIORITY),
        step=1.0,
    ),
    ParamSpec(
        "middleware_priority",
        -1,
        "SCHED_FIFO priority (1-99) of the middleware threads that deliver the node's "
        "messages (Fast DDS's reception and event threads); -1: one below thread_priority "
        "(normal scheduling when thread_priority is 0); 0: normal scheduling",
        read_only=True,
        minimum=-1.0,
        maximum=float(scheduling.MAX_PRIORITY),
        step=1.0,
    ),
    ParamSpec(
        "cpu_affinity",
        [],
        "CPUs the realtime threads may run on (empty: any the process may use)",
        read_only=True,
        kind="numbers",
        empty_ok=True,
    ),
    ParamSpec(
        "lock_memory",
        False,
        "Lock the process's memory, present and future, in RAM (mlockall)",
        read_only=True,
    ),
)


#: Reads the URDF text of ``robot:=topic`` (the ROS layer gives one: a node that waits for the
#: latched topic); its argument is ``description_timeout`` [s].
DescriptionSource = Callable[[float], str]


def robot_spec(
    values: Mapping[str, Any], description: DescriptionSource | None = None
) -> RobotSpec:
    """The description the robot parameters name (``robot_description``, else ``urdf_path``,
    else ``robot``; ``robot:=topic`` reads it through ``description``)."""
    text = values["robot_description"]
    urdf = values["urdf_path"]
    robot = values["robot"] if not (text or urdf) else ""
    if robot == ROBOT_FROM_TOPIC:
        if description is None:
            raise ValueError("robot:=topic needs a node to read the robot_description topic")
        text, robot = description(value(values, "description_timeout")), ""
    return resolve_robot(
        robot,
        urdf if not text else "",
        robot_description=text,
        xacro_args=value(values, "xacro_args"),
        package_paths=value(values, "package_paths"),
    )


def robot_model(
    values: Mapping[str, Any],
    perturbation: Any = None,
    description: DescriptionSource | None = None,
) -> RobotModel:
    """The model of the robot the parameters name, for the ``joints`` given (its warnings,
    and its description's, in ``model.spec.warnings`` and ``model.warnings``)."""
    spec = robot_spec(values, description)
    limits = values["effort_limits"]
    return RobotModel(
        spec,
        value(values, "joints") or None,
        perturbation,
        effort_limits=value(values, "effort_limits") if np.size(limits) else None,
    )


def refused_at_run_time(specs: Mapping[str, ParamSpec], names: Iterable[str]) -> list[str]:
    """Why each of ``names`` cannot be set while a node runs, as rclpy refuses it: no such
    parameter, or read-only (``name: reason``; empty when all can be set)."""
    return [
        f"{name}: " + ("no such parameter" if name not in specs else "read-only")
        for name in names
        if name not in specs or specs[name].read_only
    ]


def defaults(specs: Iterable[ParamSpec], **given: Any) -> ParamValues:
    """The values of ``specs``: their defaults, with ``given`` over them (a name that is
    none of them is a ValueError naming it: a typo must not pass silently)."""
    specs = tuple(specs)
    values = {spec.name: spec.default for spec in specs}
    unknown = sorted(set(given) - set(values))
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}")
    return ParamValues(specs, {**values, **given})
