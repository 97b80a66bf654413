"""Recording a real closed loop: the bag reads back with both readers, analyses to the live
run's numbers, and survives a SIGTERM mid-run."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader

from joint_space_control.recording.bag_writer import jazzy_typestore
from joint_space_control.ros.messages import stamp_to_ns

from .conftest import JOINTS, SETPOINTS

pytestmark = pytest.mark.integration

ROBOT = "planar_2dof"
STATE_TOPIC = "/pd_gravity_controller/state"


def read_with_rosbags(bag: Path) -> dict[str, list]:
    """Every message, deserialized strictly, per topic: [(log time ns, message)]."""
    topics: dict[str, list] = {}
    with AnyReader([bag], default_typestore=jazzy_typestore()) as reader:
        for conn, stamp, raw in reader.messages():
            topics.setdefault(conn.topic, []).append(
                (stamp, reader.deserialize(raw, conn.msgtype))
            )
    return topics


def read_with_mcap(bag: Path) -> dict[str, list]:
    (mcap_file,) = bag.glob("*.mcap")
    topics: dict[str, list] = {}
    for item in read_ros2_messages(str(mcap_file)):
        topics.setdefault(item.channel.topic, []).append((item.log_time_ns, item.ros_msg))
    return topics


def joint_state_stamps(messages: list) -> np.ndarray:
    return np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, m in messages])


def test_recorded_run_reads_back_with_both_readers(make_loop, tmp_path):
    bag = tmp_path / "bag"
    loop = make_loop(ROBOT, record=bag)
    loop.start(JOINTS[ROBOT], [SETPOINTS[ROBOT]])
    loop.run_until(1.5)
    last = loop.pause()
    loop.settle_recording()  # the recorder takes the tail (a loaded machine delays it)
    t, q, _, _ = loop.probe.recording.arrays()
    assert t[-1] == last * 1e-9  # the probe holds the state the plant's pause answer names
    loop.close()

    by_rosbags = read_with_rosbags(bag)
    by_mcap = read_with_mcap(bag)
    for name in ["/joint_states", "/effort_command", "/reference", STATE_TOPIC, "/clock"]:
        assert by_rosbags.get(name), f"{name} not recorded"
        assert len(by_mcap[name]) == len(by_rosbags[name]), name
    assert {k: len(v) for k, v in by_mcap.items()} == {k: len(v) for k, v in by_rosbags.items()}

    # The plant's states in the bag are the ones the live probe saw, to the last one.
    states = by_rosbags["/joint_states"]
    stamps = joint_state_stamps(states)
    last = {s: m for s, (_, m) in zip(stamps, states, strict=True)}
    assert stamps.max() == pytest.approx(t[-1], abs=1e-9)
    np.testing.assert_array_equal(last[stamps.max()].position, q[-1])
    # Commands (empty position/velocity) read back strictly and name the joints.
    _, cmd = by_rosbags["/effort_command"][-1]
    assert list(cmd.name) == JOINTS[ROBOT] and cmd.position.size == 0 and cmd.effort.size == 2
    # The controller's configuration (latched) and the reference are in the bag.
    (_, config), *_ = by_rosbags["/pd_gravity_controller/config"]
    assert '"law": "pd_gravity"' in config.data
    (_, ref), *_ = by_rosbags["/reference"]
    assert list(ref.points[0].positions) == SETPOINTS[ROBOT]

    # `jsc analyze` on the bag finds the live run's final error, to the last bit.
    out = tmp_path / "report"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "joint_space_control.cli.main",
            "analyze",
            str(bag),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    controller = metrics["controllers"]["/pd_gravity_controller"]
    live_error = np.array(SETPOINTS[ROBOT]) - q[-1]
    measured = [controller["final_error"][j] for j in JOINTS[ROBOT]]
    np.testing.assert_allclose(measured, live_error, rtol=0, atol=1e-12)
    assert controller["law"] == "pd_gravity" and controller["robot"] == ROBOT
    (step,) = controller["steps"]
    assert all(step["joints"][j]["moving"] for j in JOINTS[ROBOT])
    report = (out / "report.md").read_text()
    for png in ("positions.png", "error.png", "torques.png", "torque_split.png"):
        assert (out / png).stat().st_size > 10_000 and f"]({png})" in report


def test_sigterm_mid_run_leaves_a_complete_readable_bag(make_loop, tmp_path):
    bag = tmp_path / "bag"
    loop = make_loop(ROBOT, record=bag)
    loop.start(JOINTS[ROBOT], [SETPOINTS[ROBOT]])
    loop.run_until(0.8)
    recorder = loop.group.nodes["recorder"]
    t_stop = loop.probe.latest_time()
    # the recorder has taken the states up to there (a loaded machine delays it: seen 0.35 s
    # of simulated time behind a lockstep loop); the loop runs on meanwhile
    seen = len(set(loop.probe.recording.stamps))
    loop.probe.spin_until(
        lambda: loop.recorded_counts().get("/joint_states", 0) >= seen,
        30.0,
        f"the recorder to hold the {seen} states up to t = {t_stop:.3f} s",
    )
    recorder.signal(signal.SIGTERM)
    assert recorder.proc.wait(timeout=15) == 0
    log = recorder.log()
    loop.close()
    assert "closed" in log, log

    for topics in (read_with_rosbags(bag), read_with_mcap(bag)):
        stamps = np.unique(joint_state_stamps(topics["/joint_states"]))
        # every step from the first to (nearly) the stop is there: nothing lost
        assert stamps[0] < 0.01
        assert stamps[-1] >= t_stop - 0.05
        np.testing.assert_allclose(np.diff(stamps), 1e-3, atol=1e-9)


def test_recorder_flush_answers_what_the_bag_holds(make_loop, tmp_path):
    """``~/flush`` counts what is written: once the runner's wait for the run's tail ends,
    the bag has every state the probe saw and every answer to them, as the counts said."""
    bag = tmp_path / "bag"
    loop = make_loop(ROBOT, record=bag, sim_params={"pause_at": 0.8})
    # ~/matched: before the run, each of its topics has its one publisher matched (the loop
    # waited for it)
    matched = json.loads(loop.probe.call_trigger("/recorder/matched").message)
    for name in ["/joint_states", "/effort_command", "/clock", "/reference", STATE_TOPIC]:
        assert matched[name] == 1, (name, matched)
    loop.start(JOINTS[ROBOT], [SETPOINTS[ROBOT]])
    loop.hold_at(0.8)
    loop.settle_recording()
    counts = loop.recorded_counts()
    seen = set(loop.probe.recording.stamps)
    loop.close()

    topics = read_with_rosbags(bag)
    in_bag = {name: len(messages) for name, messages in topics.items()}
    # the states 0 … 0.8 s, each in the bag; a state left unanswered 0.5 s of wall time is
    # sent again (republish_period), so the counts may hold one twice (at the probe, the
    # recorder, or both)
    assert len(seen) == 801
    assert {stamp_to_ns(m.header.stamp) for _, m in topics["/joint_states"]} == seen
    assert counts["/joint_states"] >= len(seen)
    for name in ["/joint_states", "/effort_command", "/clock", STATE_TOPIC]:
        assert in_bag[name] == counts[name], name
    assert in_bag["/effort_command"] >= len(seen)
