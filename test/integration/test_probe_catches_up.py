"""The test probe behind a realtime plant after a while of taking nothing (a test driving a
browser does that): it is at the newest state within seconds of spinning again.

With Fast DDS's default reader limit of 5000 samples, a probe left 8 s behind a 1 kHz plant
never caught up again (fastdds_client.xml lifts it); left idle for seconds, it was stalled
against the controller's writer (the page test's waits timed out), so a busy caller has it
spin in a thread of its own."""

from __future__ import annotations

import time

import numpy as np
import pytest

from .loop_rate import PLANT_ALONE_RATE, loop_rate
from .test_faults import ROBOT, rig  # noqa: F401 (rig: a fixture)

# make test-long, beside the page test whose probe they keep from stalling (~1 min)
pytestmark = [pytest.mark.integration, pytest.mark.realtime, pytest.mark.long]

#: States left waiting in the probe's history: more than Fast DDS's default reader limit of
#: 5000, fewer than the probe's depth of 10000.
BACKLOG = 8000
#: Longest wait for the probe to be at the plant's newest state again [s]: it takes the
#: backlog faster than the plant sends (~11000 in 1 s on a machine running sum(range(1000))
#: in 10 µs; a few thousand a second on one 4 times slower).
CATCH_UP = 20.0
#: How long the second test's caller is busy elsewhere [s].
IDLE = 8.0


def test_the_probe_takes_the_newest_states_after_taking_none_for_8000_states(rig):  # noqa: F811
    """The plant publishes at the machine's loop rate (loop_rate.py), 250 Hz at least: at
    1 kHz, on a machine that ran sum(range(1000)) in 37 µs, the probe had taken the states up
    to 2.3 s of the plant's time when the plant was at 10.6 s, after 5 s of catching up (a
    CI run)."""
    # the plant alone: where the loop beside a browser runs at 100 Hz, the backlog would
    # take 80 s
    rate = max(loop_rate(), PLANT_ALONE_RATE)
    idle = BACKLOG / rate  # 8 s at 1 kHz, 32 s at 250 Hz
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
    """Left 6 s at a time without spinning beside a realtime loop, the probe then took 2-7 of
    the controller's 1000 commands a second (stalled against its writer); spinning in its
    own thread meanwhile, it takes them all (at 1 kHz, or at the slower rate a slow machine
    runs the loop at beside the probe: loop_rate.py)."""
    rate = loop_rate()
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
        before = len(rig.commands)
        with rig.probe.spinning_in_background():
            time.sleep(IDLE)  # busy elsewhere
            # waiting in the block: the thread serves
            rig.probe.spin_until(
                lambda n=before: len(rig.commands) > n + rate, 5.0, "commands in the block"
            )
        taken = len(rig.commands) - before
        assert taken >= 0.9 * rate * IDLE, taken  # the controller sends `rate` a second
