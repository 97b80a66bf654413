"""The metrics of issue 14 on synthetic signals with analytic answers: torque chatter, mean
error over a window, spread of repeated final positions, the frequency of a sinusoid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.analysis.metrics import (
    mean_error,
    position_spread,
    sinusoid_frequency,
    torque_chatter_rms,
)

T_S = 1e-3


def test_chatter_of_an_alternating_torque_and_a_ramp():
    t = np.arange(1001) * T_S
    alternating = 0.3 * (-1.0) ** np.arange(t.size)  # Δτ = ±0.6 every sample
    ramp = 50.0 * t  # Δτ = 50 T_s = 0.05
    tau = np.column_stack([alternating, ramp, 2.0 + 0.0 * t])
    np.testing.assert_allclose(
        torque_chatter_rms(t, tau), [0.6, 0.05, 0.0], rtol=1e-12, atol=1e-15
    )
    # both: Δτ = 0.05 ± 0.6 alternately, mean square 0.6² + 0.05²
    both = torque_chatter_rms(t, alternating + ramp)
    assert both[0] == pytest.approx(math.hypot(0.6, 0.05), rel=1e-12)


def test_chatter_window_and_repeated_stamps():
    t = np.arange(11) * T_S
    tau = np.where(t < 5.5e-3, 0.0, 1.0 * (-1.0) ** np.arange(11))
    assert torque_chatter_rms(t, tau, t_start=6e-3)[0] == pytest.approx(2.0)
    assert torque_chatter_rms(t, tau, t_end=5e-3)[0] == 0.0
    # a repeated stamp (lockstep answer sent twice) counts once: the last sample
    t2 = np.array([0.0, 1.0, 1.0, 2.0])
    assert torque_chatter_rms(t2, [0.0, 5.0, 1.0, 2.0])[0] == pytest.approx(1.0)
    assert math.isnan(torque_chatter_rms([0.0], [1.0])[0])


def test_chatter_of_white_noise_through_kp():
    rng = np.random.default_rng(3)
    kp, sigma = 400.0, 1e-4
    t = np.arange(200_000) * T_S
    tau = kp * rng.normal(0.0, sigma, t.size)
    # independent samples: RMS of a difference is √2 σ_τ (standard error 1/√(2N) relative)
    assert torque_chatter_rms(t, tau)[0] == pytest.approx(math.sqrt(2) * kp * sigma, rel=0.01)


def test_mean_error_over_the_last_window():
    t = np.arange(2001) * T_S
    q_d = np.column_stack([np.full(t.size, 1.0), np.full(t.size, -0.5)])
    offset = np.array([0.01, -0.002])
    # settles exponentially onto q_d − offset, plus a zero-mean oscillation over whole periods
    q = q_d - offset * (1 - np.exp(-t / 0.05))[:, None]
    q[:, 0] += 1e-3 * np.sin(2 * np.pi * 100 * t)
    m = mean_error(t, q, q_d, t_start=1.0 + 1e-9, t_end=1.5)  # 500 samples = 50 periods
    np.testing.assert_allclose(m, offset, atol=1e-12)
    with pytest.raises(ValueError):
        mean_error(t, q, q_d, t_start=3.0)


def test_position_spread_iso_9283():
    target = np.array([0.5, -0.3])
    # four runs on a circle of radius r around a barycentre offset by d from the target
    r, d = 1e-3, np.array([3e-4, -4e-4])
    angles = np.array([0.0, 0.5, 1.0, 1.5]) * np.pi
    finals = target + d + r * np.column_stack([np.cos(angles), np.sin(angles)])
    s = position_spread(finals, target)
    np.testing.assert_allclose(s["mean"], target + d, atol=1e-15)
    np.testing.assert_allclose(s["offset"], d, atol=1e-15)
    assert s["accuracy"] == pytest.approx(5e-4)
    assert s["repeatability"] == pytest.approx(r)  # every l_i = r: S_l = 0
    assert s["max_distance"] == pytest.approx(r)
    # per coordinate: cos over 4 quadrants = 1, 0, −1, 0: sample std √(2/3)
    np.testing.assert_allclose(s["three_sigma"], 3 * r * math.sqrt(2 / 3) * np.ones(2))
    assert s["runs"] == 4


def test_position_spread_with_unequal_distances():
    finals = np.array([[0.0], [1.0], [2.0], [3.0], [4.0]])
    s = position_spread(finals, [1.0])
    # l = 2, 1, 0, 1, 2: mean 1.2, sample std √(0.7)
    assert s["repeatability"] == pytest.approx(1.2 + 3 * math.sqrt(0.7))
    assert s["max_distance"] == 2.0 and s["accuracy"] == 1.0
    with pytest.raises(ValueError):
        position_spread(finals[:1], [1.0])


def test_sinusoid_frequency():
    t = np.arange(0.0, 3.0, 0.01)
    omega = np.array([2.0, 4.0])
    q_d = np.array([0.5, -0.3]) + 0.2 * np.sin(omega * t[:, None] + 0.3)
    ddq_d = -(omega**2) * 0.2 * np.sin(omega * t[:, None] + 0.3)
    np.testing.assert_allclose(sinusoid_frequency(q_d, ddq_d), omega, rtol=1e-12)
    # a quintic-like move and a constant are not sinusoids
    s = t / 3.0
    quintic = 10 * s**3 - 15 * s**4 + 6 * s**5
    ddquintic = (60 * s - 180 * s**2 + 120 * s**3) / 9.0
    still = np.zeros_like(t)
    out = sinusoid_frequency(
        np.column_stack([quintic, still]), np.column_stack([ddquintic, still])
    )
    assert np.all(np.isnan(out))


def _state(t, rows, joints=("joint1", "joint2")):
    from joint_space_control.analysis.bag import ControllerState

    log = 1_000_000_000 + np.round(t * 1e9).astype(np.int64)
    return ControllerState("/c/state", joints, tuple(rows), t, log, rows)


def test_run_metrics_writes_offset_chatter_and_frequency_response():
    from joint_space_control.analysis.run_metrics import controller_metrics
    from joint_space_control.laws.second_order import second_order_frequency_response

    # joint1 tracks a sinusoid as the steady state of ω_n = 20, ζ = 0.7 would; joint2 holds
    # with an offset of 0.01 rad and a torque that alternates by ±0.2 N·m
    t = np.arange(0.0, 10.0 + 1e-9, 1e-3)
    w, amp = 3.0, 0.2
    g = second_order_frequency_response(w, 20.0, 0.7)
    q_d = np.column_stack([0.5 + amp * np.sin(w * t), np.full(t.size, -0.3)])
    dq_d = np.column_stack([amp * w * np.cos(w * t), np.zeros(t.size)])
    ddq_d = np.column_stack([-amp * w * w * np.sin(w * t), np.zeros(t.size)])
    q = np.column_stack([0.5 + amp * abs(g) * np.sin(w * t + np.angle(g)), np.full(t.size, -0.31)])
    tau = np.column_stack([np.zeros(t.size), 1.0 + 0.2 * (-1.0) ** np.arange(t.size)])
    rows = {"q_d": q_d, "dq_d": dq_d, "ddq_d": ddq_d, "q": q, "tau": tau}
    m = controller_metrics(_state(t, rows))
    assert m["static_offset"]["mean_error"]["joint2"] == pytest.approx(0.01)
    assert m["static_offset"]["t_end"] - m["static_offset"]["t_start"] == pytest.approx(0.1)
    assert m["torque_chatter_rms"] == {"joint1": 0.0, "joint2": pytest.approx(0.4)}
    (run,) = m["frequency_response"]
    assert list(run["joints"]) == ["joint1"]
    fr = run["joints"]["joint1"]
    assert fr["omega"] == pytest.approx(w, rel=1e-9)
    assert fr["gain"] == pytest.approx(abs(g), abs=1e-9)
    assert fr["phase"] == pytest.approx(np.angle(g), abs=1e-9)
    # 10 s hold P = 4 whole periods of 2π/3 s: the last 2 are fitted
    assert fr["periods"] == 2
    assert fr["t_fit_start"] == pytest.approx(10.0 - 4 * math.pi / 3, abs=1e-3)


def test_run_metrics_without_sinusoid_has_no_frequency_response():
    from joint_space_control.analysis.run_metrics import controller_metrics

    t = np.arange(0.0, 1.0 + 1e-9, 1e-3)
    q_d = np.column_stack([np.full(t.size, 0.5), np.full(t.size, -0.3)])
    rows = {"q_d": q_d, "ddq_d": 0 * q_d, "q": q_d - 0.001, "tau": np.ones_like(q_d)}
    m = controller_metrics(_state(t, rows))
    assert m["frequency_response"] is None
    assert m["torque_chatter_rms"] == {"joint1": 0.0, "joint2": 0.0}
    assert m["static_offset"]["mean_error"] == {
        "joint1": pytest.approx(0.001),
        "joint2": pytest.approx(0.001),
    }
