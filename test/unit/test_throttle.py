"""Throttled log lines (issue 17): one line a second per kind, the count of those held back in
the next one, nothing built while held back. A fake clock drives them: no test waits."""

from __future__ import annotations

import ast
from pathlib import Path

from joint_space_control import throttle
from joint_space_control.throttle import Throttle, ThrottledLog


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Lines:
    """A logger that keeps (level, line)."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def info(self, message: str) -> None:
        self.lines.append(("info", message))

    def warning(self, message: str) -> None:
        self.lines.append(("warning", message))

    def error(self, message: str) -> None:
        self.lines.append(("error", message))


def test_first_occurrence_said_at_once_then_one_per_period_with_the_exact_count():
    clock = FakeClock()
    gate = Throttle(1.0, clock)
    said = []
    for k in range(5000):  # 5 s at 1 kHz
        clock.now = 100.0 + k * 0.001
        held = gate.due("rejected joint state")
        if held is not None:
            said.append((k, held))
    # at t = 0, 1, 2, 3, 4 s: each line after the first reports the 999 held back before it
    assert said == [(0, 0), (1000, 999), (2000, 999), (3000, 999), (4000, 999)]


def test_kinds_are_independent():
    clock = FakeClock()
    gate = Throttle(1.0, clock)
    assert gate.due("a") == 0
    assert gate.due("b") == 0  # another kind: said at once
    for _ in range(7):
        assert gate.due("a") is None
    for _ in range(3):
        assert gate.due("b") is None
    clock.now += 0.5
    assert gate.due("a") is None
    clock.now += 0.5  # one period after the first lines
    assert gate.due("b") == 3
    assert gate.due("a") == 8
    assert gate.due("c") == 0


def test_the_period_runs_from_the_last_line_said():
    clock = FakeClock()
    gate = Throttle(1.0, clock)
    assert gate.due("x") == 0
    clock.now += 5.0  # quiet for a while: said at once, nothing held back
    assert gate.due("x") == 0
    clock.now += 0.999
    assert gate.due("x") is None
    clock.now += 0.001
    assert gate.due("x") == 1


def test_the_log_says_the_held_back_count_and_builds_no_text_while_holding_back():
    clock = FakeClock()
    lines = Lines()
    log = ThrottledLog(lines, 1.0, clock)
    built = []

    def text(detail: str):
        def build() -> str:
            built.append(detail)
            return f"rejected joint state: {detail}"

        return build

    class Unformattable:
        def __format__(self, spec: str) -> str:
            raise AssertionError("formatted while held back")

    assert log.warning("rejected joint state", text("missing joints ['joint2']"))
    for _ in range(37):
        assert not log.warning("rejected joint state", text("never built"))
    assert log.error("non-finite torque", "non-finite torque")  # a plain str
    assert not log.error("non-finite torque", "{} at t={:.4f} s", Unformattable(), 1.0)
    clock.now += 1.0
    assert log.warning("rejected joint state", text("missing joints ['joint2']"))
    assert log.error("non-finite torque", "torque {} at t={:.4f} s", [1e400], 2.0)
    assert log.info("gains", "gains {designed}")  # no arguments: not a format string
    assert built == ["missing joints ['joint2']"] * 2
    first = "rejected joint state: missing joints ['joint2']"
    assert lines.lines == [
        ("warning", first),
        ("error", "non-finite torque"),
        ("warning", first + " (37 more since the last report)"),
        ("error", "torque [inf] at t=2.0000 s (1 more since the last report)"),
        ("info", "gains {designed}"),
    ]


def test_an_rclpy_logger_takes_every_severity():
    """rclpy's logger refuses two severities from one call site (ValueError)."""
    from rclpy.logging import get_logger

    log = ThrottledLog(get_logger("test_throttle"))
    for k in range(2):
        assert log.info(("info", k), "info {}", k)
        assert log.warning(("warning", k), "warning {}", k)
        assert log.error(("error", k), "error {}", k)


def test_no_ros_import():
    tree = ast.parse(Path(throttle.__file__).read_text())
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert not [n for n in names if n.split(".")[0] in ("rclpy", "rcl_interfaces")]
