"""Message ↔ array conversion and parameter validation at the node boundary (STYLE.md §3).

Only message classes are used (no ROS graph): every function either returns arrays in
the controlled-joint order or raises ValueError with a reason.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.ros.messages import (
    STATE_FIELDS,
    JointOrder,
    effort_arrays,
    float_array,
    joint_state_arrays,
    ns_to_stamp,
    stamp_to_ns,
    state_message,
    trajectory_from_msg,
)
from joint_space_control.ros.parameters import ParamSpec, names, numbers

MODE = ParamSpec("mode", "full", "", choices=("full", "none", "desired"))
RATE = ParamSpec("rate", 1.0, "", minimum=0.0, exclusive=True)
F = ParamSpec("f", 0.0, "", minimum=0.0)

JOINTS = ("j1", "j2", "j3")


def joint_state(names_, position, velocity=None, effort=None) -> JointState:
    msg = JointState()
    msg.name = list(names_)
    msg.position = [float(v) for v in position]
    msg.velocity = [float(v) for v in (velocity if velocity is not None else position)]
    msg.effort = [float(v) for v in (effort if effort is not None else position)]
    return msg


def point(positions, t: float, velocities=(), accelerations=()) -> JointTrajectoryPoint:
    sec = int(math.floor(t))
    return JointTrajectoryPoint(
        positions=[float(v) for v in positions],
        velocities=[float(v) for v in velocities],
        accelerations=[float(v) for v in accelerations],
        time_from_start=Duration(sec=sec, nanosec=round((t - sec) * 1e9)),
    )


def trajectory(joint_names, points, stamp_ns: int = 0) -> JointTrajectory:
    msg = JointTrajectory()
    msg.joint_names = list(joint_names)
    msg.points = list(points)
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


# -- JointOrder ------------------------------------------------------------------------------


def test_joint_order_maps_every_permutation():
    values = {"j1": 1.0, "j2": 2.0, "j3": 3.0}
    for perm in itertools.permutations(JOINTS):
        order = JointOrder(JOINTS)  # fresh: no cached permutation
        msg = joint_state(perm, [values[n] for n in perm], [10 * values[n] for n in perm])
        q, dq = joint_state_arrays(msg, order)
        np.testing.assert_array_equal(q, [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(dq, [10.0, 20.0, 30.0])
        np.testing.assert_array_equal(effort_arrays(msg, order), [1.0, 2.0, 3.0])


def test_joint_order_follows_changing_name_lists():
    """The cached permutation is refreshed when the names change between messages."""
    order = JointOrder(JOINTS)
    for perm in [*itertools.permutations(JOINTS), JOINTS, JOINTS[::-1]]:
        msg = joint_state(perm, [float(n[1]) for n in perm])
        np.testing.assert_array_equal(joint_state_arrays(msg, order)[0], [1.0, 2.0, 3.0])


def test_extra_joints_allowed_in_states_rejected_in_commands():
    msg = joint_state(["finger", "j3", "j1", "j2"], [9.0, 3.0, 1.0, 2.0])
    q, _ = joint_state_arrays(msg, JointOrder(JOINTS))
    np.testing.assert_array_equal(q, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"unknown joints \['finger'\]"):
        effort_arrays(msg, JointOrder(JOINTS))


def test_missing_and_duplicated_names_rejected():
    order = JointOrder(JOINTS)
    with pytest.raises(ValueError, match=r"missing joints \['j3'\]"):
        joint_state_arrays(joint_state(["j1", "j2"], [1.0, 2.0]), order)
    with pytest.raises(ValueError, match="duplicated joint names"):
        joint_state_arrays(joint_state(["j1", "j2", "j3", "j1"], [1.0, 2.0, 3.0, 4.0]), order)
    with pytest.raises(ValueError, match="missing joints"):
        effort_arrays(joint_state([], []), order)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("field", ["position", "velocity"])
def test_non_finite_states_rejected(bad, field):
    msg = joint_state(JOINTS, [1.0, 2.0, 3.0])
    values = list(getattr(msg, field))
    values[1] = bad
    setattr(msg, field, values)
    with pytest.raises(ValueError, match=f"non-finite {field}"):
        joint_state_arrays(msg, JointOrder(JOINTS))


def test_non_finite_effort_rejected():
    msg = joint_state(JOINTS, [1.0, 2.0, 3.0], effort=[1.0, math.nan, 3.0])
    with pytest.raises(ValueError, match="non-finite effort"):
        effort_arrays(msg, JointOrder(JOINTS))


@pytest.mark.parametrize("field", ["position", "velocity", "effort"])
def test_size_mismatch_rejected(field):
    msg = joint_state(JOINTS, [1.0, 2.0, 3.0])
    setattr(msg, field, [1.0, 2.0])
    order = JointOrder(JOINTS)
    with pytest.raises(ValueError, match=f"2 {field} values for 3 names"):
        if field == "effort":
            effort_arrays(msg, order)
        else:
            joint_state_arrays(msg, order)


def test_state_without_velocity_is_well_formed_but_a_partial_one_is_not():
    """An empty velocity array: a plant that does not measure velocity (q̇ empty); any
    other size than the names' is still rejected."""
    msg = joint_state(JOINTS, [1.0, 2.0, 3.0])
    msg.velocity = []
    q, dq = joint_state_arrays(msg, JointOrder(JOINTS))
    np.testing.assert_array_equal(q, [1.0, 2.0, 3.0])
    assert dq.shape == (0,)
    msg.velocity = [1.0]
    with pytest.raises(ValueError, match="1 velocity values for 3 names"):
        joint_state_arrays(msg, JointOrder(JOINTS))


