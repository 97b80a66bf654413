"""References sampled as (q_d, q̇_d, q̈_d): validation, quintic segments, holding.

Tolerances. The test data have |Δp| ≤ 2, |v| ≤ 1, |a| ≤ 1 and segment lengths 1 ≤ h ≤ 2,
so in the normalised time x of reference._quintic (V = v h ≤ 2, A = a h² ≤ 4) the
coefficients are |c3| ≤ 48, |c4| ≤ 70, |c5| ≤ 28, and on every segment (h ≥ 1 only
shrinks the time derivatives) sup|q̇| ≤ 570, sup|q̈| ≤ 1.7e3, sup|q⁽³⁾| ≤ 3.7e3,
sup|q⁽⁴⁾| ≤ 5.1e3 (loose bounds; the actual values are ~100× smaller).
- One-sided limits at a waypoint, sampled ε = 1e-7 s before it: |f(t − ε) − f(t⁻)| ≤
  ε·sup|f′| gives 6e-5 (q), 1.7e-4 (q̇), 3.7e-4 (q̈): tolerances 1e-4, 2e-4, 5e-4. A real
  discontinuity would be of the order of the data (0.1–1).
- Central differences with step H = 1e-5 s: truncation H²/6·sup|f‴| ≤ 1e-7, rounding
  eps·sup|f|/H ≤ 2e-8: tolerance 1e-6.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.trajectories.reference import Reference, Sample, Trajectory

EPS_T = 1e-7  # [s] how far before a waypoint its left limit is sampled
TOL_Q, TOL_DQ, TOL_DDQ = 1e-4, 2e-4, 5e-4  # left limits (module docstring)
H = 1e-5  # [s] finite-difference step


# -- validation ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("times", "positions", "extra", "match"),
    [
        ([0.0, 1.0, 1.0], np.zeros((3, 2)), {}, "strictly increasing"),
        ([0.0, 2.0, 1.0], np.zeros((3, 2)), {}, "strictly increasing"),
        ([-0.1, 1.0], np.zeros((2, 2)), {}, ">= 0"),
        ([0.0, math.nan], np.zeros((2, 2)), {}, "non-finite times"),
        ([0.0, 1.0], [[0.0, math.nan], [0.0, 0.0]], {}, "non-finite positions"),
        ([0.0, 1.0], np.zeros((2, 2)), {"velocities": [[0, 0], [math.inf, 0]]}, "velocities"),
        ([0.0, 1.0], np.zeros((2, 2)), {"accelerations": [[0, 0], [0, math.nan]]}, "accel"),
        ([0.0, 1.0], np.zeros((3, 2)), {}, "2 times for 3 points"),
        ([0.0, 1.0], np.zeros((2, 2)), {"velocities": np.zeros((2, 3))}, "velocities have"),
        ([0.0, 1.0], np.zeros((2, 2)), {"accelerations": np.zeros((1, 2))}, "accelerations"),
        ([], np.zeros((0, 2)), {}, "0 times for 0 points"),
        ([], [], {}, "times"),
    ],
)
def test_build_rejects_invalid(times, positions, extra, match):
    with pytest.raises(ValueError, match=match):
        Trajectory.build(0.0, times, positions, **extra)


@pytest.mark.parametrize("start", [math.nan, math.inf])
def test_build_rejects_non_finite_start(start):
    with pytest.raises(ValueError, match="start"):
        Trajectory.build(start, [0.0], [[1.0]])


def test_build_fills_zero_derivatives_and_freezes():
    tr = Trajectory.build(2.0, [0.5, 1.5], [[1.0, 2.0], [3.0, 4.0]])
    assert tr.start == 2.0
    assert tr.end == 3.5
    np.testing.assert_array_equal(tr.velocities, np.zeros((2, 2)))
    np.testing.assert_array_equal(tr.accelerations, np.zeros((2, 2)))
    for arr in (tr.times, tr.positions, tr.velocities, tr.accelerations):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0


def test_build_does_not_alias_the_callers_times():
    times = np.array([0.0, 1.0])
    tr = Trajectory.build(0.0, times, [[0.0], [1.0]])
    times[1] = -1.0
    np.testing.assert_array_equal(tr.times, [0.0, 1.0])


def test_build_leaves_the_callers_positions_writable():
    positions = np.zeros((2, 1))
    Trajectory.build(0.0, [0.0, 1.0], positions)
    positions[0, 0] = 1.0  # raises "assignment destination is read-only"
    assert positions[0, 0] == 1.0


# -- hold ---------------------------------------------------------------------------------


def test_hold_is_constant_with_zero_derivatives():
    q = np.array([0.3, -1.2, 2.0])
    ref = Reference.hold(q, start=5.0)
    for t in (-100.0, 0.0, 4.999, 5.0, 5.001, 7.0, 1e6):
        s = ref.sample(t)
        np.testing.assert_array_equal(s.q, q)
        np.testing.assert_array_equal(s.dq, np.zeros(3))
        np.testing.assert_array_equal(s.ddq, np.zeros(3))


# -- quintic segments ----------------------------------------------------------------------


@pytest.fixture
def three_points() -> tuple[Trajectory, Sample]:
    """Three waypoints (the first at time 0) with given velocities and accelerations; the
    last point at rest so that holding it afterwards is continuous."""
    tr = Trajectory.build(
        10.0,
        [0.0, 1.0, 2.5],
        [[0.0, 1.0], [0.8, -0.5], [0.2, 0.4]],
        velocities=[[0.5, -0.2], [-0.7, 0.9], [0.0, 0.0]],
        accelerations=[[1.0, 0.0], [0.3, -1.0], [0.0, 0.0]],
    )
    initial = Sample(np.array([9.0, 9.0]), np.array([1.0, 1.0]), np.array([2.0, 2.0]))
    return tr, initial


def test_waypoints_are_matched_exactly(three_points):
    tr, initial = three_points
    ref = Reference(tr, initial)
    for k in range(len(tr.times) - 1):  # the last one is the hold (checked below)
        s = ref.sample(tr.start + tr.times[k])
        np.testing.assert_allclose(s.q, tr.positions[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(s.dq, tr.velocities[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(s.ddq, tr.accelerations[k], rtol=0, atol=1e-12)


def test_segment_end_conditions_and_continuity(three_points):
    """Left limits at the interior and final waypoints equal the point's (q, q̇, q̈)."""
    tr, initial = three_points
    ref = Reference(tr, initial)
    for k in (1, 2):
        t = tr.start + tr.times[k]
        before, at = ref.sample(t - EPS_T), ref.sample(t)
        for got, want, bound in (
            (before.q, tr.positions[k], TOL_Q),
            (before.dq, tr.velocities[k], TOL_DQ),
            (before.ddq, tr.accelerations[k], TOL_DDQ),
        ):
            np.testing.assert_allclose(got, want, rtol=0, atol=bound)
        # continuity: the sample at the waypoint (next segment or hold) is the same point
        np.testing.assert_allclose(at.q, before.q, rtol=0, atol=TOL_Q)
        np.testing.assert_allclose(at.dq, before.dq, rtol=0, atol=TOL_DQ)
        np.testing.assert_allclose(at.ddq, before.ddq, rtol=0, atol=TOL_DDQ)


