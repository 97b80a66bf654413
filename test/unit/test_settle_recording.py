"""ClosedLoop.settle_recording's decision, on the recorder's counts as ``~/flush`` answers
them (no processes: the loop's probe and recorder are stand-ins with fixed counts)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from joint_space_control.processes import loop as loop_module
from joint_space_control.processes.loop import ClosedLoop
from joint_space_control.processes.probe import Recording
from joint_space_control.workbench.experiments.scenarios.format import RobotSetup


def settled(
    counts: list[dict[str, int]], monkeypatch, counted: dict[str, int] | None = None
) -> ClosedLoop:
    """A loop whose probe saw 100 states and 100 commands (and the ``counted`` messages of
    other topics), and whose recorder answers ``counts`` one after the other (the last one
    from then on)."""
    monkeypatch.setattr(loop_module, "RECORD_POLL", 0.0)
    monkeypatch.setattr(loop_module, "RECORD_QUIET", 0.05)
    monkeypatch.setattr(loop_module, "RECORD_GAVE_UP", 0.2)
    loop = ClosedLoop.__new__(ClosedLoop)
    loop.bag = "bag"
    loop.robots = [RobotSetup("", "planar_2dof", {}, "pd_gravity_controller", {}, {})]
    loop.probe = SimpleNamespace(
        recordings={"": Recording(stamps=list(range(100)))},
        commands={"": 100},
        counted=dict(counted or {}),
    )
    answers = iter(counts)
    last = {}

    def recorded() -> dict[str, int]:
        nonlocal last
        last = next(answers, last)
        return last

    loop.recorded_counts = recorded
    return loop


WHOLE = {"/joint_states": 100, "/effort_command": 100, "/clock": 100}


def test_returns_once_the_whole_run_is_recorded_and_quiet(monkeypatch):
    tail = [{**WHOLE, "/joint_states": n, "/clock": n} for n in (40, 80)]
    settled([*tail, WHOLE], monkeypatch).settle_recording(timeout=5.0)


def test_a_recorder_that_missed_the_start_is_said_at_once_not_after_the_timeout(monkeypatch):
    missed = {**WHOLE, "/joint_states": 43, "/clock": 43}  # the first 57 never came
    loop = settled([missed], monkeypatch)
    with pytest.raises(RuntimeError, match="missed messages of the run"):
        loop.settle_recording(timeout=30.0)


def test_the_controller_states_the_probe_received_are_waited_for(monkeypatch):
    """A sampled-period run's bag once closed with 11 of its 34 controller states: the
    joint states were complete and the counts quiet. The states the probe received count."""
    state = "/pd_gravity_controller/state"
    late = [{**WHOLE, state: 11}] * 3 + [{**WHOLE, state: 34}]
    settled(late, monkeypatch, counted={state: 34}).settle_recording(timeout=5.0)
    loop = settled([{**WHOLE, state: 11}], monkeypatch, counted={state: 34})
    with pytest.raises(RuntimeError, match="missed messages of the run"):
        loop.settle_recording(timeout=30.0)
