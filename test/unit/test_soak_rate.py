"""The soak's loop rate (``jsc soak --rate``, for a machine too slow for 1 kHz) and the
machine's Python yardstick that the reports name (no ROS graph)."""

from __future__ import annotations

import math

import pytest

from joint_space_control.cli.main import main
from joint_space_control.lab.soaks.fault_soak import FaultSoakOptions
from joint_space_control.lab.soaks.soak import PHYSICS_RATE, SoakOptions, check_loop_rate
from joint_space_control.machine import describe, machine, python_speed_us


@pytest.mark.parametrize("rate", [1000.0, 500.0, 250.0, 200.0, 125.0, 100.0, 1.0])
def test_divisors_of_the_physics_rate_are_loop_rates(rate):
    check_loop_rate(rate)
    assert SoakOptions(rate=rate).rate == FaultSoakOptions(rate=rate).rate == rate
    assert (PHYSICS_RATE / rate).is_integer()


@pytest.mark.parametrize("rate", [300.0, 2000.0, 0.0, -250.0, math.nan, math.inf, 333.3])
def test_other_rates_are_refused_by_name(rate):
    with pytest.raises(ValueError, match="must divide the physics rate of 1000 Hz"):
        check_loop_rate(rate)
    with pytest.raises(ValueError):
        FaultSoakOptions(rate=rate)


def test_the_default_loop_is_1_khz():
    assert SoakOptions().rate == FaultSoakOptions().rate == PHYSICS_RATE == 1000.0


@pytest.mark.parametrize("faults", [[], ["--faults"]])
def test_jsc_soak_refuses_a_bad_rate_in_one_line(faults, capsys, tmp_path):
    assert main(["soak", *faults, "--rate", "300", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "jsc soak: error: --rate:" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())  # nothing started, nothing written


def test_the_python_yardstick_is_a_time_per_sum_and_named_in_the_machine_line():
    speed = python_speed_us(repeat=2, number=200)
    assert 0.1 < speed < 10_000.0  # µs for sum(range(1000)): finite, positive, not seconds
    found = machine()
    line = describe(found)
    assert f"sum(range(1000)) in {found['python_speed_us']:g} µs" in line
    assert line.startswith(found["cpu"]) and "cores" in line
    del found["python_speed_us"]  # a report written before it was measured
    assert "sum(range" not in describe(found)
