"""PD + gravity compensation in a real ROS 2 loop: sim_bridge + pd_gravity_controller as
separate processes in lockstep, checked against THEORY.md §2."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot

from .conftest import GAINS, JOINTS, SETPOINTS

pytestmark = pytest.mark.integration
ROBOTS = ["planar_2dof", "iiwa"]


def offset_residual(robot: str, q_e: np.ndarray, q_d: np.ndarray) -> np.ndarray:
    """g(q_e) − K_P (q_d − q_e): zero at the equilibrium of pure PD (predicted with an
    independent Pinocchio model of the same URDF)."""
    model = RobotModel(resolve_robot(robot))
    kp = np.array(GAINS[robot]["kp"])
    return model.gravity(q_e) - kp * (q_d - q_e)


@pytest.mark.parametrize("robot", ROBOTS)
def test_pd_gravity_converges_to_setpoint(make_loop, robot):
    loop = make_loop(robot, {"gravity_compensation": "full"})
    q_d = np.array(SETPOINTS[robot])
    loop.start(JOINTS[robot], [q_d])
    loop.run_until(6.0)
    q, dq = loop.final_state()
    assert np.max(np.abs(q_d - q)) < 1e-3, f"final error {q_d - q}"
    assert np.max(np.abs(dq)) < 1e-2


@pytest.mark.parametrize("robot", ROBOTS)
def test_pure_pd_settles_at_predicted_offset_then_full_gravity_removes_it(make_loop, robot):
    # held at 8 s (pause_at): the change applies from there, however far the loop would run
    # ahead of the probe
    loop = make_loop(robot, {"gravity_compensation": "none"}, sim_params={"pause_at": 8.0})
    q_d = np.array(SETPOINTS[robot])
    loop.start(JOINTS[robot], [q_d])
    loop.hold_at(8.0)
    q_e, dq = loop.final_state()
    assert np.max(np.abs(q_d - q_e)) > 1e-2, "pure PD should leave a visible offset"
    residual = offset_residual(robot, q_e, q_d)
    assert np.max(np.abs(residual)) < 1e-3, f"g(q_e) - K_P(q_d - q_e) = {residual}"

    results = loop.probe.set_parameters(loop.controller, {"gravity_compensation": "full"})
    assert results[0].successful, results[0].reason
    loop.resume()
    loop.run_until(16.0)
    q, _ = loop.final_state()
    assert np.max(np.abs(q_d - q)) < 1e-3, f"offset left after switching to full: {q_d - q}"


def test_invalid_parameter_updates_are_rejected_and_the_loop_keeps_running(make_loop):
    robot = "planar_2dof"
    loop = make_loop(robot, {"gravity_compensation": "full"})
    q_d = np.array(SETPOINTS[robot])
    loop.start(JOINTS[robot], [q_d])
    loop.run_until(1.0)
    bad_updates = [
        {"kp": -5.0},
        {"kp": [100.0, 100.0, 100.0]},
        {"kd": float("nan")},
        {"gravity_compensation": "sometimes"},
        {"ki": "high"},
    ]
    for update in bad_updates:
        (result,) = loop.probe.set_parameters(loop.controller, update)
        assert not result.successful, f"{update} was accepted"
        assert result.reason, f"{update} rejected without a reason"
    kp, kd, mode = loop.probe.get_parameters(loop.controller, ["kp", "kd", "gravity_compensation"])
    assert list(kp) == GAINS[robot]["kp"] and list(kd) == GAINS[robot]["kd"]
    assert mode == "full"
    (readonly,) = loop.probe.set_parameters(loop.controller, {"robot": "iiwa"})
    assert not readonly.successful
    loop.run_until(6.0)
    q, _ = loop.final_state()
    assert np.max(np.abs(q_d - q)) < 1e-3


def test_two_lockstep_runs_give_identical_trajectories(make_loop):
    runs = []
    for _ in range(2):
        loop = make_loop("planar_2dof", {"gravity_compensation": "full"})
        loop.start(JOINTS["planar_2dof"], [SETPOINTS["planar_2dof"]])
        loop.run_until(2.0)
        t, q, dq, tau = loop.probe.recording.arrays()
        loop.close()
        runs.append((t, q, dq, tau))
    (t1, q1, dq1, tau1), (t2, q2, dq2, tau2) = runs
    assert t1[-1] >= 2.0 and t2[-1] >= 2.0
    n = min(len(t1), len(t2))
    assert n > 1900, "the probe should have seen nearly every state"
    common, i1, i2 = np.intersect1d(t1, t2, return_indices=True)
    assert len(common) >= 0.99 * n
    np.testing.assert_array_equal(q1[i1], q2[i2])
    np.testing.assert_array_equal(dq1[i1], dq2[i2])
    np.testing.assert_array_equal(tau1[i1], tau2[i2])
    assert np.max(np.abs(q1[i1][-1] - q1[i1][0])) > 0.1, "the arm should have moved"