def test_cached_names_still_reject_unknown_joints():
    order = JointOrder(JOINTS)
    names_ = ["j1", "j2", "j3", "finger"]
    joint_state_arrays(joint_state(names_, [1.0, 2.0, 3.0, 4.0]), order)
    with pytest.raises(ValueError, match="unknown joints"):
        effort_arrays(joint_state(names_, [1.0, 2.0, 3.0, 4.0]), order)


def test_cached_names_still_reject_unknown_joints_in_trajectories():
    order = JointOrder(JOINTS)
    names_ = ["j1", "j2", "j3", "finger"]
    joint_state_arrays(joint_state(names_, [1.0, 2.0, 3.0, 4.0]), order)
    msg = trajectory(names_, [point([1.0, 2.0, 3.0, 4.0], 1.0)])
    with pytest.raises(ValueError, match="unknown joints"):
        trajectory_from_msg(msg, order, now=0.0, origin_ns=0)


def test_float_array():
    msg = Float64MultiArray(data=[1.0, 2.0, 3.0])
    out = float_array(msg, 3)
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="2 command values for 3 names"):
        float_array(Float64MultiArray(data=[1.0, 2.0]), 3)
    with pytest.raises(ValueError, match="non-finite command"):
        float_array(Float64MultiArray(data=[1.0, math.inf, 3.0]), 3)


# -- trajectories --------------------------------------------------------------------------


