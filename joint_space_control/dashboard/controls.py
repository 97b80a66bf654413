"""A parameter's descriptor → the control a generic page draws for it.

Built only from what any ROS 2 node publishes about its parameters (the
``rcl_interfaces/ParameterDescriptor`` the ``describe_parameters`` service answers, and the
current value), so the page works for every node, ours or not:

- a read-only parameter is shown, not editable;
- ``bool`` → a checkbox; ``string`` → a dropdown when the descriptor names its choices
  (``one of: a | b | c`` in ``additional_constraints``, as :class:`ParamSpec` writes it; ROS
  has no field for them), else a text box;
- ``double`` / ``integer`` → a slider within ``floating_point_range`` / ``integer_range``
  (from, to, step) when the descriptor has one, else a number box;
- a list of numbers, or a dynamically typed number (this package's "one value or one per
  joint"), → one control per value, labelled with the joint names when there is one value
  per joint; the range applies to each value;
- other lists (names, booleans, bytes) are shown only (:data:`NOT_EDITABLE` says why).

No ROS import: the descriptor is read by attribute, so a message or any object with the
same fields will do.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

# rcl_interfaces/msg/ParameterType
BOOL, INTEGER, DOUBLE, STRING = 1, 2, 3, 4
BYTE_ARRAY, BOOL_ARRAY, INTEGER_ARRAY, DOUBLE_ARRAY, STRING_ARRAY = 5, 6, 7, 8, 9

#: Parameter types the page shows but offers no control for, with the reason.
NOT_EDITABLE = {
    BYTE_ARRAY: "a byte array has no meaningful control",
    BOOL_ARRAY: "a list of booleans: no control (none of this package's parameters is one)",
    STRING_ARRAY: "a list of names: edit it with ros2 param set",
}

_CHOICES = re.compile(r"one of: ([^,;\[\]]+)")


#: The coarsest step of a continuous parameter's control [its unit]: typed values keep their
#: first two decimals.
TYPED_PRECISION = 0.01


@dataclass(frozen=True)
class Control:
    """What the page draws for one parameter.

    ``kind``: "slider" | "number" | "dropdown" | "checkbox" | "text" | "shown";
    ``elements``: labels of the values of a per-value control (one control each), () for a
    single value; ``minimum``/``maximum``/``step``: the declared range (None: none declared;
    step 0: continuous); ``integer``: values are sent as integers.
    """

    name: str
    kind: str
    hint: str = ""
    read_only: bool = False
    minimum: float | None = None
    maximum: float | None = None
    step: float = 0.0
    integer: bool = False
    options: tuple[str, ...] = ()
    elements: tuple[str, ...] = ()
    why_not: str = ""

    @property
    def label(self) -> str:
        return self.name

    def ui_step(self) -> float:
        """The step of the page's slider and number box, which round what is typed to it:
        the declared one; for a continuous parameter, a hundred-thousandth of its range
        (one significant digit) and at most :data:`TYPED_PRECISION`, so that a value typed
        with two decimals (ω_n = 12.5) reaches the node as typed."""
        if self.step:
            return self.step
        if self.integer:
            return 1.0
        if self.minimum is None or self.maximum is None or self.maximum <= self.minimum:
            return 0.001
        raw = (self.maximum - self.minimum) / 1e5
        return min(10.0 ** math.floor(math.log10(raw)), TYPED_PRECISION)

    def element_values(self, value: Any) -> list[Any]:
        """The current value as one item per element (a single value broadcast)."""
        items = list(value) if isinstance(value, list | tuple) else [value]
        if len(items) == 1 and len(self.elements) > 1:
            items = items * len(self.elements)
        return items

    def parameter_value(self, items: Sequence[Any]) -> Any:
        """The value to send for the page's items (one per element, or one)."""
        cast = int if self.integer else float
        if self.kind in ("slider", "number"):
            values = [cast(v) for v in items]
            return values if self.elements else values[0]
        return items[0]


def choices(constraints: str) -> tuple[str, ...]:
    """The allowed strings named in a descriptor's ``additional_constraints``
    (``one of: a | b | c``), () when it names none."""
    match = _CHOICES.search(constraints or "")
    if not match:
        return ()
    return tuple(c.strip() for c in match.group(1).split("|") if c.strip())


def _range(descriptor: Any, integer: bool) -> tuple[float | None, float | None, float]:
    ranges = getattr(descriptor, "integer_range" if integer else "floating_point_range", None)
    if not ranges:
        return None, None, 0.0
    r = ranges[0]
    lo, hi = sorted((float(r.from_value), float(r.to_value)))
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None, None, float(r.step)
    return lo, hi, float(r.step)


def value_type(value: Any) -> int:
    """The ParameterType of a Python value as rclpy gives it."""
    if isinstance(value, bool):
        return BOOL
    if isinstance(value, int):
        return INTEGER
    if isinstance(value, float):
        return DOUBLE
    if isinstance(value, str):
        return STRING
    if isinstance(value, bytes):
        return BYTE_ARRAY
    items = list(value)
    if not items:
        return DOUBLE_ARRAY
    if all(isinstance(v, bool) for v in items):
        return BOOL_ARRAY
    if all(isinstance(v, int) and not isinstance(v, bool) for v in items):
        return INTEGER_ARRAY
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in items):
        return DOUBLE_ARRAY
    return STRING_ARRAY


def control_for(descriptor: Any, value: Any, joints: Sequence[str] = ()) -> Control:
    """The control for a parameter with ``descriptor`` and current ``value``; ``joints``
    are the robot's joint names (per-joint lists are labelled with them)."""
    name = descriptor.name
    kind = value_type(value)
    hint = "; ".join(t for t in (descriptor.description, descriptor.additional_constraints) if t)
    read_only = bool(descriptor.read_only)
    common = {"name": name, "hint": hint, "read_only": read_only}
    if kind in NOT_EDITABLE:
        return Control(kind="shown", why_not=NOT_EDITABLE[kind], **common)
    if read_only:
        return Control(kind="shown", why_not="read-only", **common)
    if kind == BOOL:
        return Control(kind="checkbox", **common)
    if kind == STRING:
        options = choices(descriptor.additional_constraints)
        if options and value in options:
            return Control(kind="dropdown", options=options, **common)
        return Control(kind="text", **common)
    # a dynamically typed number given as an integer (kp:=100) is still a real number
    integer = kind in (INTEGER, INTEGER_ARRAY) and not descriptor.dynamic_typing
    lo, hi, step = _range(descriptor, integer)
    number_kind = "slider" if lo is not None else "number"
    elements: tuple[str, ...] = ()
    if kind in (INTEGER_ARRAY, DOUBLE_ARRAY):
        n = len(value)
        if n == 0:
            return Control(kind="shown", why_not="an empty list: no value to edit", **common)
        elements = tuple(joints) if n == len(joints) else tuple(str(i) for i in range(n))
    elif descriptor.dynamic_typing and len(joints) > 1:
        elements = tuple(joints)  # one value or one per joint: offer one per joint
    return Control(
        kind=number_kind,
        minimum=lo,
        maximum=hi,
        step=step,
        integer=integer,
        elements=elements,
        **common,
    )
