"""Loop statistics on /diagnostics from a real lockstep loop: every key from the controller
and from sim_bridge, consistent counts, and the statuses recorded in the bag. No wall-clock
assertions: the values are timings of a shared machine; only their structure is checked."""

from __future__ import annotations

import math

import pytest
from rosbags.highlevel import AnyReader

from joint_space_control.recording.bag_writer import jazzy_typestore
from joint_space_control.ros.loop_statistics import summary_keys

from .conftest import JOINTS, SETPOINTS

pytestmark = pytest.mark.integration

ROBOT = "planar_2dof"
CONTROLLER = "pd_gravity_controller: control loop"
SIM = "sim_bridge: control loop"


def test_controller_and_sim_publish_loop_statistics(make_loop, tmp_path):
    bag = tmp_path / "bag"
    loop = make_loop(ROBOT, record=bag)
    loop.start(JOINTS[ROBOT], [SETPOINTS[ROBOT]])
    loop.run_until(1.0)
    loop.pause()
    # a window without ticks from both: paused, their totals are final
    latest = loop.probe.wait_for_diagnostics(
        [CONTROLLER, SIM],
        until=lambda d: all(
            d[n]["ticks"] == 0 and d[n]["total.ticks"] > 0 for n in (CONTROLLER, SIM) if n in d
        ),
        check=loop.group.check_alive,
    )

    controller, sim = latest[CONTROLLER], latest[SIM]
    for status in (controller, sim):
        assert set(summary_keys()) <= set(status), set(summary_keys()) - set(status)
        assert status["level"] == 0 and status["hardware_id"] == ROBOT
        for key in summary_keys():
            assert isinstance(status[key], float), key
        # in lockstep every tick answers / is answered: compute and latency are measured
        assert status["total.ticks"] >= status["ticks"] >= 0
        for key in ("total.compute.p50_us", "total.latency.p50_us", "total.period.p50_us"):
            assert status[key] > 0, key
        assert status["total.compute.p50_us"] <= status["total.compute.p99_us"]
        assert status["total.compute.p99_us"] <= status["total.compute.max_us"]
        # the lockstep loop is not paced: no lateness measured, nothing late
        assert math.isnan(status["total.lateness.p50_us"]) and status["total.late"] == 0
    assert controller["trigger"] == "state"
    assert sim["mode"] == "lockstep" and sim["real_time_factor"] == 0.0  # paused window
    # one simulator step per command; the controller also answered the state the simulator
    # paused with (or not yet, if the pause came in between)
    assert controller["total.ticks"] - sim["total.ticks"] in (0, 1)
    assert sim["total.ticks"] >= 1000
    assert sim["sim_time_s"] == pytest.approx(sim["total.ticks"] * 1e-3)
    # jitter in lockstep: the wall period against the 1 ms step, measured on every tick
    assert controller["total.jitter.max_us"] >= 0

    loop.close()
    with AnyReader([bag], default_typestore=jazzy_typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == "/diagnostics"]
        names = {
            status.name
            for conn, _, raw in reader.messages(connections=connections)
            for status in reader.deserialize(raw, conn.msgtype).status
        }
    assert {CONTROLLER, SIM} <= names