def test_trajectory_reordered_with_zero_stamp_starting_now():
    msg = trajectory(
        ["j3", "j1", "j2"],
        [
            point([3.0, 1.0, 2.0], 0.5, velocities=[0.3, 0.1, 0.2]),
            point([30.0, 10.0, 20.0], 1.25, velocities=[0.0, 0.0, 0.0]),
        ],
    )
    tr = trajectory_from_msg(msg, JointOrder(JOINTS), now=12.5, origin_ns=0)
    assert tr.start == 12.5
    np.testing.assert_allclose(tr.times, [0.5, 1.25], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(tr.positions, [[1.0, 2.0, 3.0], [10.0, 20.0, 30.0]])
    np.testing.assert_array_equal(tr.velocities, [[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(tr.accelerations, np.zeros((2, 3)))


def test_trajectory_stamp_is_seconds_after_the_origin():
    origin_ns = 1_700_000_000_123_456_789
    stamp_ns = origin_ns + 3_250_000_000
    msg = trajectory(JOINTS, [point([1.0, 2.0, 3.0], 0.0)], stamp_ns=stamp_ns)
    tr = trajectory_from_msg(msg, JointOrder(JOINTS), now=3.0, origin_ns=origin_ns)
    assert tr.start == pytest.approx(3.25, abs=1e-9)
    tr = trajectory_from_msg(msg, JointOrder(JOINTS), now=99.0, origin_ns=0)
    assert tr.start == pytest.approx(stamp_ns * 1e-9, rel=1e-15)


@pytest.mark.parametrize(
    ("joint_names", "points", "match"),
    [
        (JOINTS, [], "no points"),
        (
            JOINTS,
            [point([1, 2, 3], 1.0, velocities=[0, 0, 0]), point([1, 2, 3], 2.0)],
            "velocities given on some points only",
        ),
        (
            JOINTS,
            [point([1, 2, 3], 1.0), point([1, 2, 3], 2.0, accelerations=[0, 0, 0])],
            "accelerations given on some points only",
        ),
        (["j1", "j2", "j3", "j4"], [point([1, 2, 3, 4], 1.0)], r"unknown joints \['j4'\]"),
        (["j1", "j2"], [point([1, 2], 1.0)], r"missing joints \['j3'\]"),
        (["j1", "j2", "j2"], [point([1, 2, 3], 1.0)], "duplicated"),
        (JOINTS, [point([1, 2], 1.0)], "2 point 0 position values for 3 names"),
        (JOINTS, [point([1, 2, 3], 1.0, velocities=[1, 2])], "point 0 velocity"),
        (JOINTS, [point([1, math.nan, 3], 1.0)], "non-finite point 0 position"),
        (JOINTS, [point([1, 2, 3], 2.0), point([1, 2, 3], 1.0)], "strictly increasing"),
    ],
)
def test_invalid_trajectories_rejected(joint_names, points, match):
    with pytest.raises(ValueError, match=match):
        trajectory_from_msg(trajectory(joint_names, points), JointOrder(JOINTS), 0.0, 0)


LIMITS = (np.array([-1.0, -2.0, -np.inf]), np.array([1.0, 2.0, np.inf]))


def test_set_points_outside_the_position_limits_are_rejected_not_clamped():
    order = JointOrder(JOINTS)
    inside = trajectory(JOINTS, [point([1.0, -2.0, 1e6], 0.5)])  # on the limits: accepted
    tr = trajectory_from_msg(inside, order, 0.0, 0, LIMITS)
    np.testing.assert_array_equal(tr.positions, [[1.0, -2.0, 1e6]])
    outside = trajectory(JOINTS, [point([0.0, 0.0, 0.0], 0.5), point([0.5, 2.01, 0.0], 1.0)])
    with pytest.raises(ValueError, match=r"point 1: j2 position 2.01 outside its limits"):
        trajectory_from_msg(outside, order, 0.0, 0, LIMITS)
    # in message order, not controlled-joint order
    swapped = trajectory(["j3", "j1", "j2"], [point([0.0, -1.5, 0.0], 0.5)])
    with pytest.raises(ValueError, match=r"point 0: j1 position -1.5"):
        trajectory_from_msg(swapped, order, 0.0, 0, LIMITS)


def test_a_trajectory_that_already_ended_is_rejected():
    order = JointOrder(JOINTS)
    msg = trajectory(JOINTS, [point([0, 0, 0], 0.0), point([1, 1, 1], 0.5)], stamp_ns=2 * 10**9)
    with pytest.raises(ValueError, match=r"ended at t=2.500 s, before now \(t=3.000 s\)"):
        trajectory_from_msg(msg, order, 3.0, 0)
    assert trajectory_from_msg(msg, order, 2.5, 0).end == 2.5  # its last point is now: fine
    # started in the past, ends in the future: accepted (it is joined where it is)
    assert trajectory_from_msg(msg, order, 2.2, 0).start == 2.0


# -- state message and stamps ----------------------------------------------------------------


def test_state_message_layout():
    msg = state_message(JOINTS)
    assert msg.layout.data_offset == 1
    rows, cols = msg.layout.dim
    assert rows.label.split(",") == list(STATE_FIELDS)
    assert rows.size == len(STATE_FIELDS) == 12
    assert rows.stride == 12 * 3
    assert cols.label.split(",") == list(JOINTS)
    assert (cols.size, cols.stride) == (3, 3)
    for field in ("q_d", "q", "error", "tau_unclamped", "tau"):
        assert field in STATE_FIELDS


@pytest.mark.parametrize(
    "ns",
    # up to the largest stamp builtin_interfaces/Time holds (int32 seconds)
    [
        0,
        1,
        999_999_999,
        1_000_000_000,
        1_700_000_000_123_456_789,
        (2**31 - 1) * 10**9 + 999_999_999,
    ],
)
def test_stamp_round_trip(ns):
    stamp = ns_to_stamp(ns)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert -(2**31) <= stamp.sec < 2**31
    assert stamp_to_ns(stamp) == ns


def test_stamp_to_ns_golden():
    assert stamp_to_ns(Time(sec=3, nanosec=250_000_000)) == 3_250_000_000
    stamp = ns_to_stamp(3_250_000_000)
    assert (stamp.sec, stamp.nanosec) == (3, 250_000_000)


# -- parameter helpers -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (3, [3.0]),
        (2.5, [2.5]),
        ([1, 2.5, 3], [1.0, 2.5, 3.0]),
        ((4.0,), [4.0]),
        (np.array([1.0, 2.0]), [1.0, 2.0]),
    ],
)
def test_numbers_accepts(value, expected):
    out = numbers({"kp": value}, "kp")
    assert out == expected
    assert all(type(v) is float for v in out)


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (True, "must be a number or a list of numbers"),
        ([1.0, False], "must be a number or a list of numbers"),
        ("100", "must be a number or a list of numbers"),
        (["1", "2"], "must be a number or a list of numbers"),
        (b"1", "must be a number or a list of numbers"),
        (None, "must be a number or a list of numbers"),
        ([], "'kp' is empty"),
    ],
)
def test_numbers_rejects(value, match):
    with pytest.raises(ValueError, match=match):
        numbers({"kp": value}, "kp")


