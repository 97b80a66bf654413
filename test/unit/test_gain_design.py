"""Gains from a natural frequency and a damping ratio, the controllers' gain precedence, and
the trigger a plant's mode asks for (laws/gains.py, ros/plant_mode.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.laws.gains import (
    DEFAULT_OMEGA_N,
    DEFAULT_ZETA,
    FROM_DEFAULT,
    FROM_KP,
    FROM_OMEGA_N,
    choose_gains,
    inverse_dynamics_gains,
    pd_gains_from_second_order,
)
from joint_space_control.laws.second_order import gains_to_second_order
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.ros.plant_mode import declared_realtime, trigger_for


def closed_loop_second_order(b: float, kp: float, kd: float) -> tuple[float, float]:
    """(ω_n, ζ) of B q̈ + K_D q̇ + K_P q = 0 from the eigenvalues of its state matrix."""
    a = np.array([[0.0, 1.0], [-kp / b, -kd / b]])
    lam = np.linalg.eigvals(a)
    omega = math.sqrt(abs(np.prod(lam)))  # λ₁λ₂ = ω_n²
    zeta = -float(np.sum(lam).real) / (2.0 * omega)  # λ₁ + λ₂ = −2ζω_n
    return omega, zeta


@pytest.mark.parametrize("b", [1e-3, 0.37, 22.5, 145.0, 4e3])
@pytest.mark.parametrize(("omega_n", "zeta"), [(10.0, 1.0), (3.0, 0.3), (40.0, 0.7)])
def test_one_dof_pd_design_has_the_asked_natural_frequency_and_damping(b, omega_n, zeta):
    gains = pd_gains_from_second_order([b], omega_n, zeta)
    omega, damping = closed_loop_second_order(b, gains.kp[0], gains.kd[0])
    assert omega == pytest.approx(omega_n, rel=1e-9)
    assert damping == pytest.approx(zeta, rel=1e-9, abs=1e-12)
    # the same as the inverse-dynamics loop once divided by the inertia
    w, z = gains_to_second_order(gains.kp / b, gains.kd / b)
    np.testing.assert_allclose([w[0], z[0]], [omega_n, zeta], rtol=1e-12)


def test_pd_design_scales_with_the_inertia_of_each_joint():
    b = np.array([145.0, 22.5])
    gains = pd_gains_from_second_order(b, [10.0, 20.0], [1.0, 0.5], ki=[1.0, 0.0])
    np.testing.assert_allclose(gains.kp, b * np.array([100.0, 400.0]))
    np.testing.assert_allclose(gains.kd, b * np.array([20.0, 20.0]))
    np.testing.assert_array_equal(gains.ki, [1.0, 0.0])
    with pytest.raises(ValueError, match="inertia"):
        pd_gains_from_second_order([1.0, 0.0], 10.0, 1.0)
    with pytest.raises(ValueError, match="omega_n"):
        pd_gains_from_second_order([1.0], -1.0, 1.0)


def test_pd_design_on_the_planar_arm_at_its_start_configuration():
    model = RobotModel(resolve_robot("planar_2dof"))
    q0 = np.zeros(2)
    b = np.diag(model.inertia(q0))
    # B11(0) = I1 + m lc² + I2 + m (a1² + lc² + 2 a1 lc) = 145, B22 = I2 + m lc² = 22.5
    np.testing.assert_allclose(b, [145.0, 22.5], rtol=1e-9)
    gains = pd_gains_from_second_order(b, DEFAULT_OMEGA_N, DEFAULT_ZETA)
    np.testing.assert_allclose(gains.kp, [14500.0, 2250.0], rtol=1e-9)
    np.testing.assert_allclose(gains.kd, [2900.0, 450.0], rtol=1e-9)


@pytest.mark.parametrize("b", [1e-4, 1.0, 1e4])
@pytest.mark.parametrize("rate", [1000.0, 100.0])
def test_default_design_is_stable_sampled_whatever_the_inertia(b, rate):
    """B q̈ = u, u held for T_s from the sampled (q, q̇): the sampled closed loop with the
    default design has its poles inside the unit circle, and where the continuous design puts
    them (e^{λT_s}) to within a few per cent."""
    ts = 1.0 / rate
    gains = pd_gains_from_second_order([b], DEFAULT_OMEGA_N, DEFAULT_ZETA)
    phi = np.array([[1.0, ts], [0.0, 1.0]])
    gamma = np.array([[ts * ts / (2.0 * b)], [ts / b]])
    k = np.array([[gains.kp[0], gains.kd[0]]])
    radius = max(abs(np.linalg.eigvals(phi - gamma @ k)))
    assert radius < 1.0
    # critically damped: both continuous poles at −ω_n
    assert radius == pytest.approx(math.exp(-DEFAULT_OMEGA_N * ts), rel=0.05)


def test_inverse_dynamics_gains_are_the_second_order_ones():
    gains = inverse_dynamics_gains([8.0, 12.0], [0.5, 0.8], 2)
    np.testing.assert_allclose(gains.kp, [64.0, 144.0])
    np.testing.assert_allclose(gains.kd, [8.0, 19.2])


def test_gain_precedence_omega_n_then_kp_then_the_default():
    both = choose_gains(2, [2000.0, 1000.0], [900.0, 300.0], [8.0, 12.0], [0.5, 0.8])
    assert both.source == FROM_OMEGA_N and both.designed
    np.testing.assert_array_equal(both.omega_n, [8.0, 12.0])
    np.testing.assert_array_equal(both.zeta, [0.5, 0.8])
    given = choose_gains(2, [2000.0, 1000.0], [900.0, 300.0], 0.0, 1.0)
    assert given.source == FROM_KP and not given.designed
    np.testing.assert_array_equal(given.kp, [2000.0, 1000.0])
    np.testing.assert_array_equal(given.kd, [900.0, 300.0])
    kp_only = choose_gains(2, 50.0, 0.0, 0.0, 1.0)  # K_D = 0 is a valid choice
    assert kp_only.source == FROM_KP
    np.testing.assert_array_equal(kp_only.kd, [0.0, 0.0])
    nothing = choose_gains(3, 0.0, 0.0, 0.0, 0.7)
    assert nothing.source == FROM_DEFAULT and nothing.designed
    np.testing.assert_array_equal(nothing.omega_n, [DEFAULT_OMEGA_N] * 3)
    np.testing.assert_array_equal(nothing.zeta, [0.7] * 3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"kd": 10.0}, "'kd' .* is given without 'kp'"),
        ({"kd": 10.0, "omega_n": 5.0}, "'kd' .* is given without 'kp'"),
        ({"kp": [100.0, 0.0]}, "'kp' must be > 0 on every joint"),
        ({"omega_n": [10.0, 0.0]}, "'omega_n' must be > 0 on every joint"),
        ({"kp": -5.0}, "'kp' must be >= 0"),
        ({"omega_n": -3.0}, "'omega_n' must be >= 0"),
        ({"zeta": -0.5}, "'zeta' must be >= 0"),
        ({"kd": math.nan, "kp": 1.0}, "'kd' must be finite"),
        ({"omega_n": [10.0, 10.0, 10.0]}, "'omega_n' needs 1 or 2 values, got 3"),
    ],
)
def test_gain_choice_rejects_with_one_reason(kwargs, match):
    values = {"kp": 0.0, "kd": 0.0, "omega_n": 0.0, "zeta": 1.0, **kwargs}
    with pytest.raises(ValueError, match=match):
        choose_gains(2, **values)


def test_trigger_follows_the_mode_of_the_joint_state_publishers():
    sim, other = ("/", "sim_bridge", b"1"), ("/", "probe", b"2")
    assert trigger_for({}, frozenset()) is None  # nobody publishes yet
    assert trigger_for({}, frozenset({sim})) is None  # asked, no answer yet
    assert trigger_for({sim: "lockstep"}, frozenset({sim, other})) == "state"
    assert trigger_for({sim: "realtime"}, frozenset({sim, other})) is None
    assert trigger_for({sim: "realtime", other: ""}, frozenset({sim, other})) == "timer"
    assert trigger_for({other: ""}, frozenset({other})) == "timer"  # no mode: not lockstep


def test_a_plant_is_realtime_only_when_every_publisher_says_so():
    sim, other = ("/", "sim_bridge", b"1"), ("/", "probe", b"2")
    assert not declared_realtime({}, frozenset())  # nobody publishes
    assert not declared_realtime({}, frozenset({sim}))  # no answer yet
    assert declared_realtime({sim: "realtime"}, frozenset({sim}))
    assert not declared_realtime({sim: "lockstep"}, frozenset({sim}))
    assert not declared_realtime({other: ""}, frozenset({other}))  # no mode: a test's states
    assert not declared_realtime({sim: "realtime", other: ""}, frozenset({sim, other}))
