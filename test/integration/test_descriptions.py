"""Robot descriptions at the nodes: what cannot work is one line and exit code 2, and a
description published on the latched ``robot_description`` topic feeds ``robot:=topic``."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from joint_space_control.processes.processes import ProcessGroup, isolated_env
from test.corpus import BY_NAME, PACKAGE_PATHS, floating_g1

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

#: Publishes a file's text on robot_description like robot_state_publisher (latched).
DESCRIPTION_PUBLISHER = """
import sys, rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("robot_state_publisher_stand_in")
qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                 reliability=ReliabilityPolicy.RELIABLE)
node.create_publisher(String, "robot_description", qos).publish(
    String(data=open(sys.argv[1]).read()))
try:
    rclpy.spin(node)
except BaseException:
    pass
"""


def error_lines(log: str) -> list[str]:
    return [line for line in log.splitlines() if line.startswith("error:")]


def assert_refused_in_one_line(
    tmp_path, executable: str, cases: dict[str, tuple[dict, str]]
) -> None:
    """Each case (parameters, text of its line) started as ``executable``: exit code 2,
    no traceback, one ``error:`` line holding the text."""
    with ProcessGroup(tmp_path / "runs", next_domain_id()) as group:
        nodes = {
            kind: (group.start(executable, params, name=f"{executable}_{kind}"), match)
            for kind, (params, match) in cases.items()
        }
        for kind, (node, match) in nodes.items():
            assert node.proc.wait(timeout=60) == 2, (kind, node.log())
            log = node.log()
            assert "Traceback" not in log, (kind, log)
            (line,) = error_lines(log)
            assert match in line, (kind, line)


@pytest.mark.parametrize("executable", ["sim_bridge", "pd_gravity_controller"])
def test_unusable_descriptions_exit_2_with_one_line(tmp_path, executable):
    (tmp_path / "bad.urdf").write_text('<robot name="x"><link name="a"><joint name=')
    (tmp_path / "rigid.urdf").write_text('<robot name="rigid"><link name="a"/></robot>')
    (tmp_path / "g1.urdf").write_text(floating_g1())
    cases = {
        "malformed": ({"urdf_path": str(tmp_path / "bad.urdf")}, "malformed robot description"),
        "missing": ({"urdf_path": str(tmp_path / "nope.urdf")}, "is not a file"),
        "floating": ({"urdf_path": str(tmp_path / "g1.urdf")}, "floating base"),
        "no_joints": ({"urdf_path": str(tmp_path / "rigid.urdf")}, "no movable joint"),
        "bad_limits": ({**BY_NAME["ur5"].params(), "effort_limits": [1.0, 2.0]}, "needs 1 or 6"),
    }
    assert_refused_in_one_line(tmp_path, executable, cases)


def test_what_the_mujoco_plant_cannot_do_is_refused_in_one_line(tmp_path):
    """engine:=mujoco (issue 26): a GUI, a description with inertias MuJoCo would have to
    balance (xarm6 of pybullet_data, which PyBullet takes with a warning) and an unknown
    engine each stop sim_bridge at start with one line and exit code 2."""
    iiwa = {"robot": "iiwa", "mode": "lockstep"}
    cases = {
        "gui": ({**iiwa, "engine": "mujoco", "gui": True}, "the MuJoCo plant has no viewer"),
        "unphysical": (
            {**BY_NAME["xarm6"].params(), "engine": "mujoco"},
            "have inertias that are not physical",
        ),
        "unknown": ({**iiwa, "engine": "bullet"}, "engine"),
    }
    assert_refused_in_one_line(tmp_path, "sim_bridge", cases)


def test_robot_topic_reads_the_latched_description(tmp_path):
    robot = BY_NAME["ur5"]
    domain = next_domain_id()
    publisher = subprocess.Popen(
        [sys.executable, "-c", DESCRIPTION_PUBLISHER, str(robot.path)],
        env=isolated_env(domain),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        with ProcessGroup(tmp_path, domain) as group:
            sim = group.start(
                "sim_bridge",
                {"robot": "topic", "package_paths": PACKAGE_PATHS, "mode": "lockstep"},
            )
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and "sim_bridge: ur5" not in sim.log():
                group.check_alive()
                time.sleep(0.2)
            log = sim.log()
            assert "sim_bridge: ur5 ['shoulder_pan_joint'" in log, log
            assert "mesh file(s) not found" not in log  # package_paths resolved them
    finally:
        publisher.kill()
        publisher.wait()
