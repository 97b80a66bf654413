"""How the controller nodes sample (issue 14, item 2): a control period longer than the
plant's state period (torque held over T_s in a lockstep loop), and joint states without
velocities (the law's q̇ estimated from the positions, or the state rejected when the
velocity must be measured)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sensor_msgs.msg import JointState

from joint_space_control.laws.velocity import FilteredDifference
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.ros.messages import stamp_to_ns

from .conftest import JOINTS
from .test_faults import MS, Rig, joint_state

pytestmark = pytest.mark.integration

ROBOT = "planar_2dof"
J = JOINTS[ROBOT]


def test_rate_below_the_state_rate_holds_the_torque_over_the_control_period(make_loop):
    """sim_bridge lockstep at 1 kHz, pd_gravity_controller with rate 100 Hz (ω_n = 10 rad/s,
    designed gains): every state is answered, the torque changes only at the states of the
    10 ms grid (the first state, then every tenth) and is constant over the 10 states of each
    period; /diagnostics reports the realised 10 ms; the arm still reaches the set-point."""
    loop = make_loop(ROBOT, {"kp": 0.0, "kd": 0.0, "omega_n": 10.0, "rate": 100.0})
    commands: dict[int, list[float]] = {}
    loop.probe.observe(
        JointState,
        "effort_command",
        lambda m: commands.setdefault(stamp_to_ns(m.header.stamp), list(m.effort)),
    )
    q_d = np.array([0.5, -0.3])
    loop.start(J, [q_d])
    loop.run_until(3.0)
    loop.pause()
    stamps = sorted(commands)
    assert stamps[0] == 0 and len(stamps) >= 3000
    assert np.all(np.diff(stamps) == MS)  # every 1 kHz state answered
    tau = np.array([commands[s] for s in stamps[:3000]]).reshape(300, 10, 2)
    # constant within each period, to the bit
    np.testing.assert_array_equal(tau, np.repeat(tau[:, :1, :], 10, axis=1))
    # and a new torque at each period while the arm moves (the first 0.5 s)
    assert np.all(np.any(np.diff(tau[:50, 0, :], axis=0) != 0.0, axis=1))
    status = loop.probe.wait_for_diagnostics(
        [f"{loop.controller}: control loop"], check=loop.group.check_alive
    )[f"{loop.controller}: control loop"]
    assert status["control_period"] == pytest.approx(0.01, abs=1e-9)
    q, _ = loop.final_state()
    assert np.max(np.abs(q - q_d)) < 1e-3


@pytest.fixture
def rig(tmp_path):
    r = Rig(tmp_path)
    try:
        yield r
    finally:
        r.close()


def test_states_without_velocity_use_the_filtered_difference_then_measured_rejects_them(rig):
    """pd_gravity_controller alone (kp, kd given) answering states without velocities along
    a ramp: each torque is g(q) + K_P(q_0 − q) − K_D q̇̂, q̇̂ the filtered difference over the
    stamps (computed here independently), to 1e-9 N·m; /diagnostics says filtered_difference.
    Switched to velocity_source=measured, such a state is rejected and counted, a state with
    velocities is answered."""
    node = "pd_gravity_controller"
    kp, kd = np.array([200.0, 100.0]), np.array([20.0, 10.0])
    rig.group.start(
        node, {"robot": ROBOT, "trigger": "state", "kp": kp.tolist(), "kd": kd.tolist()}
    )
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    rig.wait_for_publisher("/effort_command")

    def answer(stamp_ns: int) -> None:
        rig.probe.spin_until(
            lambda: rig.answered(stamp_ns), 20.0, f"command {stamp_ns}", rig.group.check_alive
        )

    model = RobotModel(resolve_robot(ROBOT))
    estimate = FilteredDifference(2, 50.0)
    q0 = np.array([0.1, -0.2])
    for k in range(12):
        t = (1 + k) * 1e-3 * (1 + (k > 6))  # a longer period from the 8th state on
        q = q0 + np.array([0.4, -0.3]) * (t - 1e-3)
        stamp = round(t * 1e9)
        msg = joint_state(stamp, q=q)
        msg.velocity = []
        states.publish(msg)
        answer(stamp)
        dq_hat = estimate.update(stamp * 1e-9, q)
        expected = model.gravity(q) + kp * (q0 - q) - kd * dq_hat
        np.testing.assert_allclose(dict(rig.commands)[stamp], expected, rtol=0, atol=1e-9)
    assert np.allclose(dq_hat, [0.4, -0.3], rtol=1e-9)  # the ramp's slope
    status = rig.diagnostics(node, lambda s: s["total.ticks"] >= 12)
    assert status["velocity"] == "filtered_difference"
    assert status["rejected.joint_states"] == 0

    (result,) = rig.probe.set_parameters(node, {"velocity_source": "measured"})
    assert result.successful, result.reason
    (result,) = rig.probe.set_parameters(node, {"velocity_cutoff": 0.0})
    assert not result.successful and "velocity_cutoff" in result.reason
    bare = joint_state(100 * MS, q=q0)
    bare.velocity = []
    rig.send(states, bare)
    states.publish(joint_state(101 * MS, q=q0, dq=(0.5, 0.0)))
    answer(101 * MS)
    assert not rig.answered(100 * MS)
    np.testing.assert_allclose(
        dict(rig.commands)[101 * MS],
        model.gravity(q0) + kp * (q0 - q0) - kd * np.array([0.5, 0.0]),
        rtol=0,
        atol=1e-9,
    )
    status = rig.diagnostics(node, lambda s: s["rejected.joint_states"] >= 1)
    assert status["rejected.joint_states"] == 1
    assert status["velocity"] == "measured"
    assert not math.isnan(status["control_period"])


def test_a_plant_that_does_not_measure_velocity_is_controlled_with_the_estimate(make_loop):
    """Lockstep sim_bridge with measure_velocity false (empty velocity arrays) and the
    inverse-dynamics controller with the defaults (velocity_source auto): it uses the
    filtered difference (/diagnostics), rejects no state, and the nominal step still
    settles on the set-point within 1e-4 rad in 3 s (ω_n = 10 rad/s, ζ = 1)."""
    loop = make_loop(
        ROBOT,
        {"kp": 0.0, "kd": 0.0, "omega_n": 10.0},
        controller="inverse_dynamics_controller",
        sim_params={"measure_velocity": False},
    )
    q_d = np.array([0.5, -0.3])
    loop.start(J, [q_d])
    loop.run_until(3.0)
    rec = loop.probe.recording
    assert rec.velocities and all(len(v) == 0 for v in rec.velocities)
    q, _ = loop.final_state()
    assert np.max(np.abs(q - q_d)) < 1e-4, f"final error {q_d - q}"
    name = f"{loop.controller}: control loop"
    status = loop.probe.wait_for_diagnostics([name], check=loop.group.check_alive)[name]
    assert status["velocity"] == "filtered_difference"
    assert status["rejected.joint_states"] == 0
