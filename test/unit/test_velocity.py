"""The velocity estimators on analytic signals: ramps (exact), sinusoids (the exact
discrete-time frequency response), white noise (the variance reduction)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.laws.velocity import (
    BackwardDifference,
    FilteredDifference,
    difference_response,
    filtered_difference_response,
    noise_variance_ratio,
    phase_lag,
)

T = 1e-3
CUTOFF = 50.0


def run(estimator, times, positions):
    return np.array([estimator.update(t, q).copy() for t, q in zip(times, positions, strict=True)])


@pytest.mark.parametrize(
    "make", [lambda: BackwardDifference(2), lambda: FilteredDifference(2, 50.0)]
)
def test_a_ramp_gives_its_slope_exactly_from_the_second_sample(make):
    """Irregular stamps too: each difference is over its own period."""
    rng = np.random.default_rng(1)
    times = np.cumsum(rng.uniform(0.5e-3, 3e-3, 200))
    slope = np.array([0.7, -2.5])
    estimates = run(make(), times, 0.3 + np.outer(times, slope))
    np.testing.assert_array_equal(estimates[0], [0.0, 0.0])  # no predecessor: 0
    np.testing.assert_allclose(estimates[1:], np.tile(slope, (199, 1)), rtol=0, atol=1e-9)


def test_the_filter_is_the_first_order_recursion_with_the_period_of_each_sample():
    """A step of slope: the filter approaches the new slope as 1 − Π α_k."""
    est = FilteredDifference(1, CUTOFF)
    periods = [1e-3, 1e-3, 2e-3, 1e-3, 5e-3, 1e-3]
    times = np.concatenate(([0.0], np.cumsum(periods)))
    positions = np.zeros((times.size, 1))  # at rest, then moving at 1 rad/s from times[1]
    positions[2:, 0] = times[2:] - times[1]
    got = run(est, times, positions)[:, 0]
    expected, y = [0.0, 0.0], 0.0
    for period in periods[1:]:
        alpha = math.exp(-2 * math.pi * CUTOFF * period)
        y = alpha * y + (1 - alpha) * 1.0
        expected.append(y)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("omega", [2.0, 30.0, 300.0, 1500.0])
@pytest.mark.parametrize("cutoff", [None, 5.0, 50.0])
def test_a_sinusoid_gets_the_predicted_amplitude_ratio_and_phase_lag(omega, cutoff):
    """q = sin ωt at 1 kHz: after the filter's transient (α^k < 1e-13) the estimate is
    Im(jω R(ω) e^{jωt_k}) to 1e-9 relative, R the exact discrete-time response; |R| and ∠R
    are the closed forms sinc(ωT/2)·(1−α)/√(1 − 2α cos ωT + α²) and −phase_lag."""
    est = BackwardDifference(1) if cutoff is None else FilteredDifference(1, cutoff)
    times = np.arange(20000) * T
    got = run(est, times, np.sin(omega * times)[:, None])[:, 0]
    if cutoff is None:
        response = difference_response(omega, T)
        gain = math.sin(omega * T / 2) / (omega * T / 2)
        settled = 1
    else:
        response = filtered_difference_response(omega, T, cutoff)
        alpha = math.exp(-2 * math.pi * cutoff * T)
        gain = math.sin(omega * T / 2) / (omega * T / 2)
        gain *= (1 - alpha) / math.sqrt(1 - 2 * alpha * math.cos(omega * T) + alpha**2)
        settled = math.ceil(math.log(1e-13) / math.log(alpha))
    expected = np.imag(1j * omega * response * np.exp(1j * omega * times))
    np.testing.assert_allclose(got[settled:], expected[settled:], rtol=0, atol=1e-9 * omega)
    assert abs(response) == pytest.approx(gain, rel=1e-12)
    assert -np.angle(response) == pytest.approx(float(phase_lag(omega, T, cutoff)), rel=1e-12)


@pytest.mark.parametrize(("omega", "cutoff", "rel"), [(30.0, 5.0, 2e-4), (100.0, 50.0, 0.01)])
def test_the_filtered_lag_tends_to_the_continuous_first_order(omega, cutoff, rel):
    """ωT/2 + atan(α sin ωT / (1 − α cos ωT)) → atan(ω/ω_c) when ωT, ω_cT ≪ 1 (the discrete
    pole's half-period lead cancels the difference's half-period lag)."""
    approx = math.atan(omega / (2 * math.pi * cutoff))
    assert float(phase_lag(omega, T, cutoff)) == pytest.approx(approx, rel=rel)
    assert float(phase_lag(omega, T)) == omega * T / 2


def test_white_noise_variance_is_reduced_by_the_predicted_factor():
    """σ² on q: backward difference 2σ²/T², filtered (1 − α)²/(1 + α) times that (0.042 at
    f_c = 50 Hz, T = 1 ms), each within 3 % over 200 000 seeded samples."""
    sigma, count = 1e-4, 200_000
    rng = np.random.default_rng(7)
    noise = sigma * rng.standard_normal((count, 1))
    times = np.arange(count) * T
    diff = run(BackwardDifference(1), times, noise)[1000:, 0]
    filt = run(FilteredDifference(1, CUTOFF), times, noise)[1000:, 0]
    assert np.var(diff) == pytest.approx(2 * sigma**2 / T**2, rel=0.03)
    ratio = noise_variance_ratio(T, CUTOFF)
    assert ratio == pytest.approx(0.0420, abs=5e-4)
    assert np.var(filt) / np.var(diff) == pytest.approx(ratio, rel=0.03)


def test_same_stamp_keeps_the_estimate_and_reset_forgets():
    est = FilteredDifference(1, CUTOFF)
    est.update(0.0, np.array([0.0]))
    first = est.update(0.001, np.array([0.002])).copy()
    np.testing.assert_allclose(first, [2.0])
    np.testing.assert_array_equal(est.update(0.001, np.array([5.0])), first)  # no new sample
    est.reset()
    np.testing.assert_array_equal(est.update(0.002, np.array([1.0])), [0.0])


def test_observed_samples_let_a_switch_start_without_a_zero():
    """While the measured velocity is used the estimator only observes; switched on while
    moving, its first estimate is the difference to the last observed sample, not 0."""
    est = FilteredDifference(1, CUTOFF)
    for k in range(5):
        est.observe(k * T, np.array([3.0 * k * T]))
    np.testing.assert_allclose(est.update(5 * T, np.array([15 * T])), [3.0], rtol=1e-12)
    np.testing.assert_allclose(est.update(6 * T, np.array([18 * T])), [3.0], rtol=1e-12)
