"""The sampled inverse-dynamics loop (laws/sampled.py) against independent simulations of the
double integrator with a held input, the continuous theory, and its stability limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.laws.sampled import (
    hold_coefficient,
    sampled_loop_matrices,
    sampled_spectral_radius,
    sampled_stability_limit,
    sampled_step_prediction,
    sampled_step_response,
)
from joint_space_control.laws.second_order import second_order_to_gains

OMEGA_N, ZETA = 20.0, 0.7
KP, KD = (float(g) for g in second_order_to_gains(OMEGA_N, ZETA))


def rk4_held(kp, kd, period, duration, h, y0=0.0, y1=1.0):
    """q̈ = y, y recomputed from the state at each period start and held, integrated by RK4
    at step h (exact up to rounding for a piecewise-constant input: the motion is a parabola).
    Returns the positions at every step h."""
    m = round(period / h)
    n = round(duration / period)
    q, v = y0, 0.0
    out = [q]
    for _ in range(n):
        y = kp * (y1 - q) - kd * v
        for _ in range(m):
            k1q, k1v = v, y
            k2q, k2v = v + 0.5 * h * k1v, y
            k3q, k3v = v + 0.5 * h * k2v, y
            k4q, k4v = v + h * k3v, y
            q += h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v += h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
            out.append(q)
    return np.array(out)


def semi_implicit_plant(kp, kd, period, duration, h, y0=0.0, y1=1.0):
    """What sim_bridge does for a decoupled joint: v += h y; q += h v, m times per period."""
    m = round(period / h)
    n = round(duration / period)
    q, v = y0, 0.0
    out = [q]
    for _ in range(n):
        y = kp * (y1 - q) - kd * v
        for _ in range(m):
            v += h * y
            q += h * v
            out.append(q)
    return np.array(out)


@pytest.mark.parametrize("period", [0.001, 0.01, 0.04])
def test_exact_zoh_matches_fine_step_simulation(period):
    h = 1e-5
    r = sampled_step_response(KP, KD, period, 0.4, physics_dt=None, dt=h, y0=0.3, y1=-0.2)
    reference = rk4_held(KP, KD, period, 0.4, h, y0=0.3, y1=-0.2)
    assert r.q.shape == reference.shape
    assert np.max(np.abs(r.q - reference)) < 1e-9
    np.testing.assert_allclose(r.t[:: round(period / h)], r.t_samples, atol=1e-12)
    np.testing.assert_allclose(r.q[:: round(period / h)], r.q_samples, atol=1e-12)


@pytest.mark.parametrize("period", [0.001, 0.005, 0.04])
def test_semi_implicit_matches_the_plant_integrator(period):
    h = 1e-3
    r = sampled_step_response(KP, KD, period, 0.48, physics_dt=h, y0=-1.0, y1=0.5)
    assert np.max(np.abs(r.q - semi_implicit_plant(KP, KD, period, 0.48, h, -1.0, 0.5))) < 1e-12
    assert hold_coefficient(period, h) == pytest.approx((period / h + 1) / (2 * period / h))


def test_matrices_are_the_zoh_discretisation():
    phi, gamma, a = sampled_loop_matrices(KP, KD, 0.02, None)
    np.testing.assert_array_equal(phi, [[1.0, 0.02], [0.0, 1.0]])
    np.testing.assert_allclose(gamma, [0.02**2 / 2, 0.02])
    np.testing.assert_allclose(a, phi - np.outer(gamma, [KP, KD]))
    # the characteristic polynomial given in the module doc
    T = 0.02
    assert np.trace(a) == pytest.approx(2 - KP * T * T / 2 - KD * T)
    assert np.linalg.det(a) == pytest.approx(1 - KD * T + KP * T * T / 2)


def test_small_period_recovers_the_continuous_overshoot():
    mp = 100.0 * math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2))
    p = sampled_step_prediction(KP, KD, 1e-4, physics_dt=None, dt=1e-5)
    # the hold acts as a delay of about T/2: error O(ω_n T) relative
    assert p["overshoot_percent"] == pytest.approx(mp, abs=0.01)
    assert p["stable"]


@pytest.mark.parametrize(
    ("omega_n", "zeta"), [(20.0, 0.7), (20.0, 0.3), (10.0, 1.0), (30.0, 2.0), (5.0, 0.05)]
)
@pytest.mark.parametrize("physics_dt", [None, 1e-3, 2e-4])
def test_stability_limit_is_where_the_spectral_radius_crosses_one(omega_n, zeta, physics_dt):
    kp, kd = (float(g) for g in second_order_to_gains(omega_n, zeta))
    limit = sampled_stability_limit(kp, kd, physics_dt)
    if physics_dt is None:
        assert limit == pytest.approx(min(1 / (zeta * omega_n), 4 * zeta / omega_n), rel=1e-14)
    # the spectral radius as a function of a continuous T (c = 1/2 + h/(2T)); both sides
    h = 0.0 if physics_dt is None else physics_dt

    def rho(T):
        c = 0.5 + h / (2 * T)
        a = np.array([[1 - c * kp * T * T, T - c * kd * T * T], [-kp * T, 1 - kd * T]])
        return np.max(np.abs(np.linalg.eigvals(a)))

    assert rho(limit * (1 - 1e-6)) < 1.0 < rho(limit * (1 + 1e-6))
    # and nothing unstable below it
    grid = np.linspace(limit * 1e-3, limit * (1 - 1e-6), 400)
    assert max(rho(T) for T in grid) < 1.0


def test_spectral_radius_beside_the_limit_for_whole_periods():
    limit = sampled_stability_limit(KP, KD, None)
    assert sampled_spectral_radius(KP, KD, limit * 0.999, None) < 1.0
    assert sampled_spectral_radius(KP, KD, limit * 1.001, None) > 1.0
    p = sampled_step_prediction(KP, KD, 0.08, physics_dt=1e-3)
    assert not p["stable"] and math.isnan(p["overshoot_percent"])


def test_prediction_sampled_overshoot_is_the_samples_peak():
    p = sampled_step_prediction(KP, KD, 0.04, physics_dt=1e-3)
    r = sampled_step_response(KP, KD, 0.04, 2.0, physics_dt=1e-3)
    assert p["overshoot_percent"] == pytest.approx(100 * (r.q.max() - 1), rel=1e-12)
    assert p["overshoot_percent_sampled"] == pytest.approx(100 * (r.q_samples.max() - 1))
    assert p["overshoot_percent_sampled"] <= p["overshoot_percent"]
    assert 0.0 < p["settling_time_2"] < 1.0


def test_exact_overshoot_includes_the_vertex_between_grid_points():
    coarse = sampled_step_prediction(KP, KD, 0.04, physics_dt=None, dt=0.04)
    fine = sampled_step_prediction(KP, KD, 0.04, physics_dt=None, dt=1e-6, duration=1.0)
    assert coarse["overshoot_percent"] == pytest.approx(fine["overshoot_percent"], abs=1e-9)


def test_rejects_bad_input():
    with pytest.raises(ValueError):
        sampled_step_response(KP, KD, 0.0015, 1.0, physics_dt=1e-3)
    with pytest.raises(ValueError):
        sampled_stability_limit(-1.0, KD)
    with pytest.raises(ValueError):
        sampled_loop_matrices(KP, KD, 0.0)


def delayed_plant(kp, kd, period, duration, h, delay, semi_implicit, y0=0.0, y1=1.0):
    """Independent: commands computed at t_k = k T from the state then, queued, and applied
    from t_k + δ on; the plant steps at h (exact for a held input, or semi-implicit Euler)."""
    m = round(period / h)
    lag = round(delay / h)  # the delay in steps h
    n = round(duration / period)
    q, v = y0, 0.0
    queue = {}  # step index at which a command starts -> command
    u = 0.0
    out = [q]
    for i in range(n * m):
        if i % m == 0:
            queue[i + lag] = kp * (y1 - q) - kd * v
        u = queue.pop(i, u)
        if semi_implicit:
            v += h * u
            q += h * v
        else:
            q += h * v + 0.5 * h * h * u
            v += h * u
        out.append(q)
    return np.array(out)


@pytest.mark.parametrize("delay", [0.0, 2e-3, 10e-3, 13e-3, 27e-3])
@pytest.mark.parametrize("physics_dt", [None, 1e-3])
def test_delayed_loop_matches_a_command_queue(delay, physics_dt):
    period, h = 10e-3, 1e-3
    r = sampled_step_response(
        KP, KD, period, 0.6, physics_dt=physics_dt, dt=None if physics_dt else h, delay=delay
    )
    reference = delayed_plant(KP, KD, period, 0.6, h, delay, semi_implicit=physics_dt is not None)
    assert np.max(np.abs(r.q - reference)) < 1e-12


def test_zero_delay_block_is_the_undelayed_matrix():
    from joint_space_control.laws.sampled import delayed_loop_matrix

    a = sampled_loop_matrices(KP, KD, 0.02, 1e-3)[2]
    m = delayed_loop_matrix(KP, KD, 0.02, 1e-3, 0.0)
    np.testing.assert_allclose(m[:2, :2], a, rtol=1e-15, atol=1e-15)
    assert sampled_spectral_radius(KP, KD, 0.02, 1e-3, delay=0.0) == pytest.approx(
        np.max(np.abs(np.linalg.eigvals(a)))
    )


@pytest.mark.parametrize("delay", [0.3e-3, 5e-3, 20e-3])
@pytest.mark.parametrize("physics_dt", [None, 1e-4])
def test_delayed_stability_limit_is_where_the_spectral_radius_crosses_one(delay, physics_dt):
    from joint_space_control.laws.sampled import _delayed_map

    limit = sampled_stability_limit(KP, KD, physics_dt, delay=delay)
    h = physics_dt or 0.0

    def rho(T):
        return np.max(np.abs(np.linalg.eigvals(_delayed_map(KP, KD, T, h, delay))))

    assert rho(limit * (1 - 1e-6)) < 1.0 <= rho(limit * (1 + 1e-6))
    assert max(rho(T) for T in np.linspace(max(limit, delay) / 50, limit * (1 - 1e-6), 500)) < 1.0


def test_stability_limit_with_long_delays():
    undelayed = sampled_stability_limit(KP, KD)
    assert sampled_stability_limit(KP, KD, delay=2e-3) > undelayed  # see the docstring
    assert sampled_stability_limit(KP, KD, delay=20e-3) < undelayed
    # a continuous loop with 50 ms of delay at ω_n = 20 is unstable however fast it samples
    assert math.isnan(sampled_stability_limit(KP, KD, delay=50e-3))


def test_delay_raises_the_overshoot():
    p0 = sampled_step_prediction(KP, KD, 5e-3, physics_dt=None, dt=1e-4)
    p1 = sampled_step_prediction(KP, KD, 5e-3, physics_dt=None, dt=1e-4, delay=2e-3)
    assert p1["overshoot_percent"] > p0["overshoot_percent"]
    assert p1["delay"] == 2e-3
