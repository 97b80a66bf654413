"""The scheduled wrench w(t) = s(t) w₀ (sim_bridge/wrench.py) on simulation time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_bridge.wrench import WrenchSchedule

F0, MU0 = [0.0, 0.0, -20.0], [1.0, 0.0, 0.0]


def test_step():
    w = WrenchSchedule(F0, MU0, "step", start=1.0)
    assert [w.scale(t) for t in (0.0, 0.999, 1.0, 5.0)] == [0.0, 0.0, 1.0, 1.0]
    force, torque = w.at(2.0)
    np.testing.assert_array_equal(force, F0)
    np.testing.assert_array_equal(torque, MU0)
    force, torque = w.at(0.5)
    np.testing.assert_array_equal(np.r_[force, torque], 0.0)


def test_pulse():
    w = WrenchSchedule(F0, MU0, "pulse", start=0.2, duration=0.1)
    assert [w.scale(t) for t in (0.1, 0.2, 0.25, 0.2999, 0.3, 1.0)] == [0, 1, 1, 1, 0, 0]


def test_sinusoid():
    """f = 2 Hz from t₀ = 1 s: s = sin(2π·2·(t − 1)): 1 at a quarter period (1.125 s), 0 at
    half a period, −1 at three quarters; 0 before t₀."""
    w = WrenchSchedule(F0, MU0, "sinusoid", start=1.0, frequency=2.0)
    assert w.scale(0.9) == 0.0
    np.testing.assert_allclose(
        [w.scale(t) for t in (1.0, 1.125, 1.25, 1.375)], [0, 1, 0, -1], atol=1e-12
    )
    force, _ = w.at(1.0 + 1 / 24)  # sin(π/6) = 1/2
    np.testing.assert_allclose(force, 0.5 * np.array(F0), atol=1e-12)


def test_zero_is_off():
    assert not WrenchSchedule([0.0] * 3, [0.0] * 3).active
    assert WrenchSchedule([0.0] * 3, [0.0, 0.0, 1e-9]).active


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"force": [1.0, 2.0]}, "wrench_force"),
        ({"torque": [0.0, math.inf, 0.0]}, "wrench_torque"),
        ({"profile": "ramp"}, "wrench_profile"),
        ({"start": -1.0}, "wrench_start"),
        ({"duration": math.nan}, "wrench_duration"),
        ({"frequency": -2.0}, "wrench_frequency"),
    ],
)
def test_invalid_schedules_are_refused_with_the_parameter_name(kwargs, name):
    args = {"force": F0, "torque": MU0, **kwargs}
    with pytest.raises(ValueError, match=name):
        WrenchSchedule(**args)
