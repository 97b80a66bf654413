"""Logs stay readable under any fault (issue 17, item 2b): a controller fed a fault at every
message for seconds logs at most one line a second per kind, and a later line says how many
it held back. Counts of lines are compared, never how long anything took: each fault's lines
are bounded by the wall time from its first message to the answer to a valid state sent
after its last one (all of it handled by then)."""

from __future__ import annotations

import math
import re
import time

import pytest
from rclpy.duration import Duration
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.ros.messages import ns_to_stamp

from .test_faults import MS, ROBOT, J, joint_state, reference, rig  # noqa: F401 (rig: a fixture)

pytestmark = pytest.mark.integration

SECONDS = 3.0  # of each fault
PERIOD = 0.002  # [s] between two bad messages (~500 Hz)
HELD_BACK = re.compile(r"\((\d+) more since the last report\)$")


@pytest.mark.long  # seconds of faults at 500 Hz (make test-long): make test within 5 minutes
def test_each_recurring_fault_of_a_controller_logs_one_line_a_second(rig):  # noqa: F811
    node = "inverse_dynamics_controller"
    # measured: a state without velocities is bad input
    rig.group.start(
        node, {"robot": "planar_2dof", "trigger": "state", "velocity_source": "measured"}
    )
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    refs = rig.publisher(JointTrajectory, "reference")
    rig.wait_for_publisher("/effort_command")
    stamp = [0]

    def next_stamp() -> int:
        stamp[0] += 2 * MS
        return stamp[0]

    def answered_state() -> None:
        """A valid state, answered: every message sent before it has been handled."""
        sent = next_stamp()
        states.publish(joint_state(sent))
        rig.probe.spin_until(
            lambda: rig.answered(sent), 20.0, f"command {sent}", rig.group.check_alive
        )

    def flood(pub, make) -> float:
        """``make()``'s messages for SECONDS; returns the wall time until all were handled."""
        start = time.monotonic()
        while time.monotonic() - start < SECONDS:
            pub.publish(make())
            time.sleep(PERIOD)
        if pub is refs:
            assert pub.wait_for_all_acked(Duration(seconds=20.0))
        rig.group.check_alive()
        answered_state()
        return time.monotonic() - start

    def no_velocity() -> JointState:
        msg = JointState(name=list(J), position=[0.1, -0.2])
        msg.header.stamp = ns_to_stamp(next_stamp())
        return msg

    answered_state()
    faults = {  # the text every line of the kind starts with → its messages
        "rejected joint state: missing joints": (
            states,
            lambda: joint_state(next_stamp(), names=["joint1"], q=(0.1,), dq=(0.0,)),
        ),
        "rejected joint state: non-finite": (
            states,
            lambda: joint_state(next_stamp(), q=(math.nan, 0.0)),
        ),
        "rejected joint state: no velocity": (states, no_velocity),
        "rejected reference:": (refs, lambda: reference([(0.5, (4.0, 0.0))])),  # beyond limits
        # large plausible velocities: a torque far beyond 2 × the limits (clamped, said)
        "× the effort limits (reject_factor): clamped": (
            states,
            lambda: joint_state(next_stamp(), dq=(5e2, -5e2)),
        ),
        # absurd ones (the Coriolis term would overflow): refused where they arrive
        "rejected joint state: implausible measurement": (
            states,
            lambda: joint_state(next_stamp(), dq=(1e200, 1e200)),
        ),
    }
    took = {text: flood(pub, make) for text, (pub, make) in faults.items()}

    log = rig.group.nodes[node].log().splitlines()
    for text, seconds in took.items():
        lines = [line for line in log if text in line]
        assert 2 <= len(lines) <= math.ceil(seconds) + 1, (text, seconds, lines)
        held = [HELD_BACK.search(line) for line in lines[1:]]
        assert any(m is not None and int(m.group(1)) > 0 for m in held), (text, lines)


@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_each_recurring_fault_of_the_plant_logs_one_line_a_second(rig):  # noqa: F811
    """sim_bridge (realtime, so that it takes every message without a controller): bad,
    absurd and foreign effort commands, bad arrays and bad wrenches at ~500 Hz for seconds
    each, then a valid command; per kind at most one line a second, with the count held
    back."""
    from geometry_msgs.msg import WrenchStamped
    from std_msgs.msg import Float64MultiArray

    rig.group.start("sim_bridge", {"robot": ROBOT, "mode": "realtime", "command_timeout": 5.0})
    commands = rig.publisher(JointState, "effort_command", subscribers=2)  # + the probe
    arrays = rig.publisher(Float64MultiArray, "/sim_bridge/commands")
    wrenches = rig.publisher(WrenchStamped, "/sim_bridge/wrench")

    owner = rig.probe.node.get_fully_qualified_name()  # a node on the graph: it stays owner

    def command(effort, frame_id=owner) -> JointState:
        msg = JointState(name=list(J), effort=list(effort))
        msg.header.frame_id = frame_id
        return msg

    def wrench() -> WrenchStamped:
        msg = WrenchStamped()
        msg.header.frame_id = "no_such_link"
        msg.wrench.force.x = 1.0
        return msg

    commands.publish(command((0.0, 0.0)))  # the owner claims the plant
    rig.diagnostics("sim_bridge", lambda s: s["owner"] == owner)
    faults = {
        "rejected effort command:": (commands, lambda: command((math.nan, 0.0))),
        "beyond 2 × the effort limits": (commands, lambda: command((1e9, 0.0))),
        "rejected a command from '/intruder'": (
            commands,
            lambda: command((0.0, 0.0), "/intruder"),
        ),
        "rejected command array:": (arrays, lambda: Float64MultiArray(data=[0.0])),
        "rejected wrench:": (wrenches, wrench),
    }
    took = {}
    for text, (pub, make) in faults.items():
        start = time.monotonic()
        while time.monotonic() - start < SECONDS:
            pub.publish(make())
            if text != "rejected a command from '/intruder'":
                commands.publish(command((0.0, 0.0)))  # the owner keeps the plant
            time.sleep(PERIOD)
        rig.probe.spin_for(0.5)  # the plant takes what is queued (drained, depth 16)
        rig.group.check_alive()
        took[text] = time.monotonic() - start
    # a status published after the plant took them: the newest the probe holds may be one
    # from before the wrenches (twice in make test's parallel part on a loaded machine)
    counted = ("rejected.commands", "rejected.wrenches", "rejected.foreign_commands")
    # (a TimeoutError fails the test when the counts do not reach 100 within 20 s)
    rig.diagnostics("sim_bridge", lambda s: all(s[k] > 100 for k in counted))

    log = rig.group.nodes["sim_bridge"].log().splitlines()
    for text, seconds in took.items():
        lines = [line for line in log if text in line]
        assert 2 <= len(lines) <= math.ceil(seconds) + 1, (text, seconds, lines)
        held = [HELD_BACK.search(line) for line in lines[1:]]
        assert any(m is not None and int(m.group(1)) > 0 for m in held), (text, lines)