def test_holds_the_last_point_after_the_end(three_points):
    tr, initial = three_points
    ref = Reference(tr, initial)
    for t in (tr.end, tr.end + 1e-9, tr.end + 3.0, tr.end + 1e6):
        s = ref.sample(t)
        np.testing.assert_array_equal(s.q, tr.positions[-1])
        np.testing.assert_array_equal(s.dq, np.zeros(2))
        np.testing.assert_array_equal(s.ddq, np.zeros(2))


def test_before_the_start_the_initial_sample_is_kept(three_points):
    tr, initial = three_points
    ref = Reference(tr, initial)
    s = ref.sample(tr.start - 0.5)
    np.testing.assert_array_equal(s.q, initial.q)
    np.testing.assert_array_equal(s.dq, initial.dq)
    np.testing.assert_array_equal(s.ddq, initial.ddq)
    # from its start the trajectory applies (first point at time 0: a step)
    np.testing.assert_allclose(ref.sample(tr.start).q, tr.positions[0], atol=1e-12)


def test_first_point_later_than_start_moves_from_the_initial_sample():
    tr = Trajectory.build(1.0, [2.0], [[1.0, -1.0]])
    initial = Sample(np.array([0.0, 0.5]), np.array([0.2, -0.1]), np.array([0.0, 0.3]))
    ref = Reference(tr, initial)
    s0 = ref.sample(1.0)
    np.testing.assert_allclose(s0.q, initial.q, atol=1e-12)
    np.testing.assert_allclose(s0.dq, initial.dq, atol=1e-12)
    np.testing.assert_allclose(s0.ddq, initial.ddq, atol=1e-12)
    # midpoint of a quintic Hermite segment of length h (independent closed form):
    # q(½) = p0 + Δp/2 + 5h(v0 − v1)/32 + h²(a0 + a1)/64
    h, p1 = 2.0, np.array([1.0, -1.0])
    expected = 0.5 * (initial.q + p1) + 5 * h * initial.dq / 32 + h**2 * initial.ddq / 64
    np.testing.assert_allclose(ref.sample(2.0).q, expected, rtol=0, atol=1e-12)
    left = ref.sample(3.0 - EPS_T)
    np.testing.assert_allclose(left.q, [1.0, -1.0], rtol=0, atol=TOL_Q)
    np.testing.assert_allclose(left.dq, [0.0, 0.0], rtol=0, atol=TOL_DQ)
    np.testing.assert_allclose(left.ddq, [0.0, 0.0], rtol=0, atol=TOL_DDQ)
    np.testing.assert_array_equal(ref.sample(3.0).q, [1.0, -1.0])