def test_names():
    assert names({"joints": ["a", "b"]}, "joints") == ("a", "b")
    assert names({"joints": []}, "joints") == ()
    assert names({"joints": None}, "joints") == ()
    with pytest.raises(ValueError, match="must be a list of names"):
        names({"joints": ["a", 1]}, "joints")


def test_choice():
    assert MODE.check("full") == "full"
    with pytest.raises(ValueError, match="'mode' is 'half'; allowed: full, none, desired"):
        MODE.check("half")


@pytest.mark.parametrize("value", [1, 0.5, 1e9])
def test_positive_accepts(value):
    out = RATE.check(value)
    assert out == float(value) and type(out) is float


@pytest.mark.parametrize(
    ("value", "match"),
    [
        (0, "> 0"),
        (0.0, "> 0"),
        (-1.0, "> 0"),
        (math.nan, "> 0"),
        (math.inf, "finite"),
        (True, "> 0"),
        ("5", "> 0"),
        (None, "> 0"),
    ],
)
def test_positive_rejects(value, match):
    with pytest.raises(ValueError, match=match):
        RATE.check(value)


@pytest.mark.parametrize("value", [0, 0.0, 2, 3.5])
def test_nonnegative_number_accepts(value):
    assert F.check(value) == float(value)


@pytest.mark.parametrize(
    ("value", "match"),
    [(-0.1, ">= 0"), (math.nan, ">= 0"), (math.inf, "finite"), (False, ">= 0"), ("0", ">= 0")],
)
def test_nonnegative_number_rejects(value, match):
    with pytest.raises(ValueError, match=match):
        F.check(value)


def test_config_message_is_strict_json_of_parameter_values():
    import array
    import json

    from joint_space_control.ros.messages import config_message

    msg = config_message(
        {
            "kp": array.array("d", [1.0, 2.0]),  # what rclpy hands out for a double array
            "limits": np.array([2000.0, np.inf]),
            "bounds": [[-np.inf, 1.5]],
            "flag": True,
            "names": ("a", "b"),
            "count": np.int64(3),
            "nested": {"x": np.float64(0.5), "raw": b"\x01"},
        }
    )
    decoded = json.loads(msg.data)
    assert decoded == {
        "kp": [1.0, 2.0],
        "limits": [2000.0, None],
        "bounds": [[None, 1.5]],
        "flag": True,
        "names": ["a", "b"],
        "count": 3,
        "nested": {"x": 0.5, "raw": "b'\\x01'"},
    }
    assert "NaN" not in msg.data and "Infinity" not in msg.data


def test_rcl_init_errors_and_unknown_overrides_are_said_in_words():
    from joint_space_control.ros.node_main import init_error
    from joint_space_control.ros.parameters import ParamSpec, unknown_overrides

    err = RuntimeError(
        "failed to initialize rcl: Couldn't parse params file: '--params-file b.yaml'. "
        "Error: Error parsing a event near line 3, at /project/src/parse.c:782, at "
        "/project/src/rcl/arguments.c:415"
    )
    assert init_error(err) == (
        "Couldn't parse params file: '--params-file b.yaml'. Error: Error parsing a event near "
        "line 3"
    )
    specs = (ParamSpec("kp", 0.0, "gain"), ParamSpec("rate", 1.0, "rate"))
    given = ["rate", "kp_gain", "use_sim_time", "qos_overrides./clock.publisher.depth", "ki"]
    assert unknown_overrides(given, specs) == ["ki", "kp_gain"]


def test_references_beyond_the_documented_bounds_are_rejected_with_the_reason(monkeypatch):
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from joint_space_control.ros import messages

    def points(times):
        return [
            JointTrajectoryPoint(positions=[0.0], time_from_start=Duration(sec=s, nanosec=0))
            for s in times
        ]

    order = messages.JointOrder(["j"])
    monkeypatch.setattr(messages, "MAX_REFERENCE_POINTS", 3)
    ok = JointTrajectory(joint_names=["j"], points=points([1, 2, 3]))
    assert len(messages.trajectory_from_msg(ok, order, 0.0, 0).times) == 3
    many = JointTrajectory(joint_names=["j"], points=points([1, 2, 3, 4]))
    with pytest.raises(ValueError, match="has 4 points; at most 3"):
        messages.trajectory_from_msg(many, order, 0.0, 0)
    long = JointTrajectory(joint_names=["j"], points=points([1, 86_401]))
    with pytest.raises(ValueError, match="lasts 86401 s; at most 86400 s"):
        messages.trajectory_from_msg(long, order, 0.0, 0)
