"""One commander at a time (issue 15, item 1): while a controller commands the plant, valid
effort commands from another sender are refused, counted on /diagnostics
(``rejected.foreign_commands``) and never applied, in realtime and in lockstep; ``~/release``
frees the plant and the controller takes it again at its next command. (A controller killed
and restarted under the same name takes over at once: test_faults.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from joint_space_control.ros.messages import ns_to_stamp

from .conftest import GAINS
from .test_faults import LIMITS, ROBOT, J, Rig, rig  # noqa: F401  (the fixture)

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

Q0 = [0.3, -0.2]
FOREIGN = 50  # valid commands from an intruder, over about a second
OWNER = "/pd_gravity_controller"


def intruder_command(stamp_ns: int, effort) -> JointState:
    msg = JointState(name=list(J), effort=[float(x) for x in effort])
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = "/intruder"
    return msg


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
def test_a_second_commander_is_refused_counted_and_never_applied(rig: Rig, mode):  # noqa: F811
    # command_timeout 2 s: the owner keeps the plant through the stalls a loaded test
    # machine gives a realtime controller (beyond it, ownership passes by design: the
    # plant brakes at that moment too)
    rig.group.start(
        "sim_bridge",
        {"robot": ROBOT, "mode": mode, "initial_positions": Q0, "command_timeout": 2.0},
    )
    rig.group.start(
        "pd_gravity_controller",
        {"robot": ROBOT, **GAINS[ROBOT], "use_sim_time": mode == "realtime"},
    )
    status = rig.diagnostics("sim_bridge", lambda s: s["owner"] == OWNER and not s["braking"])
    assert status["rejected.foreign_commands"] == 0
    probe = rig.probe
    start = len(probe.recording.positions)
    intruder = rig.publisher(JointState, "effort_command", subscribers=2)  # plant + probe
    push = 0.9 * LIMITS * np.array([1.0, -1.0])  # valid: within reject_factor × the limits
    for k in range(FOREIGN):
        stamp = probe.recording.stamps[-1] if probe.recording.stamps else 0
        intruder.publish(intruder_command(stamp, push))
        probe.spin_for(0.02)
        if k % 10 == 0:  # malformed and absurd ones too: rejected as before, not foreign
            intruder.publish(intruder_command(stamp, [float("nan"), 0.0]))
            probe.spin_for(0.02)
            intruder.publish(intruder_command(stamp, 1e9 * np.ones(2)))
            probe.spin_for(0.02)
    probe.spin_for(0.5)
    # every command received is judged (the plant's command queue holds 16, drained)
    status = rig.diagnostics(
        "sim_bridge", lambda s: s["rejected.foreign_commands"] >= FOREIGN, timeout=10.0
    )
    assert status["rejected.foreign_commands"] == FOREIGN
    assert status["rejected.commands"] == 2 * FOREIGN // 10
    assert status["owner"] == OWNER
    q = np.array(probe.recording.positions[start:])
    assert len(q) > 100  # the loop ran meanwhile
    moved = float(np.max(np.abs(q - np.array(Q0))))
    print(f"{mode}: {len(q)} states, moved {moved:.2e} rad, {FOREIGN} foreign commands counted")
    assert moved < 0.01, moved
    log = rig.group.nodes["sim_bridge"].log()
    assert "rejected a command from '/intruder'" in log and "Traceback" not in log

    # ~/release frees the plant; the controller (still commanding) takes it again
    response = probe.call_trigger("/sim_bridge/release")
    assert response.success and OWNER in response.message, response.message
    assert "~/release: released '/pd_gravity_controller'" in rig.group.nodes["sim_bridge"].log()
    foreign = status["rejected.foreign_commands"]
    status = rig.diagnostics("sim_bridge", lambda s: s["owner"] == OWNER)
    assert status["rejected.foreign_commands"] == foreign  # nothing foreign since
