"""Reference shapes: values against the analytic formulas, at the samples and between them
(through the controllers' own sampler, :class:`Reference`), and validation one by one; then
the trajectory_generator node's pure helpers (no ROS graph): parameters → shape, and shape →
message → what the controllers parse (``messages.trajectory_from_msg``).

Between samples the sinusoid is a quintic Hermite interpolation of exact (q, q̇, q̈); its
remainder is f⁽⁶⁾(ξ)((t − a)(t − b))³/6!, whose maxima over a step h, with
|f⁽⁶⁾| ≤ Δω⁶, are Δω⁶h⁶/46080 (q), Δω⁶h⁵/13416 (q̇) and Δω⁶h⁴/1920 (q̈). The tests allow
10 % above these leading-order bounds (plus rounding).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.nodes.trajectory_generator import (
    PARAMETERS,
    build_config,
    trajectory_message,
)
from joint_space_control.ros.messages import JointOrder, stamp_to_ns, trajectory_from_msg
from joint_space_control.trajectories import shapes
from joint_space_control.trajectories.reference import Reference, Sample
from joint_space_control.trajectories.shapes import quintic, sinusoid, step, waypoints


def rest(q) -> Sample:
    q = np.asarray(q, dtype=float)
    return Sample(q, np.zeros_like(q), np.zeros_like(q))


def shift(tr, start):
    """The same trajectory starting at ``start`` (what a stamped message does)."""
    return type(tr).build(start, tr.times, tr.positions, tr.velocities, tr.accelerations)


# -- step ----------------------------------------------------------------------------------


def test_step_is_one_point_at_time_zero():
    tr = step([0.5, -0.3])
    assert tr.start == 0.0
    np.testing.assert_array_equal(tr.times, [0.0])
    np.testing.assert_array_equal(tr.positions, [[0.5, -0.3]])
    assert not tr.velocities_given and not tr.accelerations_given
    ref = Reference(tr, Sample(np.zeros(2), np.ones(2), np.ones(2)))
    s = ref.sample(0.0)
    np.testing.assert_array_equal(s.q, [0.5, -0.3])
    np.testing.assert_array_equal(s.dq, [0.0, 0.0])
    np.testing.assert_array_equal(s.ddq, [0.0, 0.0])


def test_step_broadcasts_one_value():
    np.testing.assert_array_equal(step(0.2, n=3).positions, [[0.2, 0.2, 0.2]])


# -- sinusoid ------------------------------------------------------------------------------

CENTER, AMPLITUDE, PHASE = np.array([0.1, -0.2, 0.4]), np.array([0.3, 0.5, -0.2]), [0.0, 1.0, -2.0]


def analytic(t, omega, center=CENTER, amplitude=AMPLITUDE, phase=PHASE):
    angle = np.multiply.outer(np.atleast_1d(t), omega) + np.asarray(phase)
    return (
        center + amplitude * np.sin(angle),
        amplitude * omega * np.cos(angle),
        -amplitude * omega**2 * np.sin(angle),
    )


def test_sinusoid_samples_are_exact():
    omega = np.array([2 * math.pi, 3.0, 0.5])
    tr = sinusoid(CENTER, AMPLITUDE, omega, PHASE, duration=2.0, sample_period=0.01)
    assert tr.times.size == 201
    np.testing.assert_allclose(tr.times, np.arange(201) * 0.01, rtol=0, atol=1e-15)
    q, dq, ddq = analytic(tr.times, omega)
    np.testing.assert_allclose(tr.positions, q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(tr.velocities, dq, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.accelerations, ddq, rtol=0, atol=1e-13)


@pytest.mark.parametrize(("omega", "h"), [(2 * math.pi, 0.01), (10.0, 0.01), (10.0, 0.003)])
def test_sinusoid_between_samples_within_the_hermite_bound(omega, h):
    duration = 1.0
    tr = sinusoid(CENTER, AMPLITUDE, omega, PHASE, duration, h)
    start = 7.0
    ref = Reference(shift(tr, start), rest(np.zeros(3)))
    times = np.linspace(0.0, duration, 2999, endpoint=False)  # the end is the hold
    q, dq, ddq = analytic(times, np.full(3, omega))
    worst = np.max(np.abs(AMPLITUDE)) * omega**6
    bounds = (worst * h**6 / 46080, worst * h**5 / 13416, worst * h**4 / 1920)
    err = np.zeros(3)
    for k, s in enumerate(times):
        got = ref.sample(start + s)
        err = np.maximum(
            err,
            [
                np.max(np.abs(got.q - q[k])),
                np.max(np.abs(got.dq - dq[k])),
                np.max(np.abs(got.ddq - ddq[k])),
            ],
        )
    rounding = np.array([1e-14, 1e-12, 1e-9])  # start + s loses ~1e-15 s; /h, /h² amplify
    assert np.all(err <= 1.1 * np.array(bounds) + rounding), (err, bounds)
    assert np.all(err[:2] >= 0.5 * np.array(bounds[:2])), "the bound should be nearly reached"


def test_sinusoid_starts_moving_unless_phased_to_rest():
    omega = 2.0
    tr = sinusoid(0.5, 0.2, omega, 0.0, 1.0)
    np.testing.assert_allclose(tr.positions[0], [0.5])
    np.testing.assert_allclose(tr.velocities[0], [0.2 * omega])  # Δω: the reference jumps
    tr = sinusoid(0.5, 0.2, omega, math.pi / 2, 1.0)
    np.testing.assert_allclose(tr.positions[0], [0.7])
    np.testing.assert_allclose(tr.velocities[0], [0.0], atol=1e-16)
    np.testing.assert_allclose(tr.accelerations[0], [-0.2 * omega**2])


def test_sinusoid_broadcasts_and_checks_the_joint_count():
    tr = sinusoid(CENTER, 0.1, 1.0, 0.0, 0.5)
    assert tr.positions.shape == (51, 3)
    assert sinusoid(0.0, 0.1, 1.0, 0.0, 0.5, n=7).positions.shape == (51, 7)


@pytest.mark.parametrize(
    ("duration", "h", "expected"),
    [
        (1.0, 0.3, [0.0, 0.3, 0.6, 0.9, 1.0]),  # last interval shorter
        (0.3, 0.1, [0.0, 0.1, 0.2, 0.3]),  # 0.3/0.1 = 2.9999999999999996: no sliver
        (0.05, 0.1, [0.0, 0.05]),  # shorter than one period: the two ends
    ],
)
def test_sample_times_end_exactly_at_the_duration(duration, h, expected):
    np.testing.assert_allclose(shapes.sample_times(duration, h), expected, rtol=0, atol=1e-15)


def test_sinusoid_of_zero_frequency_is_constant():
    tr = sinusoid([0.0, 1.0], [0.5, 0.5], [0.0, 0.0], [math.pi / 2, 0.0], 0.2)
    np.testing.assert_allclose(tr.positions, np.tile([0.5, 1.0], (21, 1)))
    np.testing.assert_array_equal(tr.velocities, np.zeros((21, 2)))


# -- quintic -------------------------------------------------------------------------------


def min_jerk(q0, q1, T, t):
    x = t / T
    d = np.asarray(q1) - np.asarray(q0)
    return (
        q0 + d * (10 * x**3 - 15 * x**4 + 6 * x**5),
        d * (30 * x**2 - 60 * x**3 + 30 * x**4) / T,
        d * (60 * x - 180 * x**2 + 120 * x**3) / T**2,
    )


def test_quintic_is_the_minimum_jerk_profile():
    q0, q1, T = np.array([0.1, -0.4]), np.array([0.9, 0.6]), 2.5
    tr = quintic(q0, q1, T)
    np.testing.assert_array_equal(tr.times, [0.0, T])
    np.testing.assert_array_equal(tr.positions, [q0, q1])
    np.testing.assert_array_equal(tr.velocities, np.zeros((2, 2)))
    np.testing.assert_array_equal(tr.accelerations, np.zeros((2, 2)))
    ref = Reference(shift(tr, 3.0), rest([5.0, 5.0]))  # tracked elsewhere: jumps to q0
    for t in np.linspace(0.0, T, 51):
        got, (q, dq, ddq) = ref.sample(3.0 + t), min_jerk(q0, q1, T, t)
        if t == T:
            dq, ddq = np.zeros(2), np.zeros(2)
        np.testing.assert_allclose(got.q, q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.dq, dq, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.ddq, ddq, rtol=0, atol=1e-12)


def test_quintic_without_start_moves_from_the_tracked_sample():
    q0, q1, T = np.array([0.3, 0.2]), np.array([-0.5, 1.0]), 1.5
    tr = quintic(None, q1, T)
    np.testing.assert_array_equal(tr.times, [T])
    np.testing.assert_array_equal(tr.positions, [q1])
    ref = Reference(tr, rest(q0))
    for t in np.linspace(0.0, T, 31):
        got, (q, dq, ddq) = ref.sample(t), min_jerk(q0, q1, T, t)
        np.testing.assert_allclose(got.q, q, rtol=0, atol=1e-12)
        if t < T:
            np.testing.assert_allclose(got.dq, dq, rtol=0, atol=1e-12)
            np.testing.assert_allclose(got.ddq, ddq, rtol=0, atol=1e-12)


# -- waypoints -----------------------------------------------------------------------------


def test_waypoints_without_velocities_are_splined_through_the_points():
    p = [[0.5, 0.0], [1.0, 0.5], [0.2, 0.2]]
    tr = waypoints(p, [1.0, 2.0, 3.5], n=2)
    assert not tr.velocities_given and not tr.accelerations_given
    ref = Reference(tr, rest([0.0, 0.0]))
    for t, q in zip([1.0, 2.0, 3.5], p, strict=True):
        np.testing.assert_allclose(ref.sample(t).q, q, rtol=0, atol=1e-12)
    assert np.any(ref.sample(1.0).dq != 0)  # does not stop at the waypoints
    np.testing.assert_array_equal(ref.sample(3.5).dq, [0.0, 0.0])


def test_waypoints_with_velocities_keep_them():
    v = [[0.1, 0.0], [0.0, -0.2]]
    tr = waypoints([[0.5, 0.0], [1.0, 0.5]], [0.5, 1.0], v)
    assert tr.velocities_given and not tr.accelerations_given
    np.testing.assert_array_equal(tr.velocities, v)
    np.testing.assert_allclose(Reference(tr, rest([0.0, 0.0])).sample(0.5).dq, v[0], atol=1e-12)


# -- validation ----------------------------------------------------------------------------

NAN, INF = math.nan, math.inf


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: step([]), "'target' is empty"),
        (lambda: step([0.1, NAN]), "'target' must be finite"),
        (lambda: step([0.1, 0.2], n=3), "'target' needs 1 or 3 values"),
        (lambda: step("up"), "'target' must be numbers"),
        (lambda: step([0.1], n=0), "number of joints"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, 0.0), "'duration' must be finite and > 0"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, -1.0), "'duration'"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, INF), "'duration'"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, NAN), "'duration'"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, 1.0, 0.0), "'sample_period' must be finite"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, 1.0, True), "'sample_period' must be a number"),
        (lambda: sinusoid(0.0, 0.1, -1.0, 0.0, 1.0), "'omega' must be >= 0"),
        (lambda: sinusoid([0.0, 0.0], [0.1] * 3, 1.0, 0.0, 1.0), "'center' needs 1 or 3"),
        (lambda: sinusoid([0.0, 0.0], 0.1, 1.0, 0.0, 1.0, n=3), "'center' needs 1 or 3"),
        (lambda: sinusoid([0.0, NAN], 0.1, 1.0, 0.0, 1.0), "'center' must be finite"),
        (lambda: sinusoid(0.0, INF, 1.0, 0.0, 1.0), "'amplitude' must be finite"),
        (lambda: sinusoid(0.0, 0.1, 1.0, [], 1.0), "'phase' is empty"),
        (lambda: sinusoid(0.0, 0.1, 1.0, 0.0, 1000.0, 0.01), "at most 20001"),
        (lambda: quintic([0.0], [1.0], 0.0), "'duration' must be finite and > 0"),
        (lambda: quintic([0.0, 0.0], [1.0, 2.0, 3.0], 1.0), "'start' needs 1 or 3"),
        (lambda: quintic([0.0], [NAN], 1.0), "'goal' must be finite"),
        (lambda: quintic(None, [1.0, 2.0], 1.0, n=3), "'goal' needs 1 or 3"),
        (lambda: waypoints([0.1, 0.2], [1.0, 2.0]), "m × n array"),
        (lambda: waypoints(np.zeros((0, 2)), []), "m × n array"),
        (lambda: waypoints([[0.1, 0.2]], [1.0], n=3), "2 columns for 3 joints"),
        (lambda: waypoints([[0.1], [0.2]], [1.0]), "1 times for 2 waypoints"),
        (lambda: waypoints([[0.1], [0.2]], [1.0, 1.0]), "strictly increasing"),
        (lambda: waypoints([[0.1], [0.2]], [-1.0, 1.0]), ">= 0"),
        (lambda: waypoints([[0.1], [NAN]], [1.0, 2.0]), "non-finite waypoint positions"),
        (lambda: waypoints([[0.1], [0.2]], [1.0, INF]), "non-finite waypoint times"),
        (lambda: waypoints([[0.1], [0.2]], [1.0, 2.0], [[0.0], [NAN]]), "velocities"),
        (lambda: waypoints([[0.1], [0.2]], [1.0, 2.0], [[0.0]]), "'velocities' have shape"),
        (lambda: waypoints([[0.1], ["x"]], [1.0, 2.0]), "must be numbers"),
    ],
)
def test_invalid_shapes_rejected(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_too_many_waypoints_rejected():
    m = shapes.MAX_POINTS + 1
    with pytest.raises(ValueError, match=f"{m} waypoints"):
        waypoints(np.zeros((m, 1)), np.arange(m, dtype=float))


# -- the node's helpers: parameters → shape → message → controller ---------------------------

DEFAULTS = {spec.name: spec.default for spec in PARAMETERS}


def config(**changes):
    return build_config({**DEFAULTS, **changes}, 2)


def test_default_parameters_are_a_step_to_zero():
    cfg = config()
    assert cfg.shape == "step" and not cfg.needs_current
    np.testing.assert_array_equal(cfg.trajectory().positions, [[0.0, 0.0]])


def test_parameters_select_the_shape():
    tr = config(shape="sinusoid", center=[0.1, 0.2], amplitude=0.3, omega=[1.0, 2.0]).trajectory()
    np.testing.assert_allclose(tr.velocities[0], [0.3, 0.6])
    assert config(shape="quintic", target=[1.0, 2.0]).trajectory().times.tolist() == [5.0]
    cfg = config(shape="quintic", target=[1.0, 2.0], start_from_current=True)
    assert cfg.needs_current
    np.testing.assert_array_equal(cfg.trajectory(np.array([0.5, 0.5])).positions[0], [0.5, 0.5])
    with pytest.raises(ValueError, match="needs the current configuration"):
        cfg.trajectory()
    cfg = config(shape="sinusoid", start_from_current=True)  # empty centre: the current one
    assert cfg.needs_current
    assert config(shape="sinusoid", start_from_current=True, center=None).needs_current  # YAML []
    np.testing.assert_allclose(cfg.trajectory(np.array([1.0, -1.0])).positions[0], [1.0, -1.0])
    cfg = config(shape="waypoints", waypoints=[1, 2, 3, 4, 5, 6], waypoint_times=[1, 2, 3])
    np.testing.assert_array_equal(cfg.trajectory().positions, [[1, 2], [3, 4], [5, 6]])


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"shape": "square"}, "'shape' is 'square'"),
        ({"target": [1.0, 2.0, 3.0]}, "'target' needs 1 or 2"),
        ({"target": "high"}, "'target' must be a number"),
        ({"omega": [1.0, -1.0]}, "'omega' must be >= 0"),
        ({"center": [0.0, NAN]}, "'center' must be finite"),
        ({"duration": 0.0}, "'duration' must be a number > 0"),
        ({"sample_period": -0.01}, "'sample_period'"),
        ({"start_delay": -1.0}, "'start_delay' must be a number >= 0"),
        ({"waypoints": [0.0, 1.0, 2.0]}, "3 values, not a multiple of the 2 joints"),
        ({"waypoints": [0.0, INF]}, "'waypoints' must be finite"),
        ({"waypoint_times": [1.0, 1.0]}, "strictly increasing"),
        ({"waypoint_times": [-1.0]}, ">= 0"),
        ({"shape": "sinusoid"}, "'center' is empty"),
        ({"shape": "sinusoid", "center": 0.0, "duration": 1e3}, "samples"),
        ({"shape": "waypoints"}, "needs 'waypoints' and 'waypoint_times'"),
        (
            {"shape": "waypoints", "waypoints": [0.0] * 4, "waypoint_times": [1.0]},
            "2 waypoints but 1 waypoint_times",
        ),
    ],
)
def test_invalid_parameters_rejected(changes, match):
    with pytest.raises(ValueError, match=match):
        config(**changes)


@pytest.mark.parametrize(
    "tr",
    [
        step([0.5, -0.3]),
        sinusoid([0.1, 0.2], 0.3, [2.0, 3.0], 0.4, 1.0),
        quintic([0.0, 0.1], [1.0, 2.0], 1.5),
        quintic(None, [1.0, 2.0], 1.5),
        waypoints([[0.1, 0.2], [0.3, 0.4]], [0.5, 1.25]),
        waypoints([[0.1, 0.2], [0.3, 0.4]], [0.5, 1.25], [[1.0, 0.0], [0.0, 0.0]]),
    ],
)
def test_shapes_reach_the_controllers_unchanged(tr):
    joints = ("j1", "j2")
    msg = trajectory_message(tr, joints)
    assert list(msg.joint_names) == list(joints) and stamp_to_ns(msg.header.stamp) == 0
    got = trajectory_from_msg(msg, JointOrder(joints), now=3.0, origin_ns=0)
    assert got.start == 3.0
    np.testing.assert_allclose(got.times, tr.times, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got.positions, tr.positions)
    assert (got.velocities_given, got.accelerations_given) == (
        tr.velocities_given,
        tr.accelerations_given,
    )
    np.testing.assert_array_equal(got.velocities, tr.velocities)
    np.testing.assert_array_equal(got.accelerations, tr.accelerations)


def test_message_stamp_and_time_resolution():
    msg = trajectory_message(step([0.0]), ["j"], stamp_ns=12_500_000_000)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 500_000_000)
    with pytest.raises(ValueError, match="closer than 1 ns"):
        trajectory_message(waypoints([[0.0], [1.0]], [1.0, 1.0 + 1e-10]), ["j"])
    with pytest.raises(ValueError, match="1 columns for 2 joints"):
        trajectory_message(step([0.0]), ["a", "b"])
