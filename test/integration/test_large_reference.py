"""A reference is validated and splined off the control path (issue 15, item 3): a
100,000-point trajectory (4 MB) sent to a realtime controller holding the arm is built in
the controller's reference process (ros/reference_worker.py) while the control loop keeps
its usual timing, and the plant's brakes never engage.

Judged on the controller's /diagnostics windows (1 s each): the loop's period p99 over the
windows while the reference is received, built and started stays that of the six windows
before (median of the window p99s within 2×), and no period reaches 50 ms (or twice the
worst of those six windows, on a machine that stalls the loop by itself). Measured on this
2-core machine with plant, controller and probe running: p99 1.7–2.5 ms before, 1.9–2.9 ms
during (one window 5.8 ms in one of four runs); the worst period during, 9–17 ms, is rclpy
copying
the 4 MB message when the control path takes it. The baseline itself varies: its median
went from 1.6 to 7.1 ms between seven runs here, and CI saw 1.50× during a build (2.6 ms
before, 3.9 ms during; the bound was then 1.5× over four windows). Built in a thread of the
controller (the previous design), the same run gave window p99s of 9–13 ms (about 5×) and
worst periods of 77–122 ms;
built on the control path (before that), a 1.3 s stall that braked the plant. The plant's
command_timeout is 1 s here so that a loaded test machine's own stalls do not brake it.
"""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.ros.diagnostics import statuses

from .conftest import GAINS
from .loop_rate import loop_rate
from .test_faults import ROBOT, J, Rig, reference, rig  # noqa: F401  (the fixture)

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

Q0 = [0.3, -0.2]
POINTS = 100_000
CONTROLLER = "pd_gravity_controller: control loop"
PLANT = "sim_bridge: control loop"
#: The windows' median p99 during the build within this many times that before it: a
#: shared 2-core machine's own variation stays inside, a build on the loop's interpreter
#: (about 5×) does not.
USUAL_RATIO = 2.0
#: No period during the build this long [µs], unless the loop had one half as long before it
#: (a loaded machine's own stall: 124 ms once in make test, 2026-12-03, where a build on the
#: control path stalled 1.3 s and a waited-for build 3.5 s).
STALL_US = 50_000.0


def sine_reference(points: int, period: float = 1e-3) -> JointTrajectory:
    """q_d = Q0 + 1 mrad sin(2π t) on joint 1, starting when it arrives."""
    msg = JointTrajectory(joint_names=list(J))
    for k in range(1, points + 1):
        t = k * period
        sec, nsec = divmod(round(t * 1e9), 1_000_000_000)
        msg.points.append(
            JointTrajectoryPoint(
                positions=[Q0[0] + 1e-3 * np.sin(2 * np.pi * t), Q0[1]],
                time_from_start=Duration(sec=sec, nanosec=nsec),
            )
        )
    return msg