def test_rest_to_rest_segment_is_the_minimum_jerk_profile():
    """From rest to rest the quintic is p0 + Δ(10x³ − 15x⁴ + 6x⁵): golden values at x = ½."""
    tr = Trajectory.build(0.0, [0.0, 2.0], [[1.0], [3.0]])
    ref = Reference(tr, Sample(np.ones(1), np.zeros(1), np.zeros(1)))
    s = ref.sample(1.0)
    np.testing.assert_allclose(s.q, [2.0], atol=1e-12)  # halfway
    np.testing.assert_allclose(s.dq, [2.0 * 1.875 / 2.0], atol=1e-12)  # Δ·30x²(1−x)²/T
    np.testing.assert_allclose(s.ddq, [0.0], atol=1e-12)  # inflexion
    s = ref.sample(0.5)  # x = 1/4: 10/64 − 15/256 + 6/1024 = 0.103515625
    np.testing.assert_allclose(s.q, [1.0 + 2.0 * 0.103515625], atol=1e-12)


def test_derivatives_match_finite_differences(three_points):
    tr, initial = three_points
    ref = Reference(tr, initial)
    waypoints = tr.start + tr.times
    rng = np.random.default_rng(0)
    times = rng.uniform(tr.start, tr.end, 200)
    times = times[np.min(np.abs(times[:, None] - waypoints[None, :]), axis=1) > 1e-3]
    assert times.size > 150
    for t in times:
        plus, minus, mid = ref.sample(t + H), ref.sample(t - H), ref.sample(t)
        np.testing.assert_allclose((plus.q - minus.q) / (2 * H), mid.dq, rtol=0, atol=1e-6)
        np.testing.assert_allclose((plus.dq - minus.dq) / (2 * H), mid.ddq, rtol=0, atol=1e-6)
