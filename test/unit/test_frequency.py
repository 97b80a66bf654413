"""Frequency response: the analytic G(jω) and bandwidth (laws/second_order.py) and the
estimators of analysis/frequency.py on a simulated second-order system."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.analysis.frequency import (
    HALF_POWER,
    bandwidth,
    frequency_response,
    sine_fit,
)
from joint_space_control.laws.second_order import (
    second_order_bandwidth,
    second_order_frequency_response,
)


def rk4_second_order(omega_n, zeta, u, t):
    """y'' + 2ζω_n y' + ω_n² y = ω_n² u(t) from rest, RK4 on the uniform grid t (u a function)."""
    h = t[1] - t[0]
    y, v = 0.0, 0.0
    out = np.empty(t.size)
    out[0] = y

    def f(tt, y, v):
        return v, omega_n**2 * (u(tt) - y) - 2 * zeta * omega_n * v

    for i in range(t.size - 1):
        tt = t[i]
        k1 = f(tt, y, v)
        k2 = f(tt + h / 2, y + h / 2 * k1[0], v + h / 2 * k1[1])
        k3 = f(tt + h / 2, y + h / 2 * k2[0], v + h / 2 * k2[1])
        k4 = f(tt + h, y + h * k3[0], v + h * k3[1])
        y += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        v += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        out[i + 1] = y
    return out


@pytest.mark.parametrize("zeta", [0.0, 0.3, 1 / math.sqrt(2), 1.0, 2.5])
def test_bandwidth_formula_is_the_half_power_point(zeta):
    wb = second_order_bandwidth(10.0, zeta)
    assert abs(second_order_frequency_response(wb, 10.0, zeta)) == pytest.approx(HALF_POWER)


def test_frequency_response_values():
    assert second_order_frequency_response(0.0, 20.0, 0.7) == pytest.approx(1.0)
    g = second_order_frequency_response(20.0, 20.0, 0.7)  # at ω_n: 1/(2jζ)
    assert g == pytest.approx(1.0 / (2j * 0.7))
    assert second_order_bandwidth(20.0, 1 / math.sqrt(2)) == pytest.approx(20.0)


@pytest.mark.parametrize("omega", [5.0, 20.0, 45.0])
def test_estimator_on_a_known_transfer_function(omega):
    omega_n, zeta = 20.0, 0.3
    t = np.arange(0.0, 5.0, 2e-4)
    amplitude, phase0, offset = 0.2, 0.4, -0.3

    def u(tt):
        return offset + amplitude * math.sin(omega * tt + phase0)

    y = rk4_second_order(omega_n, zeta, u, t)
    q_d = offset + amplitude * np.sin(omega * t + phase0)
    point = frequency_response(t, q_d, y, omega, t_start=2.5)  # transient e^{-15} by then
    g = second_order_frequency_response(omega, omega_n, zeta)
    assert point.gain[0] == pytest.approx(abs(g), abs=1e-6)
    assert point.phase[0] == pytest.approx(np.angle(g), abs=1e-6)
    assert point.periods >= 1 and point.t_start >= 2.5


def test_estimator_with_white_noise_and_two_columns():
    rng = np.random.default_rng(7)
    omega, n = 12.0, 8000
    t = np.sort(rng.uniform(0.0, 8.0, n))  # irregular samples too
    u = np.column_stack([np.sin(omega * t), 2.0 * np.cos(omega * t)])
    y = np.column_stack([0.5 * np.sin(omega * t - 1.0), 2.0 * 1.5 * np.cos(omega * t + 0.25)])
    sigma = 0.05
    point = frequency_response(t, u, y + rng.normal(0.0, sigma, y.shape), omega)
    # about σ√(2/N)/A = 7.9e-4 (A = 1) one σ: 5σ
    np.testing.assert_allclose(point.gain, [0.5, 1.5], atol=4e-3)
    np.testing.assert_allclose(point.phase, [-1.0, 0.25], atol=8e-3)


def test_sine_fit_phasor_convention():
    t = np.linspace(0.0, 2.0, 2001)
    phasor, offset, periods = sine_fit(t, 1.0 + 3.0 * np.sin(math.pi * t + 0.5), math.pi)
    assert phasor[0] == pytest.approx(3.0 * np.exp(0.5j))
    assert offset[0] == pytest.approx(1.0 + 0.0, abs=1e-12)
    assert periods == 1
    with pytest.raises(ValueError):
        sine_fit(t, t, 1.0)  # less than one period of 2π s


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7, 1.0, 2.0])
def test_bandwidth_from_samples_of_the_analytic_response(zeta):
    omega_n = 20.0
    w = np.geomspace(1.0, 400.0, 25)  # ~4 points per octave
    gain = np.abs(second_order_frequency_response(w, omega_n, zeta))
    assert bandwidth(w, gain) == pytest.approx(second_order_bandwidth(omega_n, zeta), rel=0.01)


def test_bandwidth_outside_the_points_is_nan():
    assert math.isnan(bandwidth([1.0, 2.0], [1.0, 0.9]))
    assert math.isnan(bandwidth([1.0, 2.0], [0.5, 0.4]))
    assert bandwidth([1.0, 4.0], [1.0, HALF_POWER**2]) == pytest.approx(2.0)
