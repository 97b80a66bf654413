"""Loop statistics on ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), once a second.

One DiagnosticStatus per node: ``name`` "<node>: control loop", ``hardware_id`` the robot,
``values`` every key of :func:`~joint_space_control.ros.loop_statistics.summary_keys`
(numbers as text, ``nan`` where nothing was measured) followed by the node's own keys. The
level is ERROR while the node reports an alarm (a controller not commanding for lack of
joint states, a plant braking for lack of commands), WARN while ticks miss their deadline
by more than 1 ms (paced loops), else OK.
The timer runs on the steady clock, so diagnostics keep coming in simulation time, paused
or not, and the summary work happens in the executor thread, off the control path.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from joint_space_control.ros.loop_statistics import LoopStatistics

DIAGNOSTICS_TOPIC = "/diagnostics"
DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: Publishing period [s] (wall time).
PERIOD = 1.0


def text(value: Any) -> str:
    """A KeyValue value: integers as they are, floats with 4 decimals, NaN as ``nan``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    if isinstance(value, int) or float(value).is_integer():
        return str(int(value))
    return "nan" if math.isnan(value) else f"{value:.4f}"


def loop_status(
    name: str,
    hardware_id: str,
    summary: Mapping[str, float],
    extra: Mapping[str, Any],
    alarm: str | None = None,
) -> DiagnosticStatus:
    """The DiagnosticStatus of one loop from a :meth:`LoopStatistics.summary`; an ``alarm``
    makes it an ERROR with the alarm first in the message."""
    if summary["ticks"] == 0:
        level, message = DiagnosticStatus.OK, "idle (no tick in the last window)"
    else:
        level = DiagnosticStatus.WARN if summary["too_late"] else DiagnosticStatus.OK
        message = (
            f"{summary['rate_hz']:.0f} Hz, compute p99 {summary['compute.p99_us']:.0f} us, "
            f"latency p99 {summary['latency.p99_us']:.0f} us"
        )
        if summary["too_late"]:
            message += f", {int(summary['too_late'])} ticks more than 1 ms late"
    if alarm:
        level, message = DiagnosticStatus.ERROR, f"{alarm}; {message}"
    values = [KeyValue(key=k, value=text(v)) for k, v in summary.items()]
    values += [KeyValue(key=k, value=text(v)) for k, v in extra.items()]
    return DiagnosticStatus(
        level=level, name=name, message=message, hardware_id=hardware_id, values=values
    )


class LoopDiagnostics:
    """Publishes the summary of ``stats`` on /diagnostics every :data:`PERIOD` seconds, with
    the node's own values ``extra(summary)`` after the statistics and the level raised to
    ERROR while ``alarm()`` gives a reason."""

    def __init__(
        self,
        node: Node,
        stats: LoopStatistics,
        hardware_id: str,
        extra: Callable[[Mapping[str, float]], Mapping[str, Any]] = lambda summary: {},
        alarm: Callable[[], str | None] = lambda: None,
    ) -> None:
        self._node = node
        self._stats = stats
        self._name = f"{node.get_fully_qualified_name().lstrip('/')}: control loop"
        self._hardware_id = hardware_id
        self._extra = extra
        self._alarm = alarm
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self._timer = node.create_timer(
            PERIOD, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME)
        )

    def publish(self) -> None:
        summary = self._stats.summary(time.perf_counter_ns())
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status = [
            loop_status(
                self._name, self._hardware_id, summary, self._extra(summary), self._alarm()
            )
        ]
        self._pub.publish(msg)


def parse_value(value: str) -> float | str:
    """A KeyValue value back to a number where it is one (``nan`` included)."""
    try:
        return float(value)
    except ValueError:
        return value


def statuses(msg: DiagnosticArray) -> dict[str, dict[str, float | str]]:
    """Each status of a DiagnosticArray by name: its values (numbers parsed), with the level,
    message and hardware id under ``level``, ``message`` and ``hardware_id``."""
    return {
        status.name: {
            "level": int.from_bytes(status.level, "little")
            if isinstance(status.level, bytes)
            else int(status.level),
            "message": status.message,
            "hardware_id": status.hardware_id,
            **{kv.key: parse_value(kv.value) for kv in status.values},
        }
        for status in msg.status
    }
