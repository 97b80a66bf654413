"""What counts as the same experiment on two engines
(workbench/experiments/execution/equivalence.py)."""

from __future__ import annotations

import math

from joint_space_control.workbench.experiments.execution.equivalence import differences


def test_equal_values_and_nan_are_the_same():
    a = {"x": [1.0, math.nan, {"y": "text"}], "n": 3}
    assert differences(a, {"x": [1.0, math.nan, {"y": "text"}], "n": 3}) == []


def test_the_last_bit_differs():
    assert differences({"e": 0.1 + 0.2}, {"e": 0.3}) == ["/e: 0.30000000000000004 != 0.3"]


def test_missing_keys_lengths_and_types_are_differences():
    found = differences({"a": [1, 2], "b": 1}, {"a": [1], "c": 1})
    assert found == ["/a: 2 items != 1", "/b: only in the first", "/c: only in the second"]
    assert differences({"a": 1}, {"a": "1"}) == ["/a: 1 != '1'"]


def test_what_only_the_recording_clock_decides_is_left_out():
    a = {"duration_s": 1.0, "period_statistics": {"receive_period_ms": {"p50": 1.0}}, "k": 1}
    b = {"duration_s": 5.4, "period_statistics": {"receive_period_ms": {"p50": 0.5}}, "k": 1}
    assert differences(a, b) == []
    assert differences({**a, "k": 2}, b) == ["/k: 2 != 1"]