@pytest.mark.parametrize(
    "trigger",
    [
        "auto",  # the timer behind a realtime plant
        # answering each state: behind a realtime plant a large reference is built off the
        # control path as with the timer (waited for, the loop stalled 35-40 s in the fault
        # soak on a loaded machine)
        pytest.param("state", marks=pytest.mark.long),
    ],
)
def test_a_100000_point_reference_does_not_stall_the_realtime_loop(rig: Rig, trigger):  # noqa: F811
    rate = loop_rate()  # beside the reference's build: 1 kHz, less on a slow machine
    rig.group.start(
        "sim_bridge",
        {
            "robot": ROBOT,
            "mode": "realtime",
            "initial_positions": Q0,
            "command_timeout": 1.0,
            "publish_rate": rate,
        },
    )
    controller = rig.group.start(
        "pd_gravity_controller",
        {
            "robot": ROBOT,
            **GAINS[ROBOT],
            "use_sim_time": True,
            "trigger": trigger,
            "rate": rate,
        },
    )
    probe = rig.probe
    rig.diagnostics("sim_bridge", lambda s: not s["braking"])
    windows: list[dict] = []
    probe.node.create_subscription(
        DiagnosticArray, "/diagnostics", lambda m: windows.append(statuses(m)), 100
    )
    probe.spin_until(  # the usual timing: six whole windows of the running loop
        lambda: sum(CONTROLLER in w for w in windows) >= 7,
        30.0,
        "diagnostics",
        rig.group.check_alive,
    )
    before = [w[CONTROLLER] for w in windows if CONTROLLER in w][1:]
    brakes = [w[PLANT]["brake.engaged"] for w in windows if PLANT in w][-1]
    msg = sine_reference(POINTS)
    references = rig.publisher(JointTrajectory, "reference")
    start = len(windows)
    references.publish(msg)
    probe.spin_until(
        lambda: f"reference accepted: {POINTS} point(s)" in controller.log(),
        60.0,
        "the reference accepted",
        rig.group.check_alive,
    )
    probe.spin_for(2.5)
    during = [w[CONTROLLER] for w in windows[start:] if CONTROLLER in w]
    plant = [w[PLANT] for w in windows[start:] if PLANT in w]
    usual = [w["period.p99_us"] for w in before]
    now = [w["period.p99_us"] for w in during]
    worst = max(w["period.max_us"] for w in during)
    worst_before = max(w["period.max_us"] for w in before)
    print(
        f"period p99 before {usual} us, during {now}; worst period before {worst_before} us,"
        f" during {worst} us"
    )
    assert plant[-1]["brake.engaged"] == brakes  # no brake while the reference was built
    assert np.median(now) <= USUAL_RATIO * np.median(usual)  # the loop's usual timing
    # no stall: within 50 ms, or within twice the machine's own worst before the build
    assert worst < max(STALL_US, USUAL_RATIO * worst_before), (worst, worst_before)
    log = controller.log()
    assert "rejected" not in log and "Traceback" not in log


def test_a_large_reference_does_not_replace_a_newer_one_taken_while_it_was_built(rig: Rig):  # noqa: F811
    """References take effect in the order they arrive. Behind a realtime plant with
    ``trigger: state`` a small reference is taken at once and a large one is built off the
    control path: the 100,000-point one sent first must not replace, when its build ends,
    the step sent 0.3 s after it. In the fault soak it did, seconds later, and sent q_d back
    2.7 rad to where the arm had been (the controller clamped 5e6 N·m). On the old code
    the arm went back to Q0 and no ``superseded.references`` was counted."""
    rate = loop_rate()  # beside the reference's build: 1 kHz, less on a slow machine
    rig.group.start(
        "sim_bridge",
        {
            "robot": ROBOT,
            "mode": "realtime",
            "initial_positions": Q0,
            "command_timeout": 1.0,
            "publish_rate": rate,
        },
    )
    controller = rig.group.start(
        "pd_gravity_controller",
        {
            "robot": ROBOT,
            **GAINS[ROBOT],
            "use_sim_time": True,
            "trigger": "state",
            "rate": rate,
        },
    )
    probe = rig.probe
    rig.diagnostics("sim_bridge", lambda s: not s["braking"])
    references = rig.publisher(JointTrajectory, "reference")
    references.publish(sine_reference(POINTS))  # about Q0
    probe.spin_for(0.3)
    target = [Q0[0] + 0.3, Q0[1] - 0.2]
    references.publish(reference([(0.5, target)]))
    status = rig.diagnostics(
        "pd_gravity_controller", lambda s: s["superseded.references"] >= 1, timeout=60.0
    )
    probe.spin_for(3.0)  # the step is over (0.5 s) and PD + g has settled on it
    q = np.array(probe.recording.positions[-1])
    log = controller.log()
    print(f"q {q}, target {target}; superseded {status['superseded.references']}")
    assert status["superseded.references"] == 1
    assert f"dropped a reference of {POINTS} point(s) built after a newer one" in log
    assert f"reference accepted: {POINTS} point(s)" not in log
    assert np.abs(q - target).max() < 0.02, (q, target)
    assert "Traceback" not in log
