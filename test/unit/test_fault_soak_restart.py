"""What the fault soak does when a process it restarted is matched but never fed (no ROS
graph: the soak's nodes and observer are fakes).

A node restarted after SIGKILL can be left by Fast DDS's shared-memory transport without
the messages of some publishers (docs/safety.md, "What the package cannot survive"). The
package does not hide it: the soak waits :data:`BACK_TIMEOUT` for the restarted recorder's
subscriptions, then says which topic was never matched, and its run ends there (``stuck``),
judged on what it recorded and failed by name."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from joint_space_control.lab.soaks import fault_soak
from joint_space_control.lab.soaks.fault_soak import FaultSoak, FaultSoakOptions, Injected


class NeverFed:
    """An observer whose recorder answers ``~/matched`` with the diagnostics unmatched."""

    def __init__(self, topics: list[str]) -> None:
        self.matched = {topic: 1 for topic in topics} | {"/diagnostics": 0}
        self.asked = 0

    def call_trigger(self, service: str, check=None):
        assert service == "/recorder/matched"
        self.asked += 1
        return SimpleNamespace(success=True, message=json.dumps(self.matched))

    def spin_for(self, seconds: float, check=None) -> None:
        pass

    def spin_once(self) -> None:
        pass


def test_a_restarted_recorder_never_matched_ends_the_run_saying_which_topic(tmp_path, monkeypatch):
    soak = FaultSoak(tmp_path, FaultSoakOptions(minutes=1.0, period=15.0), lambda line: None)
    soak.topics = [*fault_soak.RECORDED, f"/{soak.controller}/state"]
    soak.observer = NeverFed(soak.topics)
    soak.group = SimpleNamespace(check_alive=lambda: None)
    restarted: list[str] = []
    monkeypatch.setattr(soak, "kill", restarted.append)
    monkeypatch.setattr(soak, "start", restarted.append)
    monkeypatch.setattr(soak, "_sample", lambda now: None)
    soak._holding = True  # no move sent
    # BACK_TIMEOUT (60 s) shortened to 1 s: the wait's length is not what is tested
    monkeypatch.setattr(FaultSoak.wait_until, "__defaults__", (1.0,))

    with pytest.raises(TimeoutError) as raised:
        soak._kill_recorder(Injected(0, "kill_recorder", 0.0))
    message = str(raised.value)
    assert restarted == ["recorder", "recorder"]  # killed, then started again
    assert "the restarted recorder's subscriptions" in message
    assert "['/diagnostics']" in message and "were not matched" in message
    assert soak.observer.asked > 1  # asked again until the limit, not once
