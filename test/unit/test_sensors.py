"""The measurement model of sim_bridge (sim_bridge/sensors.py): quantization to the nearest
count, Gaussian noise with the σ asked for, reproducible from its seed, nothing drawn or
changed when off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_bridge.sensors import Encoder

N = 200_000  # joints measured at once: one call gives N independent samples


def test_off_passes_the_state_through_and_draws_nothing():
    enc = Encoder(3, seed=5)
    assert enc.exact
    q, dq = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, -3.0])
    y_q, y_v = np.empty(3), np.empty(3)
    enc.measure(q, dq, y_q, y_v)
    np.testing.assert_array_equal(y_q, q)
    np.testing.assert_array_equal(y_v, dq)
    # the generator is untouched: its next draw is a fresh generator's first
    assert enc._rng.standard_normal() == np.random.default_rng(5).standard_normal()


def test_quantization_rounds_to_the_nearest_count():
    """Δ = 2π/4096; every output a multiple of Δ, error in [−Δ/2, Δ/2], uniform: mean 0
    (±4 standard errors), RMS Δ/√12 (within 1 %)."""
    enc = Encoder(N, counts=4096)
    delta = 2 * math.pi / 4096
    q = np.random.default_rng(1).uniform(-3.0, 3.0, N)
    y = np.empty(N)
    enc.measure(q, np.zeros(N), y, np.empty(0))
    counts = y / delta
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    err = y - q
    assert np.all(np.abs(err) <= delta / 2 + 1e-15)
    assert abs(err.mean()) <= 4 * delta / math.sqrt(12 * N)
    np.testing.assert_allclose(np.sqrt(np.mean(err**2)), delta / math.sqrt(12), rtol=0.01)
    # exact values: 2.4Δ → 2Δ, 2.6Δ → 3Δ, −2.6Δ → −3Δ
    small = Encoder(3, counts=4096)
    y3 = np.empty(3)
    small.measure(np.array([2.4, 2.6, -2.6]) * delta, np.zeros(3), y3, np.empty(0))
    np.testing.assert_allclose(y3 / delta, [2.0, 3.0, -3.0], atol=1e-12)


def test_noise_has_the_sigma_asked_for():
    """σ_q = 1e-3 rad, σ_v = 0.05 rad/s: sample standard deviations within 1 % (standard
    error 0.16 % for 2·10⁵ samples), means within 4 standard errors."""
    enc = Encoder(N, position_noise=1e-3, velocity_noise=0.05, seed=3)
    q, dq = np.full(N, 0.5), np.full(N, -1.0)
    y_q, y_v = np.empty(N), np.empty(N)
    enc.measure(q, dq, y_q, y_v)
    for y, truth, sigma in ((y_q, 0.5, 1e-3), (y_v, -1.0, 0.05)):
        np.testing.assert_allclose(np.std(y - truth), sigma, rtol=0.01)
        assert abs(np.mean(y - truth)) <= 4 * sigma / math.sqrt(N)


def test_noise_per_joint_and_before_quantization():
    """A joint with σ = 0 stays exact; noise of σ ≪ Δ on a value mid-way between counts
    never moves it off its count (the noise is added before the rounding)."""
    delta = 2 * math.pi / 1000
    enc = Encoder(2, counts=[0.0, 1000.0], position_noise=[1e-3, 1e-6])
    y = np.empty(2)
    for _ in range(100):
        enc.measure(np.array([0.25, 7.0 * delta]), np.zeros(2), y, np.empty(0))
        assert y[1] == pytest.approx(7.0 * delta, abs=1e-15)
    assert y[0] != 0.25


def test_seeded_noise_is_reproducible():
    def sequence(enc: Encoder, k: int = 5) -> np.ndarray:
        y_q, y_v = np.empty(2), np.empty(2)
        rows = []
        for _ in range(k):
            enc.measure(np.zeros(2), np.zeros(2), y_q, y_v)
            rows.append(np.r_[y_q, y_v])
        return np.array(rows)

    a = sequence(Encoder(2, position_noise=0.01, velocity_noise=0.1, seed=11))
    b = Encoder(2, position_noise=0.01, velocity_noise=0.1, seed=11)
    np.testing.assert_array_equal(sequence(b), a)
    other = sequence(Encoder(2, position_noise=0.01, velocity_noise=0.1, seed=12))
    assert not np.array_equal(other, a)
    b.reseed(11)  # restarts the sequence
    np.testing.assert_array_equal(sequence(b), a)


def test_no_velocities_measured_draws_none_for_them():
    """y_v empty (measure_velocity false): the position draws are the same as with no
    velocity noise at all."""
    y = np.empty(2)
    with_v = Encoder(2, position_noise=0.01, velocity_noise=1.0, seed=4)
    without = Encoder(2, position_noise=0.01, seed=4)
    y2 = np.empty(2)
    for _ in range(3):
        with_v.measure(np.zeros(2), np.zeros(2), y, np.empty(0))
        without.measure(np.zeros(2), np.zeros(2), y2, np.empty(2))
        np.testing.assert_array_equal(y, y2)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"counts": -1.0}, "encoder_counts"),
        ({"position_noise": [0.1, -0.1]}, "position_noise"),
        ({"velocity_noise": np.nan}, "velocity_noise"),
        ({"counts": [1.0, 2.0, 3.0]}, "encoder_counts"),
        ({"seed": -1}, "noise_seed"),
        ({"seed": 1.5}, "noise_seed"),
    ],
)
def test_invalid_settings_are_refused_with_their_name(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Encoder(2, **kwargs)
