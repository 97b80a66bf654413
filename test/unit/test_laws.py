"""PD control with gravity compensation and its variants (THEORY.md §2).

τ = ĝ + K_P (q_d − q) − K_D q̇ + K_I ξ,      ξ̇ = q_d − q
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.pd_gravity import (
    GravityCompensation,
    TorqueSplit,
    integrate_error,
    pid_torque_split,
)
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot


def pd_gravity(
    q: np.ndarray, dq: np.ndarray, q_des: np.ndarray, gains: PDGains, gravity: np.ndarray
) -> np.ndarray:
    """The PD + ĝ torque as the controller computes it with no integral (ξ = 0)."""
    return pid_torque_split(q, dq, q_des, np.zeros_like(q), gains, gravity).total


@pytest.fixture(scope="module")
def planar() -> RobotModel:
    return RobotModel(resolve_robot("planar_2dof"))


# -- the PD + gravity law ------------------------------------------------------------------


def test_at_the_set_point_at_rest_the_torque_is_gravity(planar):
    gains = PDGains.build(2, [300.0, 100.0], [30.0, 10.0])
    for q in np.random.default_rng(1).uniform(-np.pi, np.pi, size=(10, 2)):
        g = planar.gravity(q)
        np.testing.assert_array_equal(pd_gravity(q, np.zeros(2), q, gains, g), g)


def pure_pd_equilibrium(model: RobotModel, q_des: np.ndarray, kp: np.ndarray) -> np.ndarray:
    """q_e with g(q_e) = K_P (q_d − q_e), by Newton on f(q) = g(q) − K_P (q_d − q).

    The Jacobian ∂g/∂q + K_P uses a central difference of g (h = 1e-6); an approximate
    Jacobian only slows Newton down, the residual itself is exact."""
    q = q_des.copy()
    h = 1e-6
    for _ in range(20):
        f = model.gravity(q) - kp * (q_des - q)
        jac = np.column_stack(
            [(model.gravity(q + h * e) - model.gravity(q - h * e)) / (2 * h) for e in np.eye(2)]
        ) + np.diag(kp)
        q = q - np.linalg.solve(jac, f)
    return q


def test_pure_pd_settles_where_gravity_balances_the_spring(planar):
    """THEORY.md §2: without ĝ the arm rests at q_e with g(q_e) = K_P (q_d − q_e)."""
    gains = PDGains.build(2, [3000.0, 1500.0], [100.0, 50.0])
    q_des = np.array([0.4, -0.3])
    q_e = pure_pd_equilibrium(planar, q_des, gains.kp)
    # the offset is real (heavy arm) and the arm sags: g > 0 here, so q_e < q_d
    assert np.max(np.abs(q_e - q_des)) > 0.05
    assert np.all(planar.gravity(q_e) > 0) and np.all(q_e < q_des)
    tau = pd_gravity(q_e, np.zeros(2), q_des, gains, np.zeros(2))
    np.testing.assert_allclose(tau - planar.gravity(q_e), 0.0, atol=1e-9)
    # with gravity compensation the same state is not an equilibrium
    tau_full = pd_gravity(q_e, np.zeros(2), q_des, gains, planar.gravity(q_e))
    assert np.max(np.abs(tau_full - planar.gravity(q_e))) > 10.0


def test_pure_pd_offset_shrinks_with_kp(planar):
    q_des = np.array([0.4, -0.3])
    offsets = [
        np.linalg.norm(q_des - pure_pd_equilibrium(planar, q_des, np.array([kp, kp])))
        for kp in (2000.0, 4000.0, 8000.0)
    ]
    assert offsets[0] > offsets[1] > offsets[2] > 0


# -- PID split and anti-windup -------------------------------------------------------------


def test_pid_split_parts_add_up():
    rng = np.random.default_rng(2)
    gains = PDGains.build(3, [100.0, 200.0, 300.0], [10.0, 5.0, 1.0], [50.0, 0.0, 20.0])
    q, dq, q_des, xi, g = (rng.uniform(-1, 1, 3) for _ in range(5))
    split = pid_torque_split(q, dq, q_des, xi, gains, g)
    assert isinstance(split, TorqueSplit)
    np.testing.assert_array_equal(split.gravity, g)
    np.testing.assert_array_equal(split.model, np.zeros(3))
    np.testing.assert_array_equal(split.total, split.feedback + split.gravity)
    np.testing.assert_allclose(
        split.total, g + gains.kp * (q_des - q) - gains.kd * dq + gains.ki * xi, atol=1e-12
    )
    # the integral contributes K_I ξ to the feedback part only
    without = pid_torque_split(q, dq, q_des, np.zeros(3), gains, g)
    np.testing.assert_allclose(split.feedback - without.feedback, gains.ki * xi, atol=1e-12)
    assert split.feedback[1] == without.feedback[1]  # ki = 0 on joint 2


LIMITS = np.array([100.0, 100.0])
GAINS_I = PDGains.build(2, 100.0, 10.0, 20.0)
DT = 1e-3


def test_integrate_error_unsaturated():
    xi = np.array([0.1, -0.2])
    error = np.array([0.5, -0.25])
    out = integrate_error(xi, error, DT, GAINS_I, np.array([10.0, -50.0]), LIMITS)
    np.testing.assert_allclose(out, xi + error * DT, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(xi, [0.1, -0.2])  # a new array, input untouched
    assert out is not xi


@pytest.mark.parametrize("tau_sign", [1.0, -1.0])
def test_integrate_error_stops_when_saturated_in_the_error_direction(tau_sign):
    xi = np.array([0.1, 0.1])
    error = tau_sign * np.array([0.5, 0.5])  # pushes the command further the same way
    tau = tau_sign * np.array([150.0, 100.0])  # beyond, and exactly at, the limit
    out = integrate_error(xi, error, DT, GAINS_I, tau, LIMITS)
    np.testing.assert_array_equal(out, xi)


def test_integrate_error_integrates_out_of_saturation():
    xi = np.array([0.1, 0.1])
    error = np.array([-0.5, 0.5])  # opposes the saturated command: brings it back
    tau = np.array([150.0, -150.0])
    out = integrate_error(xi, error, DT, GAINS_I, tau, LIMITS)
    np.testing.assert_allclose(out, xi + error * DT, rtol=0, atol=1e-15)


def test_integrate_error_clamps_the_integral_torque():
    big = np.array([100.0, -100.0])
    out = integrate_error(big, np.array([1.0, -1.0]), DT, GAINS_I, np.zeros(2), LIMITS)
    np.testing.assert_allclose(GAINS_I.ki * out, [100.0, -100.0], rtol=1e-15)
    # per-joint limits and gains
    gains = PDGains.build(2, 100.0, 10.0, [10.0, 40.0])
    limits = np.array([50.0, 20.0])
    out = integrate_error(
        np.array([4.9, 0.4]), np.array([1000.0, 1000.0]), DT, gains, 0 * big, limits
    )
    np.testing.assert_allclose(out, [5.0, 0.5], rtol=1e-15)
    assert np.all(np.abs(gains.ki * out) <= limits * (1 + 1e-15))


def test_integrate_error_without_ki_keeps_zero():
    gains = PDGains.build(2, 100.0, 10.0, [0.0, 5.0])
    out = integrate_error(
        np.array([3.0, 0.0]), np.array([1.0, 1.0]), DT, gains, np.zeros(2), LIMITS
    )
    assert out[0] == 0.0
    assert out[1] == pytest.approx(DT)


def test_integrate_error_with_infinite_limits():
    out = integrate_error(
        np.zeros(2), np.array([1.0, -2.0]), DT, GAINS_I, np.array([1e9, -1e9]), np.full(2, np.inf)
    )
    np.testing.assert_allclose(out, [DT, -2 * DT], rtol=1e-15)


# -- gains -------------------------------------------------------------------------------


def test_gains_broadcast_and_are_read_only():
    gains = PDGains.build(3, 100.0, 10.0)
    np.testing.assert_array_equal(gains.kp, [100.0] * 3)
    np.testing.assert_array_equal(gains.kd, [10.0] * 3)
    np.testing.assert_array_equal(gains.ki, [0.0] * 3)
    for arr in (gains.kp, gains.kd, gains.ki):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0
    gains = PDGains.build(2, [1.0, 2.0], [0.0, 3.0], [4.0, 0.0])
    np.testing.assert_array_equal(gains.kp, [1.0, 2.0])
    np.testing.assert_array_equal(gains.kd, [0.0, 3.0])
    np.testing.assert_array_equal(gains.ki, [4.0, 0.0])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"kp": 0.0, "kd": 1.0}, "'kp' must be > 0"),
        ({"kp": [1.0, 0.0], "kd": 1.0}, "'kp' must be > 0"),
        ({"kp": -1.0, "kd": 1.0}, "'kp'"),
        ({"kp": 1.0, "kd": -1.0}, "'kd' must be >= 0"),
        ({"kp": 1.0, "kd": 1.0, "ki": -0.1}, "'ki' must be >= 0"),
        ({"kp": math.nan, "kd": 1.0}, "'kp' must be finite"),
        ({"kp": 1.0, "kd": math.inf}, "'kd' must be finite"),
        ({"kp": 1.0, "kd": 1.0, "ki": [math.nan, 1.0]}, "'ki' must be finite"),
        ({"kp": [1.0, 2.0, 3.0], "kd": 1.0}, "'kp' needs 1 or 2 values, got 3"),
        ({"kp": 1.0, "kd": []}, "'kd' needs 1 or 2 values, got 0"),
    ],
)
def test_gains_reject_invalid(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PDGains.build(2, **kwargs)


def test_gains_do_not_alias_the_callers_array():
    kp = np.array([100.0, 200.0])
    gains = PDGains.build(2, kp, 10.0)
    kp[0] = -5.0
    np.testing.assert_array_equal(gains.kp, [100.0, 200.0])


def test_gravity_compensation_parse():
    assert GravityCompensation.parse("full") is GravityCompensation.FULL
    assert GravityCompensation.parse("none") is GravityCompensation.NONE
    assert GravityCompensation.parse("desired") is GravityCompensation.DESIRED
    for bad in ("Full", "constant", ""):
        with pytest.raises(ValueError, match=rf"'{bad}' is not one of: full, none, desired"):
            GravityCompensation.parse(bad)


# -- property: finite and linear ------------------------------------------------------------

N = 3
box = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
vectors = arrays(np.float64, N, elements=box)
kp_values = arrays(np.float64, N, elements=st.floats(1e-3, 1e4))
kd_values = arrays(np.float64, N, elements=st.floats(0.0, 1e3))


@settings(max_examples=200, deadline=None)
@given(
    q=vectors,
    dq=vectors,
    q_des=vectors,
    g=vectors,
    kp=kp_values,
    kd=kd_values,
    e2=vectors,
    dq2=vectors,
    alpha=st.floats(-5.0, 5.0),
)
def test_pd_gravity_is_finite_and_linear(q, dq, q_des, g, kp, kd, e2, dq2, alpha):
    gains = PDGains.build(N, kp, kd)

    def feedback(error: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The law's feedback part as a function of (q_d − q, q̇): at q = 0 with ĝ = 0."""
        return pd_gravity(np.zeros(N), velocity, error, gains, np.zeros(N))

    tau = pd_gravity(q, dq, q_des, gains, g)
    assert tau.shape == (N,)
    assert np.all(np.isfinite(tau))
    e1 = q_des - q
    # Rounding bound: a few ulps (eps ≈ 2.2e-16) of the largest term that was added; 1e-12
    # relative is a wide margin that a wrong sign or a missing term would never meet.
    # ĝ enters additively, and q, q_d only through q_d − q:
    size0 = np.abs(g) + kp * (np.abs(q) + np.abs(q_des)) + kd * np.abs(dq) + 1.0
    assert np.all(np.abs(tau - (g + feedback(e1, dq))) <= 1e-12 * size0)
    # additive and homogeneous in (q_d − q, q̇)
    size = kp * (np.abs(e1) + np.abs(e2)) + kd * (np.abs(dq) + np.abs(dq2)) + 1.0
    lhs = feedback(e1 + e2, dq + dq2)
    assert np.all(np.abs(lhs - feedback(e1, dq) - feedback(e2, dq2)) <= 1e-12 * size)
    lhs = feedback(alpha * e1, alpha * dq)
    assert np.all(np.abs(lhs - alpha * feedback(e1, dq)) <= 1e-12 * (abs(alpha) + 1) * size)
    np.testing.assert_array_equal(feedback(np.zeros(N), np.zeros(N)), np.zeros(N))
