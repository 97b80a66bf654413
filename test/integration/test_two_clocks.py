"""Two simulators in one domain (issue 17, item 3): time that goes back and forth is said
once at ERROR, counted on /diagnostics, and neither restarts the controller at each jump nor
fills its log; a single backward jump (a restarted simulator) still restarts it
(test_faults.py). Counts of lines and jumps are compared, never how long anything took."""

from __future__ import annotations

import time

import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from joint_space_control.ros.messages import ns_to_stamp

from .test_faults import GAINS, MS, ROBOT, joint_state, rig  # noqa: F401 (rig: a fixture)

pytestmark = pytest.mark.integration

SECONDS = 4.0
JUMP_NS = 100_000_000_000  # the second simulator's time, 100 s ahead
NODE = "pd_gravity_controller"
CLOCK_ERROR = "/clock goes backwards and forwards: more than one node publishes /clock"
STATE_ERROR = "joint state time goes backwards and forwards: more than one node publishes"


def lines_of(rig, text: str) -> list[str]:  # noqa: F811
    return [line for line in rig.group.nodes[NODE].log().splitlines() if text in line]


def test_a_clock_going_back_and_forth_is_said_once_and_changes_nothing_else(rig):  # noqa: F811
    """A controller on simulation time (timer) with joint states arriving; /clock from two
    publishers, 100 s apart, alternating at ~200 Hz."""
    rig.group.start(
        NODE,
        {"robot": ROBOT, "trigger": "timer", "use_sim_time": True, "rate": 200.0, **GAINS[ROBOT]},
    )
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    clock = rig.publisher(Clock, "/clock")
    rig.wait_for_publisher("/effort_command")
    rig.diagnostics(NODE, lambda s: True)  # subscribed: statuses arrive while it runs
    start = time.monotonic()
    k = 0
    while (elapsed := time.monotonic() - start) < SECONDS:
        now_ns = 1000 * 1_000_000_000 + round(elapsed * 1e9)
        msg = Clock()
        msg.clock = ns_to_stamp(now_ns + (JUMP_NS if k % 2 else 0))
        clock.publish(msg)
        states.publish(joint_state(now_ns))  # one plant's states: their time goes forwards
        rig.probe.spin_for(0.004)
        k += 1
    rig.group.check_alive()
    status = rig.diagnostics(NODE, lambda s: True)
    assert status["clock.backward_jumps"] >= 3
    assert status["level"] == 2 and "/clock goes backwards and forwards" in status["message"]
    assert status["restarts"] == 0 and status["joint_states.backward_jumps"] == 0
    assert len(rig.commands) > 0  # it commanded meanwhile
    assert len(lines_of(rig, CLOCK_ERROR)) == 1
    log = rig.group.nodes[NODE].log().splitlines()
    assert len(log) <= 8, log  # start-up (3-4 lines) and the error


def test_joint_states_going_back_and_forth_are_said_once_and_restart_at_most_twice(rig):  # noqa: F811
    """Two plants on one joint_states topic, 100 s apart, alternating at ~500 Hz: the first
    jumps restart the controller as a restarted simulator would, then it stops restarting."""
    rig.group.start(NODE, {"robot": ROBOT, "trigger": "state", **GAINS[ROBOT]})
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    rig.wait_for_publisher("/effort_command")
    rig.diagnostics(NODE, lambda s: True)
    start = time.monotonic()
    k = 0
    while (elapsed := time.monotonic() - start) < SECONDS:
        stamp = round(elapsed * 1e9) // MS * MS + (JUMP_NS if k % 2 else 0)
        states.publish(joint_state(stamp))
        time.sleep(0.002)
        k += 1
    rig.group.check_alive()
    status = rig.diagnostics(NODE, lambda s: s["joint_states.backward_jumps"] >= 3)
    assert status["level"] == 2 and "joint state time goes backwards" in status["message"]
    assert status["restarts"] <= 2
    assert len(lines_of(rig, STATE_ERROR)) == 1
    assert len(lines_of(rig, "joint state time went backwards: restarting")) <= 2
    log = rig.group.nodes[NODE].log().splitlines()
    assert len(log) <= 10, log
