"""The tests' choice of the realtime loop's rate by machine speed
(test/integration/loop_rate.py): the thresholds measured on the machines where each rate
passed, every rate one the plant can run."""

from __future__ import annotations

import pytest

from joint_space_control.lab.soaks.soak import check_loop_rate
from test.integration.loop_rate import PLANT_ALONE_RATE, RATES, SLOWEST_RATE, rate_for


@pytest.mark.parametrize(
    ("speed_us", "rate"),
    [
        (9.0, 1000.0),  # the machines of the 1 kHz hours (~10 µs)
        (15.0, 1000.0),
        (15.1, 250.0),
        (20.0, 250.0),
        (20.1, 100.0),
        (37.5, 100.0),  # the VM where the page test failed at 250 Hz and passed at 100 Hz
    ],
)
def test_the_rate_falls_as_the_machine_slows(speed_us, rate):
    assert rate_for(speed_us) == rate


def test_every_rate_is_one_the_plant_publishes_at():
    for rate in [r for _, r in RATES] + [SLOWEST_RATE, PLANT_ALONE_RATE]:
        check_loop_rate(rate)  # raises unless it divides the 1 kHz physics
    speeds = [s for s, _ in RATES]
    rates = [r for _, r in RATES] + [SLOWEST_RATE]
    assert speeds == sorted(speeds)  # fastest first: rate_for takes the first that fits
    assert rates == sorted(rates, reverse=True)
