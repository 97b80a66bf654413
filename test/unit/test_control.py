"""The controller objects without ROS (joint_space_control.control): reference schedule,
restart, gain design at the first measured configuration, the non-finite gate, the clamp."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.control.inverse_dynamics import (
    IDConfig,
    InverseDynamicsController,
    gains_from_choice,
)
from joint_space_control.control.pd_gravity import PDConfig, PDGravityController
from joint_space_control.laws.gains import PDGains, choose_gains, pd_gains_from_second_order
from joint_space_control.laws.inverse_dynamics import ModelLaw
from joint_space_control.laws.pd_gravity import GravityCompensation
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.trajectories.reference import Trajectory


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel(resolve_robot("planar_2dof"))


def pd(model: RobotModel, kp=0.0, kd=0.0, omega_n=0.0, ki=0.0) -> PDGravityController:
    n, zero = model.n, np.zeros(model.n)
    choice = choose_gains(n, kp, kd, omega_n, 1.0)
    ki = np.full(n, ki)
    gains = None if choice.designed else PDGains.build(n, choice.kp, choice.kd, ki)
    config = PDConfig(model, gains, GravityCompensation.FULL, zero, choice, ki)
    return PDGravityController(config, model.effort_limits)


def test_holds_the_first_configuration_then_follows_scheduled_trajectories(model):
    c = pd(model, kp=2000.0, kd=300.0)
    q0, dq = np.array([0.3, -0.2]), np.zeros(2)
    first = c.step(0.0, q0, dq)
    np.testing.assert_array_equal(first.ref.q, q0)  # holds where it started
    # PD + g(q) at the set-point, at rest: τ = g(q)
    np.testing.assert_allclose(first.unclamped, model.gravity(q0), rtol=1e-12)
    c.add_trajectory(Trajectory.build(1.0, np.array([0.0]), np.array([[0.5, 0.1]])))
    np.testing.assert_array_equal(c.step(0.5, q0, dq).ref.q, q0)  # not started yet
    np.testing.assert_array_equal(c.step(1.0, q0, dq).ref.q, [0.5, 0.1])
    later = c.step(2.0, q0, dq)
    np.testing.assert_array_equal(later.ref.q, [0.5, 0.1])
    expected = model.gravity(q0) + 2000.0 * (np.array([0.5, 0.1]) - q0)
    np.testing.assert_allclose(later.unclamped, expected, rtol=1e-12)
    limits = model.effort_limits
    np.testing.assert_array_equal(later.tau, np.clip(expected, -limits, limits))


def test_default_gains_are_designed_at_the_first_state_and_again_after_a_restart(model):
    c = pd(model)  # nothing given: ω_n = 10 rad/s, ζ = 1
    assert c.gains_pending
    q0 = np.array([0.3, -0.2])
    c.step(0.0, q0, np.zeros(2))
    expected = pd_gains_from_second_order(np.diag(model.inertia(q0)), 10.0, 1.0)
    np.testing.assert_allclose(c.config.gains.kp, expected.kp, rtol=1e-12)
    np.testing.assert_allclose(c.config.gains.kd, expected.kd, rtol=1e-12)
    c.restart()
    assert c.gains_pending and c.q0 is None
    q1 = np.array([-1.0, 0.8])
    c.step(5.0, q1, np.zeros(2))
    again = pd_gains_from_second_order(np.diag(model.inertia(q1)), 10.0, 1.0)
    np.testing.assert_allclose(c.config.gains.kp, again.kp, rtol=1e-12)
    assert not np.allclose(again.kp, expected.kp)  # the configuration mattered
    # a new configuration (another ω_n) is designed at the same start configuration
    c.set_config(pd(model, omega_n=20.0).config)
    np.testing.assert_allclose(c.config.gains.kp, 4.0 * again.kp, rtol=1e-12)


def test_integral_is_reset_by_a_restart_and_not_integrated_across_a_non_finite_step(model):
    c = pd(model, kp=100.0, kd=10.0, ki=50.0)
    q = np.array([0.3, -0.2])
    c.step(0.0, q, np.zeros(2))
    c.add_trajectory(Trajectory.build(0.0, np.array([0.0]), np.array([[0.4, -0.1]])))
    for k in range(1, 11):
        c.step(k * 1e-3, q, np.zeros(2))
    assert np.all(c._integral > 0)
    bad = c.step(0.011, q, np.array([np.nan, 0.0]))
    assert bad.tau is None and not np.isfinite(bad.unclamped).all()
    c.restart()
    np.testing.assert_array_equal(c._integral, 0.0)


def test_inverse_dynamics_object_is_the_law_clamped(model):
    n = model.n
    choice = choose_gains(n, 0.0, 0.0, 8.0, 0.5)
    config = IDConfig(model, gains_from_choice(choice, n), ModelLaw.INVERSE_DYNAMICS, choice)
    c = InverseDynamicsController(config, np.array([5.0, 5.0]))
    q, dq = np.array([0.3, -0.2]), np.array([0.1, 0.0])
    c.step(0.0, q, dq)
    c.add_trajectory(Trajectory.build(0.0, np.array([0.0]), np.array([[0.4, -0.1]])))
    step = c.step(1.0, q, dq)
    y = 64.0 * (step.ref.q - q) + 8.0 * (step.ref.dq - dq) + step.ref.ddq
    np.testing.assert_allclose(step.unclamped, model.rnea(q, dq, y), rtol=1e-10)
    np.testing.assert_array_equal(step.tau, np.clip(step.unclamped, -5.0, 5.0))
    assert np.any(np.abs(step.unclamped) > 5.0)  # the clamp acted
