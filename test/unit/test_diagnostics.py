"""The /diagnostics status built from a loop summary (message classes only, no ROS graph)."""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from joint_space_control.ros.diagnostics import loop_status, parse_value, statuses, text
from joint_space_control.ros.loop_statistics import LoopStatistics, summary_keys

US = 1000


def summary_of(ticks: list[tuple[int, int, int, int]]) -> dict[str, float]:
    stats = LoopStatistics()
    for start, compute, latency, lateness in ticks:
        stats.tick(start * US, (start + compute) * US, latency * US, lateness * US, 1000 * US)
    return stats.summary((ticks[-1][0] + 1000) * US if ticks else 0)


def test_values_as_text_and_back():
    assert text(3) == "3" and text(1000.0) == "1000" and text(12.345678) == "12.3457"
    assert text(math.nan) == "nan" and text("lockstep") == "lockstep" and text(True) == "True"
    assert parse_value("12.3457") == 12.3457 and math.isnan(parse_value("nan"))
    assert parse_value("lockstep") == "lockstep"


def test_status_has_every_summary_key_then_the_extra_values():
    summary = summary_of([(k * 1000, 20, 300, 10) for k in range(10)])
    status = loop_status("sim_bridge: control loop", "iiwa", summary, {"mode": "realtime"})
    keys = [kv.key for kv in status.values]
    assert keys == summary_keys() + ["mode"]
    assert status.level == DiagnosticStatus.OK and status.hardware_id == "iiwa"
    assert "compute p99 20 us" in status.message and "latency p99 300 us" in status.message


def test_deadline_misses_warn():
    summary = summary_of([(0, 20, 300, 10), (1000, 20, 300, 1500), (2000, 20, 300, 10)])
    status = loop_status("x: control loop", "iiwa", summary, {})
    assert status.level == DiagnosticStatus.WARN
    assert "1 ticks more than 1 ms late" in status.message


def test_idle_window_is_ok_and_says_so():
    status = loop_status("x: control loop", "planar_2dof", summary_of([]), {})
    assert status.level == DiagnosticStatus.OK and status.message.startswith("idle")
    assert dict((kv.key, kv.value) for kv in status.values)["compute.p50_us"] == "nan"


def test_statuses_parse_a_diagnostic_array_by_name():
    summary = summary_of([(k * 1000, 20, 300, 10) for k in range(5)])
    msg = DiagnosticArray(
        status=[
            loop_status("a: control loop", "iiwa", summary, {"trigger": "state"}),
            loop_status("b: control loop", "iiwa", summary, {}),
        ]
    )
    parsed = statuses(msg)
    assert set(parsed) == {"a: control loop", "b: control loop"}
    a = parsed["a: control loop"]
    assert a["ticks"] == 5.0 and a["trigger"] == "state" and a["level"] == 0
    assert a["hardware_id"] == "iiwa" and a["compute.p50_us"] == 20.0


def test_an_alarm_is_an_error_first_in_the_message():
    summary = summary_of([(0, 20, 300, 10), (1000, 20, 300, 10)])
    status = loop_status("x: control loop", "iiwa", summary, {}, "brakes engaged")
    assert status.level == DiagnosticStatus.ERROR
    assert status.message.startswith("brakes engaged; ")
    assert loop_status("x", "iiwa", summary, {}, None).level == DiagnosticStatus.OK
