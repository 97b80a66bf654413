"""The test probe behind a realtime plant after a while of taking nothing (a test driving a
browser does that): it is at the newest state within seconds of spinning again.

With Fast DDS's default reader limit of 5000 samples, a probe left 8000 states behind a
plant never caught up again (fastdds_client.xml lifts it); left idle for seconds, it was stalled
against the controller's writer (the page test's waits timed out), so a busy caller has it
spin in a thread of its own."""

from __future__ import annotations

import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray

from joint_space_control.ros.diagnostics import statuses

from .test_faults import ROBOT, rig  # noqa: F401 (rig: a fixture)

# make test-long, beside the page test whose probe they keep from stalling (~1 min)
pytestmark = [pytest.mark.integration, pytest.mark.realtime, pytest.mark.long]

#: States left waiting in the probe's history: more than Fast DDS's default reader limit of
#: 5000, fewer than the probe's depth of 10000.
BACKLOG = 8000
#: The plant's and the controller's rate [Hz], the same on every machine: what is judged is
#: a count of messages left waiting (BACKLOG), not the rate; the caller is idle for as long
#: as that many take.
RATE = 250.0
IDLE = BACKLOG / RATE  # [s]
#: Longest wait for the probe to be at the plant's newest state again [s]: the backlog and
#: what the plant sends meanwhile, taken at 650 states a second at least. A probe that
#: takes them no faster than the plant sends them never catches up (the stall this tests).
CATCH_UP = 20.0


def test_the_probe_takes_the_newest_states_after_taking_none_for_8000_states(rig):  # noqa: F811
    """The plant alone at :data:`RATE`; the probe takes nothing while BACKLOG states are
    published, then takes them all, in order and none twice, and is at the plant's newest
    state within CATCH_UP."""
    rate, idle = RATE, IDLE
    rig.group.start("sim_bridge", {"robot": ROBOT, "mode": "realtime", "publish_rate": rate})
    status = "sim_bridge: control loop"
    rig.probe.run_until(1.0, 60.0, rig.group.check_alive)
    taken = len(rig.probe.recording.stamps)
    time.sleep(idle)  # nothing spun: the states wait in the reader's history
    rig.probe.spin_until(
        lambda: len(rig.probe.recording.stamps) > taken + rate, 10.0, "states again"
    )
    now = float(rig.probe.wait_for_diagnostics([status])[status]["sim_time_s"])
    rig.probe.spin_until(
        lambda: rig.probe.latest_time() >= now,
        CATCH_UP,
        f"the probe at the plant's time {now:.3f} s ({rig.probe.latest_time():.3f} s taken)",
        rig.group.check_alive,
    )
    t, _, _, _ = rig.probe.recording.arrays()
    after = t[taken:]
    # the states of the idle time kept (the history's depth of 10000 was not reached), in
    # order, none twice: 1/rate apart, but for one the plant may not have sent in time
    span = after[-1] - after[0]
    assert span > idle
    assert np.all(np.diff(after) > 0)
    assert len(after) >= 0.99 * rate * span, (len(after), span)


def test_a_probe_spinning_in_its_thread_takes_every_command_while_the_caller_is_busy(rig):  # noqa: F811
    """Left seconds at a time without spinning beside a realtime loop, a probe can stall
    against the controller's writer and then take a few of its commands a second; spinning
    in its own thread meanwhile, it takes what the controller sent while the caller was
    busy for BACKLOG commands' time: at least 90 % of the commands the controller says it
    sent (its ``total.ticks`` on /diagnostics, read as the probe takes them)."""
    rate = RATE
    sent: list[tuple[int, int]] = []  # (commands taken, the controller's ticks) per status
    name = "pd_gravity_controller: control loop"

    def on_diagnostics(msg: DiagnosticArray) -> None:
        found = statuses(msg)
        if name in found:
            sent.append((len(rig.commands), int(found[name]["total.ticks"])))

    rig.probe.node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 100)
    rig.group.start(
        "sim_bridge",
        {"robot": ROBOT, "mode": "realtime", "command_timeout": 2.0, "publish_rate": rate},
    )
    rig.group.start(
        "pd_gravity_controller",
        {"robot": ROBOT, "use_sim_time": True, "state_timeout": 1.0, "rate": rate},
    )
    rig.probe.spin_until(
        lambda: len(rig.commands) > rate / 2, 60.0, "commands", rig.group.check_alive
    )
    for _ in range(2):
        first = len(sent)
        with rig.probe.spinning_in_background():
            time.sleep(IDLE)  # busy elsewhere
            # waiting in the block: the thread serves
            rig.probe.spin_until(lambda n=first: len(sent) > n + 1, 5.0, "statuses in the block")
        (taken_0, ticks_0), (taken_1, ticks_1) = sent[first], sent[-1]
        taken, ticked = taken_1 - taken_0, ticks_1 - ticks_0
        print(f"{taken} commands taken of {ticked} sent")
        # the case tested: more commands sent meanwhile than Fast DDS's default reader limit
        assert ticked > 5000, ticked
        assert taken >= 0.9 * ticked, (taken, ticked)
