"""Commands as ros2_control takes them, and a robot that compensates gravity itself, with
no ROS graph: the command order, the command a gravity-compensating robot receives, the
holding command, joint states without (or with NaN) efforts, and the closed loop in process
with ``gravity_compensated_by_hardware`` on the controller and on the plant (THEORY.md §2)."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from joint_space_control.control.configure import PD_GRAVITY, command_order
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.ros.messages import JointOrder, joint_state_arrays
from joint_space_control.ros.wire import ForwardCommandImage, JointStateReader
from joint_space_control.simulation import simulate
from test.loops import GAINS, SETPOINTS

JOINTS = ("joint1", "joint2")


def test_command_joints_default_to_the_controlled_joints_and_may_permute_them():
    assert command_order(PD_GRAVITY.values(), JOINTS) == (0, 1)
    values = PD_GRAVITY.values(command_joints=["joint2", "joint1"])
    assert command_order(values, JOINTS) == (1, 0)


@pytest.mark.parametrize(
    "given, said",
    [
        (["joint1"], "missing ['joint2']"),
        (["joint1", "joint2", "joint3"], "unknown ['joint3']"),
        (["joint1", "joint1"], "duplicated ['joint1']"),
    ],
)
def test_command_joints_that_are_no_permutation_are_refused_with_one_line(given, said):
    with pytest.raises(ValueError) as err:
        command_order(PD_GRAVITY.values(command_joints=given), JOINTS)
    text = str(err.value)
    assert "'command_joints' must be a permutation" in text and said in text
    assert "\n" not in text


def test_the_forward_command_array_is_in_command_joints_order():
    image = ForwardCommandImage((1, 0))
    image.write(np.array([3.0, -7.5]))
    msg = deserialize_message(image.to_bytes(), Float64MultiArray)
    assert list(msg.data) == [-7.5, 3.0] and not msg.layout.dim


def _step(hardware: bool, q: np.ndarray):
    values = PD_GRAVITY.values(**GAINS["planar_2dof"], gravity_compensated_by_hardware=hardware)
    core = PD_GRAVITY.controller(values)
    return core, core.step(0.0, q, np.zeros(2))


def test_a_robot_that_adds_gravity_receives_the_law_torque_minus_g_and_state_is_unchanged():
    q = np.array([0.3, -0.4])
    plain_core, plain = _step(False, q)
    core, step = _step(True, q)
    g = RobotModel(resolve_robot("planar_2dof")).gravity(q)
    # the law, its split and its clamped torque (~/state) are the same
    np.testing.assert_array_equal(step.tau, plain.tau)
    np.testing.assert_array_equal(step.split.gravity, plain.split.gravity)
    np.testing.assert_array_equal(plain.sent, plain.tau)
    # the command leaves g(q) out: clamped first, then g subtracted
    np.testing.assert_allclose(step.sent, step.tau - g, rtol=0, atol=1e-12)
    # holding: g(q) clamped, or zeros where the robot adds it
    limits = plain_core.effort_limits
    np.testing.assert_allclose(plain_core.holding_torque(q), np.clip(g, -limits, limits))
    np.testing.assert_array_equal(core.holding_torque(q), np.zeros(2))


def test_clamping_applies_to_the_law_torque_before_gravity_is_taken_out():
    values = PD_GRAVITY.values(kp=[1e5, 1e5], kd=[0.0, 0.0], gravity_compensated_by_hardware=True)
    core = PD_GRAVITY.controller(values)
    core.step(0.0, np.zeros(2), np.zeros(2))  # holds where it starts
    q = np.array([0.3, -0.4])  # far from there: K_P (q_d - q) beyond the limits
    step = core.step(0.001, q, np.zeros(2))
    limits = core.effort_limits
    assert np.all(np.abs(step.unclamped) > limits)  # saturated
    np.testing.assert_array_equal(np.abs(step.tau), limits)
    g = core.config.model.gravity(q)
    np.testing.assert_allclose(step.sent, step.tau - g, rtol=0, atol=1e-12)


@pytest.mark.parametrize("effort", [[], [float("nan")] * 3, [1.0, float("nan"), 2.0]])
def test_joint_states_without_or_with_nan_efforts_are_read(effort):
    """The controller does not use the measured effort: a ros2_control robot without an
    effort state interface (joint_state_broadcaster publishes NaN there, or nothing) is
    read, in the fast path too (the second message of a layout)."""
    order = JointOrder(JOINTS)
    reader = JointStateReader(
        order, (0, 1), lambda m: joint_state_arrays(m, order), allow_extra=True, optional=(1,)
    )
    for k in range(3):
        msg = JointState(name=["extra", "joint2", "joint1"])
        msg.header.stamp.sec = k
        msg.position = [9.0, 0.2 + k, 0.1]
        msg.velocity = [0.0, -0.5, 0.5]
        msg.effort = list(effort)
        stamp, (q, dq) = reader.read(serialize_message(msg))
        assert stamp == k * 1_000_000_000
        np.testing.assert_array_equal(q, [0.1, 0.2 + k])
        np.testing.assert_array_equal(dq, [0.5, -0.5])


def _run(controller: bool, plant: bool, **parameters: object):
    return simulate(
        "planar_2dof",
        "pd_gravity",
        target=SETPOINTS["planar_2dof"],
        duration=parameters.pop("duration", 2.0),
        parameters={
            **GAINS["planar_2dof"],
            "gravity_compensated_by_hardware": controller,
            **parameters,
        },
        plant={"gravity_compensated_by_hardware": plant},
    )


def test_gravity_by_the_robot_moves_the_arm_as_gravity_by_the_controller():
    by_controller = _run(False, False)
    by_robot = _run(True, True)
    assert np.max(np.abs(by_robot.q - by_controller.q)) < 1e-9
    # the law and its split (~/state) as computed; the motors apply the same torque
    np.testing.assert_allclose(by_robot.tau_gravity, by_controller.tau_gravity, atol=1e-9)
    np.testing.assert_allclose(by_robot.tau_applied, by_controller.tau_applied, atol=1e-9)
    # what the robot received (the commands): the law's clamped torque minus g(q)
    g = np.array([RobotModel(resolve_robot("planar_2dof")).gravity(q) for q in by_robot.q])
    np.testing.assert_allclose(by_robot.tau, by_controller.tau - g, rtol=0, atol=1e-9)


def test_leaving_gravity_to_a_robot_that_does_not_add_it_sags_by_the_pure_pd_offset():
    """Only the controller's flag: the loop is pure PD, settling where
    K_P (q_d − q_e) = g(q_e) (THEORY.md §2)."""
    run = _run(True, False, duration=8.0)
    q_d = np.array(SETPOINTS["planar_2dof"])
    q_e = run.q[-1]
    assert np.max(np.abs(q_d - q_e)) > 1e-2, "the arm should sag"
    kp = np.array(GAINS["planar_2dof"]["kp"])
    residual = RobotModel(resolve_robot("planar_2dof")).gravity(q_e) - kp * (q_d - q_e)
    assert np.max(np.abs(residual)) < 1e-3, f"g(q_e) - K_P(q_d - q_e) = {residual}"
