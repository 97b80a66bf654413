"""sim_bridge with its imperfections switched on (docs/plant.md), as a real node process:
joint states without velocities, noisy positions whose spread is the σ asked for, and
wrench messages checked at the boundary. Each test leases its own ROS domain and stops
every process it starts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState

from .test_faults import ROBOT, Rig, rig  # noqa: F401  (the fixture)

pytestmark = pytest.mark.integration

SIGMA = 0.01  # [rad]
Q0 = np.array([0.3, -0.2])
STATES = 1500  # σ estimated within 2.2 % (1 standard error, Gaussian)


def wrench(frame_id: str, force=(0.0, 0.0, 0.0), torque=(0.0, 0.0, 0.0)) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.frame_id = frame_id
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = (float(v) for v in force)
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = (float(v) for v in torque)
    return msg


def test_noisy_positions_without_velocities_and_rejected_wrenches(rig: Rig):  # noqa: F811
    """Realtime, no controller: the brakes hold the arm at Q0 (to ~1e-4 rad), the published
    positions scatter around it with standard deviation σ (within 10 %: 1500 states give
    2.2 % standard error) and mean within 4σ/√N + 1e-3 rad, every joint state has an empty
    velocity array; a wrench on an unknown link and a non-finite one are rejected and
    counted, a valid one is not."""
    rig.group.start(
        "sim_bridge",
        {
            "robot": ROBOT,
            "mode": "realtime",
            "initial_positions": Q0.tolist(),
            "measure_velocity": False,
            "position_noise": SIGMA,
            "velocity_noise": 1.0,  # not measured: nothing to add it to
            "noise_seed": 7,
        },
    )
    probe = rig.probe
    probe.spin_until(
        lambda: len(probe.recording.stamps) >= STATES, 60.0, "joint states", rig.group.check_alive
    )
    rec = probe.recording
    assert all(len(v) == 0 for v in rec.velocities)
    assert all(
        len(q) == 2 and len(e) == 2 for q, e in zip(rec.positions, rec.efforts, strict=True)
    )
    q = np.array(rec.positions[:STATES])
    spread = q.std(axis=0)
    np.testing.assert_allclose(spread, SIGMA, rtol=0.10)
    np.testing.assert_allclose(q.mean(axis=0), Q0, atol=4 * SIGMA / math.sqrt(STATES) + 1e-3)

    wrenches = rig.publisher(WrenchStamped, "/sim_bridge/wrench")
    rig.send(wrenches, wrench("no_such_link", force=(0.0, 0.0, -10.0)))
    rig.send(wrenches, wrench("link2", force=(0.0, math.nan, 0.0)))
    rig.send(wrenches, wrench("link2", force=(0.0, 0.0, -10.0)))
    rig.send(wrenches, wrench(""))  # zero: removes it
    rig.diagnostics("sim_bridge", lambda s: s["rejected.wrenches"] >= 2)
    probe.spin_for(1.5)  # diagnostics come once a second: one sent after the last wrench
    status = rig.diagnostics("sim_bridge", lambda s: True)
    assert status["rejected.wrenches"] == 2
    assert status["rejected.commands"] == 0
    log = rig.group.nodes["sim_bridge"].log()
    assert "rejected wrench: no moving link 'no_such_link'" in log
    assert "Traceback" not in log


def test_lockstep_state_sent_again_carries_the_same_measurement(rig: Rig):  # noqa: F811
    """Lockstep, nobody answering: the true state (exactly Q0, at rest) is published on
    sim_bridge/true_joint_states beside the measurement; the state at t = 0 is sent again
    every republish_period with the same noisy, quantized positions (one measurement per
    simulation instant, so a run does not depend on how often a state had to be sent), each
    a whole number of counts Δ = 2π/1000, and differing from the true Q0 (the noise is on).
    Invalid updates of the new parameters are refused with their name, valid ones accepted."""
    rig.group.start(
        "sim_bridge",
        {
            "robot": ROBOT,
            "mode": "lockstep",
            "initial_positions": Q0.tolist(),
            "encoder_counts": 1000,
            "position_noise": 0.05,
            "velocity_noise": 0.05,
            "republish_period": 0.2,
        },
    )
    probe = rig.probe
    truth: list = []
    probe.observe(JointState, "/sim_bridge/true_joint_states", truth.append)
    probe.spin_until(
        lambda: len(probe.recording.stamps) >= 3 and truth,
        30.0,
        "three sends",
        rig.group.check_alive,
    )
    rec = probe.recording
    assert set(rec.stamps) == {0}
    # the true state beside the measurement: exactly Q0 at rest, same stamp
    np.testing.assert_array_equal(truth[0].position, Q0)
    np.testing.assert_array_equal(truth[0].velocity, [0.0, 0.0])
    assert (truth[0].header.stamp.sec, truth[0].header.stamp.nanosec) == (0, 0)
    for row in (rec.positions, rec.velocities):
        assert all(r == row[0] for r in row)
    counts = np.array(rec.positions[0]) / (2 * math.pi / 1000)
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-9)
    assert not np.allclose(rec.positions[0], Q0, atol=1e-3)
    assert rec.velocities[0] != [0.0, 0.0]

    assert probe.set_parameters("sim_bridge", {"coulomb_friction": 5.0})[0].successful
    for values, what in [
        ({"static_friction": 1.0}, "static_friction"),  # below F_c
        ({"wrench_link": "no_such_link"}, "wrench_link"),
        ({"wrench_force": [1.0, 2.0]}, "wrench_force"),
        ({"wrench_profile": "ramp"}, "wrench_profile"),
        ({"encoder_counts": -1.0}, "encoder_counts"),
        ({"position_noise": [0.1, 0.1, 0.1]}, "position_noise"),
        ({"noise_seed": -3}, "noise_seed"),
    ]:
        result = probe.set_parameters("sim_bridge", values)[0]
        assert not result.successful and what in result.reason, (values, result.reason)
    result = probe.set_parameters("sim_bridge", {"measure_velocity": False})[0]
    assert not result.successful  # read-only: the message layout is fixed at start
    valid = {
        "coulomb_friction": [5.0, 3.0],
        "static_friction": 6.0,
        "wrench_link": "link1",
        "wrench_force": [0.0, 0.0, -10.0],
        "wrench_profile": "sinusoid",
        "wrench_frequency": 2.0,
        "noise_seed": 3,
    }
    assert all(r.successful for r in probe.set_parameters("sim_bridge", valid))
