"""Effort and torque-rate limits (no ROS), and the plant applying the rate limit."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.laws.limits import beyond_bound, joints_beyond, limit_rate, rate_steps
from joint_space_control.model.robots import resolve_robot
from sim_bridge.plant import Plant


def test_rate_steps_zero_means_unlimited():
    np.testing.assert_array_equal(rate_steps(np.array([0.0, 500.0]), 1e-3), [np.inf, 0.5])


@pytest.mark.parametrize("bad", [[-1.0], [np.nan], [np.inf]])
def test_rate_steps_reject_invalid_rates(bad):
    with pytest.raises(ValueError, match="torque rates"):
        rate_steps(np.array(bad), 1e-3)


def test_limit_rate_moves_at_most_the_step_and_exactly_to_targets_in_reach():
    previous = np.array([0.0, 10.0, 5.0, -3.0])
    target = np.array([100.0, -100.0, 5.2, 0.1])
    step = np.array([1.0, 2.0, 0.5, np.inf])
    out = limit_rate(target, previous, step)
    np.testing.assert_array_equal(out, [1.0, 8.0, 5.2, 0.1])  # 5.2 and 0.1 exactly


def test_plant_ramps_a_torque_step_at_the_rate_limit_then_holds_it():
    plant = Plant(resolve_robot("planar_2dof"), ("joint1", "joint2"), 1000.0)
    try:
        plant.set_torque_rate_limit([1000.0, 0.0])  # 1 N·m per 1 ms step on joint1 only
        efforts = []
        for _ in range(5):
            plant.step(np.array([500.0, -300.0]), substeps=2)
            efforts.append(plant.state().effort.copy())
        # two physics steps per command: +2 N·m per command on joint1, joint2 unlimited
        np.testing.assert_allclose([e[0] for e in efforts], [2.0, 4.0, 6.0, 8.0, 10.0])
        assert all(e[1] == -300.0 for e in efforts)
        plant.set_torque_rate_limit(0.0)  # off: the command is applied as is
        plant.step(np.array([500.0, -300.0]))
        np.testing.assert_array_equal(plant.state().effort, [500.0, -300.0])
    finally:
        plant.close()


def test_plant_rate_limit_starts_from_the_braking_torque():
    """After braking, the first commands are ramped from the torque the brakes applied
    (no jump when a controller takes over)."""
    plant = Plant(
        resolve_robot("planar_2dof"), ("joint1", "joint2"), 1000.0, initial_positions=[0.3, -0.2]
    )
    try:
        plant.brake(substeps=300)
        braking = plant.state().effort.copy()
        assert np.max(np.abs(braking)) > 100.0  # carrying gravity
        plant.set_torque_rate_limit(2000.0)  # 2 N·m per step
        plant.step(np.zeros(2))
        applied = plant.state().effort
        np.testing.assert_allclose(np.abs(applied - braking), np.minimum(np.abs(braking), 2.0))
    finally:
        plant.close()


def test_plant_rejects_invalid_rate_limits():
    plant = Plant(resolve_robot("planar_2dof"), ("joint1", "joint2"), 1000.0)
    try:
        with pytest.raises(ValueError):
            plant.set_torque_rate_limit([-1.0, 0.0])
    finally:
        plant.close()


def test_beyond_bound_is_a_multiple_of_the_limits_and_never_for_unlimited_joints():
    limits = np.array([2000.0, 1000.0, np.inf])
    assert not beyond_bound(np.array([4000.0, -2000.0, 1e300]), limits, 2.0)  # at the bound
    assert beyond_bound(np.array([4000.1, 0.0, 0.0]), limits, 2.0)
    assert beyond_bound(np.array([0.0, -2000.1, 0.0]), limits, 2.0)
    assert not beyond_bound(np.array([2500.0, 0.0, 0.0]), limits, 2.0)  # clamped, not rejected
    assert beyond_bound(np.array([2500.0, 0.0, 0.0]), limits, 1.0)


def test_joints_beyond_names_each_joint_with_its_torque_and_limit():
    limits = np.array([50.0, 50.0, np.inf])
    names = ("right_s0", "right_s1", "free")
    assert joints_beyond(np.array([10.0, -212.0, 1e9]), limits, names) == (
        "right_s1 -212 N·m (limit 50)"
    )
    assert joints_beyond(np.array([120.0, -101.0, 0.0]), limits, names, 2.0) == (
        "right_s0 120 N·m (limit 50), right_s1 -101 N·m (limit 50)"
    )
    assert joints_beyond(np.array([50.0, -50.0, 1e300]), limits, names) == ""  # at the limit
