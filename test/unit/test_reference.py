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


# -- filling in missing derivatives (C² interpolation) --------------------------------------
#
# Continuity is checked at t_k ± EPS_K: |f(t + ε) − f(t − ε)| ≤ 2ε·sup|f′| with the test data
# below (|Δq| ≤ 1.5, h ≥ 0.4 s) keeping sup|q⁽³⁾| well under 1e4, so 1e-5 covers q, q̇ and
# q̈ alike, while a real discontinuity (the old zero-velocity knots, a jump in q̈) is ≥ 1e-2.

EPS_K = 1e-9  # [s]
TOL_K = 1e-5


def rest(n: int) -> Sample:
    return Sample(np.zeros(n), np.zeros(n), np.zeros(n))


def assert_continuous(ref: Reference, t: float) -> None:
    before, after = ref.sample(t - EPS_K), ref.sample(t + EPS_K)
    for name in ("q", "dq", "ddq"):
        np.testing.assert_allclose(
            getattr(after, name), getattr(before, name), rtol=0, atol=TOL_K, err_msg=name
        )


def spline_by_slopes(t, p, v_first, v_last) -> np.ndarray:
    """Knot velocities of the clamped cubic spline from the slope form (an independent
    derivation, solved densely): h_k v_{k−1} + 2(h_{k−1} + h_k) v_k + h_{k−1} v_{k+1} =
    3(h_k d_{k−1} + h_{k−1} d_k), v_0 and v_N given."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    h, d = np.diff(t), np.diff(p, axis=0) / np.diff(t)[:, None]
    size = len(t)
    A, b = np.zeros((size, size)), np.zeros_like(p)
    A[0, 0], b[0] = 1.0, v_first
    A[-1, -1], b[-1] = 1.0, v_last
    for k in range(1, size - 1):
        A[k, k - 1], A[k, k], A[k, k + 1] = h[k], 2 * (h[k - 1] + h[k]), h[k - 1]
        b[k] = 3 * (h[k] * d[k - 1] + h[k - 1] * d[k])
    return np.linalg.solve(A, b)


@pytest.fixture
def positions_only() -> tuple[Trajectory, Sample]:
    """Four positions (first one later than the start), uneven spacing, tracked sample
    moving; two joints."""
    tr = Trajectory.build(
        1.0,
        [0.5, 1.3, 1.7, 2.6],
        [[0.4, -0.2], [1.2, 0.3], [0.9, 0.6], [0.2, -0.5]],
    )
    initial = Sample(np.array([0.1, 0.0]), np.array([0.3, -0.4]), np.array([0.5, 1.0]))
    return tr, initial


def test_build_records_which_derivatives_were_given():
    p = [[0.0], [1.0]]
    assert not Trajectory.build(0.0, [0.0, 1.0], p).velocities_given
    assert not Trajectory.build(0.0, [0.0, 1.0], p).accelerations_given
    tr = Trajectory.build(0.0, [0.0, 1.0], p, velocities=[[0.0], [0.0]])
    assert tr.velocities_given and not tr.accelerations_given


def test_spline_passes_through_the_points_and_ends_at_rest(positions_only):
    tr, initial = positions_only
    ref = Reference(tr, initial)
    for k in range(len(tr.times) - 1):
        np.testing.assert_allclose(
            ref.sample(tr.start + tr.times[k]).q, tr.positions[k], rtol=0, atol=1e-12
        )
    end = ref.sample(tr.end - EPS_K)
    np.testing.assert_allclose(end.q, tr.positions[-1], rtol=0, atol=TOL_K)
    np.testing.assert_allclose(end.dq, [0.0, 0.0], rtol=0, atol=TOL_K)
    np.testing.assert_allclose(end.ddq, [0.0, 0.0], rtol=0, atol=TOL_K)
    held = ref.sample(tr.end + 1.0)
    np.testing.assert_array_equal(held.q, tr.positions[-1])
    np.testing.assert_array_equal(held.dq, [0.0, 0.0])


def test_spline_is_c2_at_every_knot_including_start_and_end(positions_only):
    tr, initial = positions_only
    ref = Reference(tr, initial)
    for t in [tr.start, *(tr.start + tr.times)]:
        assert_continuous(ref, t)
    # leaving the tracked sample: q, q̇, q̈ all continuous
    s = ref.sample(tr.start + EPS_K)
    np.testing.assert_allclose(s.q, initial.q, rtol=0, atol=TOL_K)
    np.testing.assert_allclose(s.dq, initial.dq, rtol=0, atol=TOL_K)
    np.testing.assert_allclose(s.ddq, initial.ddq, rtol=0, atol=TOL_K)


def test_spline_does_not_stop_at_interior_points(positions_only):
    """Changed behaviour: a positions-only trajectory used to stop (q̇_d = 0) at every point."""
    tr, initial = positions_only
    ref = Reference(tr, initial)
    for k in range(len(tr.times) - 1):
        assert np.all(np.abs(ref.sample(tr.start + tr.times[k]).dq) > 0.05)


def test_spline_knot_values_match_an_independent_solution(positions_only):
    tr, initial = positions_only
    t, p, v, a = Reference(tr, initial).knots
    np.testing.assert_array_equal(t, np.concatenate(([0.0], tr.times)))
    np.testing.assert_array_equal(p, np.vstack((initial.q, tr.positions)))
    expected = spline_by_slopes(t, p, initial.dq, np.zeros(2))
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-12)
    # interior accelerations: the spline's, equal from both sides of each knot
    h, d = np.diff(t)[:, None], np.diff(p, axis=0) / np.diff(t)[:, None]
    from_left = (-6 * d + 2 * v[:-1] + 4 * v[1:]) / h
    from_right = (6 * d - 4 * v[:-1] - 2 * v[1:]) / h
    np.testing.assert_allclose(from_left[:-1], from_right[1:], rtol=0, atol=1e-11)
    np.testing.assert_allclose(a[1:-1], from_right[1:], rtol=0, atol=1e-11)
    np.testing.assert_array_equal(a[0], initial.ddq)
    np.testing.assert_array_equal(a[-1], [0.0, 0.0])


@pytest.mark.parametrize("points", [*range(1, 18), 1000])
def test_spline_of_any_length_matches_the_dense_solution(points):
    """Every size around the powers of two of the cyclic reduction, and a long one."""
    rng = np.random.default_rng(points)
    times = np.cumsum(rng.uniform(0.01, 1.0, points))
    positions = rng.uniform(-1.0, 1.0, (points, 2))
    initial = Sample(rng.normal(size=2), rng.normal(size=2), rng.normal(size=2))
    t, p, v, _ = Reference(Trajectory.build(0.0, times, positions), initial).knots
    expected = spline_by_slopes(t, p, initial.dq, np.zeros(2))
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-9)


def test_long_uneven_spline_matches_the_dense_solution():
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.05, 2.0, 60))
    positions = rng.uniform(-2.0, 2.0, (60, 3))
    initial = Sample(rng.normal(size=3), rng.normal(size=3), rng.normal(size=3))
    t, p, v, _ = Reference(Trajectory.build(0.0, times, positions), initial).knots
    expected = spline_by_slopes(t, p, initial.dq, np.zeros(3))
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-9)


def test_points_on_a_cubic_with_matching_ends_are_reproduced_exactly():
    """q(t) = c + b (t − T)³ has q̇(T) = q̈(T) = 0: started from its own (q, q̇, q̈) at 0 the
    reference is that cubic everywhere, to rounding."""
    T, c, b = 3.0, np.array([0.5, -1.0]), np.array([0.05, -0.02])

    def cubic(t):
        return c + b * (t - T) ** 3, 3 * b * (t - T) ** 2, 6 * b * (t - T)

    knots = [0.7, 1.1, 2.0, T]
    q0, dq0, ddq0 = cubic(0.0)
    ref = Reference(
        Trajectory.build(2.0, knots, [cubic(t)[0] for t in knots]), Sample(q0, dq0, ddq0)
    )
    for s in np.linspace(0.0, T, 301):
        got, (q, dq, ddq) = ref.sample(2.0 + s), cubic(s)
        np.testing.assert_allclose(got.q, q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.dq, dq, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.ddq, ddq, rtol=0, atol=1e-11)


def test_interior_segments_are_the_cubic_spline_and_end_segments_stay_close():
    """Points on q(t) = t³ − 4.5 t² + 6 t, q̇ = 3(t − 1)(t − 2): with the tracked q̇ = q̇(0) = 6
    and q̇(2) = 0 the clamped spline on [0, 2] is the polynomial itself. Only the end
    accelerations differ (tracked q̈ = 0 instead of −9 at the start, 0 instead of 3 at the
    end), so the end segments deviate by at most 0.0173 |Δq̈| h² (module docstring)."""

    def cubic(t):
        return t**3 - 4.5 * t**2 + 6 * t, 3 * t**2 - 9 * t + 6, 6 * t - 9

    knots = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    tr = Trajectory.build(0.0, knots, [[cubic(t)[0]] for t in knots])
    ref = Reference(tr, Sample(np.zeros(1), np.array([6.0]), np.zeros(1)))
    for s in np.linspace(0.5, 1.5, 101):  # interior segments: exact
        got, (q, dq, ddq) = ref.sample(s), cubic(s)
        np.testing.assert_allclose([got.q[0], got.dq[0], got.ddq[0]], [q, dq, ddq], atol=1e-12)
    for s in np.concatenate((np.linspace(0.0, 0.5, 51), np.linspace(1.5, 2.0, 51))):
        dev = abs(ref.sample(s).q[0] - cubic(s)[0])
        assert dev <= 0.01728 * 9.0 * 0.25 + 1e-12  # |Δq̈| ≤ 9, h = 0.5
    for t in knots:
        assert_continuous(ref, t)


def test_two_positions_from_a_moving_sample_leave_it_smoothly():
    """Changed behaviour: with the first point at 0 and no velocities, the start velocity and
    acceleration are the tracked ones (they were 0)."""
    initial = Sample(np.array([1.0]), np.array([0.4]), np.array([-0.3]))
    ref = Reference(Trajectory.build(5.0, [0.0, 2.0], [[1.0], [3.0]]), initial)
    s = ref.sample(5.0)
    np.testing.assert_allclose([s.q[0], s.dq[0], s.ddq[0]], [1.0, 0.4, -0.3], atol=1e-12)
    assert_continuous(ref, 5.0)
    assert_continuous(ref, 7.0)


def test_single_points_keep_their_behaviour():
    moving = Sample(np.array([0.2, 0.1]), np.array([1.0, -1.0]), np.array([2.0, 0.5]))
    step = Reference(Trajectory.build(3.0, [0.0], [[0.5, -0.3]]), moving)
    for t in (3.0, 3.0 + 1e-9, 4.0):
        s = step.sample(t)
        np.testing.assert_array_equal(s.q, [0.5, -0.3])
        np.testing.assert_array_equal(s.dq, [0.0, 0.0])
        np.testing.assert_array_equal(s.ddq, [0.0, 0.0])
    assert step.sample(3.0 - 1e-9) is moving
    # one point later than the start: quintic from the tracked sample to rest
    move = Reference(Trajectory.build(3.0, [2.0], [[0.5, -0.3]]), moving)
    _, _, v, a = move.knots
    np.testing.assert_array_equal(v, [moving.dq, [0.0, 0.0]])
    np.testing.assert_array_equal(a, [moving.ddq, [0.0, 0.0]])


def test_given_velocities_are_kept_and_accelerations_make_it_c2(positions_only):
    tr0, initial = positions_only
    velocities = [[0.5, 0.0], [-0.2, 0.4], [-1.0, 0.1], [0.0, 0.0]]
    tr = Trajectory.build(tr0.start, tr0.times, tr0.positions, velocities=velocities)
    ref = Reference(tr, initial)
    for k, t in enumerate(tr.start + tr.times[:-1]):
        np.testing.assert_allclose(ref.sample(t).dq, velocities[k], rtol=0, atol=1e-12)
    for t in [tr.start, *(tr.start + tr.times)]:
        assert_continuous(ref, t)
    t, p, v, a = ref.knots
    # interior: mean of the one-sided cubic accelerations (golden values from the formula)
    h = np.diff(t)[:, None]
    d = np.diff(p, axis=0) / h
    left = (-6 * d[:-1] + 2 * v[:-2] + 4 * v[1:-1]) / h[:-1]
    right = (6 * d[1:] - 4 * v[1:-1] - 2 * v[2:]) / h[1:]
    np.testing.assert_allclose(a[1:-1], 0.5 * (left + right), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a[0], initial.ddq)
    np.testing.assert_array_equal(a[-1], [0.0, 0.0])


def test_given_spline_velocities_reproduce_the_spline(positions_only):
    """Velocities taken from the positions-only spline give the same reference."""
    tr, initial = positions_only
    spline = Reference(tr, initial)
    _, _, v, _ = spline.knots
    with_v = Reference(Trajectory.build(tr.start, tr.times, tr.positions, v[1:]), initial)
    for s in np.linspace(tr.start - 0.1, tr.end + 0.1, 157):
        a, b = spline.sample(s), with_v.sample(s)
        np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.dq, a.dq, rtol=0, atol=1e-11)
        np.testing.assert_allclose(b.ddq, a.ddq, rtol=0, atol=1e-10)


def test_accelerations_without_velocities_take_zero_velocities():
    tr = Trajectory.build(0.0, [0.0, 1.0], [[0.0], [1.0]], accelerations=[[0.5], [0.0]])
    _, _, v, a = Reference(tr, rest(1)).knots
    np.testing.assert_array_equal(v, [[0.0], [0.0]])
    np.testing.assert_array_equal(a, [[0.5], [0.0]])


def test_spline_derivatives_match_finite_differences(positions_only):
    tr, initial = positions_only
    ref = Reference(tr, initial)
    knots = tr.start + np.concatenate(([0.0], tr.times))
    times = np.linspace(tr.start, tr.end, 401)
    times = times[np.min(np.abs(times[:, None] - knots[None, :]), axis=1) > 1e-3]
    for t in times:
        plus, minus, mid = ref.sample(t + H), ref.sample(t - H), ref.sample(t)
        np.testing.assert_allclose((plus.q - minus.q) / (2 * H), mid.dq, rtol=0, atol=1e-6)
        np.testing.assert_allclose((plus.dq - minus.dq) / (2 * H), mid.ddq, rtol=0, atol=1e-6)


@pytest.mark.parametrize("lead", [0.0, 0.5])
def test_a_prepared_spline_equals_the_one_solved_at_activation(lead):
    """Trajectory.prepared (the reference worker's): the knots of the Reference that starts
    it from any sample equal the directly solved clamped spline's to 1e-13 (relative), with
    and without a leading segment from the sample; the first and last knot velocities are
    exact. Trajectories with velocities keep no basis."""
    rng = np.random.default_rng(1)
    times = lead + np.cumsum(rng.uniform(0.01, 0.1, 500))
    tr = Trajectory.build(2.0, times, rng.normal(size=(500, 3)))
    prepared = tr.prepared()
    assert prepared.basis is not None and tr.basis is None
    for _ in range(5):
        initial = Sample(rng.normal(size=3), rng.normal(size=3), rng.normal(size=3))
        direct, combined = Reference(tr, initial).knots, Reference(prepared, initial).knots
        for x, y in zip(direct, combined, strict=True):
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-13 * max(1.0, np.abs(x).max()))
        np.testing.assert_array_equal(combined[2][0], initial.dq)
        np.testing.assert_array_equal(combined[2][-1], 0.0)
    with_v = Trajectory.build(0.0, times, np.ones((500, 3)), np.zeros((500, 3)))
    assert with_v.prepared() is with_v


@pytest.mark.parametrize("lead", [0.0, 0.5])
@pytest.mark.parametrize("given", ["positions", "velocities", "both"])
def test_knots_filled_block_by_block_sample_as_filled_at_once(monkeypatch, lead, given):
    """Reference fills its knot rows a block at a time as sampling reaches them (a start
    is O(1) in the points): with blocks of 3 rows, sampled out of order, every sample and
    the knots are bit-identical to blocks larger than the trajectory (all filled at the
    first sample)."""
    rng = np.random.default_rng(7)
    m = 40
    times = lead + np.concatenate(([0.0], np.cumsum(rng.uniform(0.01, 0.1, m - 1))))
    extra = {}
    if given in ("velocities", "both"):
        extra["velocities"] = rng.normal(size=(m, 2))
    if given == "both":
        extra["accelerations"] = rng.normal(size=(m, 2))
    tr = Trajectory.build(1.0, times, rng.normal(size=(m, 2)), **extra).prepared()
    initial = Sample(rng.normal(size=2), rng.normal(size=2), rng.normal(size=2))
    instants = 1.0 + rng.uniform(-0.1, times[-1] + 0.1, 300)

    def run(block: int):
        monkeypatch.setattr(Reference, "BLOCK", block)
        ref = Reference(tr, initial)
        samples = [ref.sample(t) for t in instants]
        return samples, ref.knots

    small, small_knots = run(3)
    whole, whole_knots = run(10**6)
    for a, b in zip(small, whole, strict=True):
        for x, y in ((a.q, b.q), (a.dq, b.dq), (a.ddq, b.ddq)):
            np.testing.assert_array_equal(x, y)
    for x, y in zip(small_knots, whole_knots, strict=True):
        np.testing.assert_array_equal(x, y)
    assert small_knots[0].size == m + int(lead > 0)
