"""A robot that cannot do what it is asked says so at start, naming the joints (issue 26,
item 7): Baxter of example-robot-data at its zero configuration needs 56.4 N·m of gravity
torque (Pinocchio's g(q)) on ``right_s1`` and ``left_s1``, whose URDF limit is 50 N·m (the
issue saw 100–212 N·m computed there while the arm sagged: the PD terms on top)."""

from __future__ import annotations

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from test.corpus import PACKAGE_PATHS, ROBOTS

from .test_faults import joint_state, rig  # noqa: F401 (rig: a fixture)

pytestmark = pytest.mark.integration

BAXTER = ROBOTS / "baxter_description" / "urdf" / "baxter.urdf"
GRAVITY_LINE = "the arm cannot hold its configuration against gravity"


def test_baxter_says_once_which_joints_gravity_takes_beyond_their_limits(rig):  # noqa: F811
    model = RobotModel(resolve_robot(urdf_path=str(BAXTER), package_paths=PACKAGE_PATHS))
    q = np.zeros(model.n)
    needed = model.gravity(q)
    beyond = [
        name
        for name, g, limit in zip(model.joint_names, needed, model.effort_limits, strict=True)
        if abs(g) > limit
    ]
    assert sorted(beyond) == ["left_s1", "right_s1"]  # what the issue found
    node = "pd_gravity_controller"
    rig.group.start(
        node,
        {"urdf_path": str(BAXTER), "package_paths": PACKAGE_PATHS, "trigger": "state"},
    )
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    rig.wait_for_publisher("/effort_command")
    for k in (1, 2, 3):  # three states, each answered: the line comes once
        stamp = k * 1_000_000
        rig.send(states, joint_state(stamp, model.joint_names, q, q))
        rig.probe.spin_until(
            lambda stamp=stamp: rig.answered(stamp),
            20.0,
            f"command {stamp}",
            rig.group.check_alive,
        )
    lines = [line for line in rig.group.nodes[node].log().splitlines() if GRAVITY_LINE in line]
    assert len(lines) == 1, lines
    (line,) = lines
    for name in beyond:
        j = model.joint_names.index(name)
        assert f"{name} {needed[j]:.4g} N·m (limit {model.effort_limits[j]:g})" in line, line
    assert "Traceback" not in rig.group.nodes[node].log()
