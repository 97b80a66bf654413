"""A measured state far outside what the arm can do is refused (laws/plausible.py): the
bounds, the reason naming the joints, and what stays accepted."""

from __future__ import annotations

import numpy as np

from joint_space_control.laws.plausible import (
    POSITION_SLACK,
    SPEED_BOUND,
    UNLIMITED_POSITION,
    PlausibleStates,
)

LOWER, UPPER = np.array([-2.0, -np.inf]), np.array([1.0, np.inf])
NAMES = ("elbow", "wheel")


def test_within_half_a_turn_of_the_limits_and_any_sane_speed_is_plausible():
    check = PlausibleStates(LOWER, UPPER, NAMES)
    for q in ([-2.0 - POSITION_SLACK, 0.0], [1.0 + POSITION_SLACK, UNLIMITED_POSITION]):
        assert check.reason(np.array(q), np.array([SPEED_BOUND, -SPEED_BOUND])) == ""
    assert check.reason(np.array([0.0, -123.0]), np.array([])) == ""  # no velocity measured


def test_beyond_the_bounds_is_refused_naming_the_joint():
    check = PlausibleStates(LOWER, UPPER, NAMES)
    over = 1.0 + POSITION_SLACK + 1e-6
    reason = check.reason(np.array([over, 0.0]), np.zeros(2))
    assert reason.startswith("implausible measurement: positions beyond the joints' limits")
    assert "elbow at 4.142" in reason and "wheel" not in reason
    reason = check.reason(np.array([0.0, -1e9]), np.zeros(2))
    assert "wheel at -1e+09 (range [-1e+04, 1e+04])" in reason
    reason = check.reason(np.zeros(2), np.array([0.0, 1.5 * SPEED_BOUND]))
    assert reason == "implausible measurement: speeds beyond 1000: wheel at 1500/s"
