"""Stopping a node with SIGINT or SIGTERM prints no traceback, whoever is connected: the
realtime sim_bridge used to crash its physics thread on the shut-down context when a /clock
subscriber made it publish at the moment of the signal (RCLError from _publish_state)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from joint_space_control.processes.processes import ProcessGroup, isolated_env

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

CLOCK_SUBSCRIBER = """
import rclpy
from rosgraph_msgs.msg import Clock
rclpy.init()
node = rclpy.create_node("clock_listener")
node.create_subscription(Clock, "/clock", lambda m: None, 10)
try:
    rclpy.spin(node)
except BaseException:
    pass
"""
ROUNDS = 3  # per signal


@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_realtime_sim_bridge_stops_without_traceback_with_a_clock_subscriber(tmp_path):
    domain = next_domain_id()
    listener = subprocess.Popen(
        [sys.executable, "-c", CLOCK_SUBSCRIBER],
        env=isolated_env(domain),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    stops = 0
    try:
        for k in range(ROUNDS):
            for sig in (signal.SIGINT, signal.SIGTERM):
                with ProcessGroup(tmp_path / f"{k}_{sig.name}", domain) as group:
                    sim = group.start("sim_bridge", {"mode": "realtime"})
                    deadline = time.monotonic() + 60
                    while "realtime on pybullet, physics" not in sim.log():
                        group.check_alive()
                        assert time.monotonic() < deadline, sim.log()
                        time.sleep(0.1)
                    time.sleep(1.0)  # publishing /clock to the listener at 1 kHz
                    sim.signal(sig)
                    assert sim.proc.wait(timeout=30) == 0, sim.log()
                    assert "Traceback" not in sim.log(), (sig.name, sim.log())
                    stops += 1
    finally:
        listener.kill()
        listener.wait()
    assert stops == 2 * ROUNDS
