"""Property-based tests (hypothesis) of the boundary checks, the fast readers and the laws.

Each property holds for *every* input its strategy draws, and each can fail: the inputs
cover what the code must accept (any permutation of the names, extra joints, any finite
value, subnormals and −0.0 included) and what it must reject (one defect at a time: a
non-finite value anywhere, a wrong size, an unknown, missing or duplicated name, a
non-increasing time, arbitrary bytes).

- messages.py (shared STYLE.md §3): valid messages come back in the controlled-joint order
  bit for bit; every defect raises ``ValueError`` naming it.
- wire.py: the in-place reader gives exactly what the validating conversion gives and
  rejects exactly what it rejects; no byte string makes it raise anything but ValueError.
- laws/ (shared THEORY.md §2, §3): on random states within the position limits every part of
  every torque split is finite and the total is the law's equation (inverse dynamics is
  Pinocchio's rnea(q, q̇, y)); PD + g at rest on the set-point is exactly ĝ; the command the
  controller's tick publishes never exceeds the effort limits.
"""

from __future__ import annotations

import functools
import math
import string
import types

import numpy as np
import pinocchio as pin
import pytest
from builtin_interfaces.msg import Duration
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.control.controller import Controller
from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.inverse_dynamics import (
    LAWS,
    ModelLaw,
    pd_acceleration,
)
from joint_space_control.laws.pd_gravity import (
    GravityCompensation,
    pid_torque_split,
)
from joint_space_control.laws.split import TorqueSplit
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.ros.messages import (
    STATE_FIELDS,
    JointOrder,
    effort_arrays,
    float_array,
    joint_state_arrays,
    ns_to_stamp,
    state_message,
    trajectory_from_msg,
)
from joint_space_control.ros.wire import (
    Float64ArrayImage,
    JointStateImage,
    JointStateReader,
    fill_images,
)
from joint_space_control.trajectories.reference import Sample

NAME = st.text(alphabet=string.ascii_letters + string.digits + "_", min_size=1, max_size=12)
#: Every finite float64: huge, tiny, subnormal, ±0.0.
FINITE = st.floats(allow_nan=False, allow_infinity=False)
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


def same_bits(a, b) -> bool:
    """Equal as float64 arrays bit for bit (−0.0 ≠ 0.0)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


@st.composite
def name_lists(draw, extra: bool, max_names: int = 8):
    """(controlled joints, the names of a message): the message names are a permutation of
    the joints, with extra (uncontrolled) names interleaved when ``extra``."""
    names = draw(st.lists(NAME, min_size=1, max_size=max_names, unique=True))
    count = draw(st.integers(1, len(names))) if extra else len(names)
    joints = tuple(names[:count])
    return joints, list(draw(st.permutations(names[: len(names) if extra else count])))


def in_joint_order(values, names, joints):
    return [values[names.index(j)] for j in joints]


# -- JointOrder --------------------------------------------------------------------------------


@settings(max_examples=100, deadline=None)
@given(allow_extra=st.booleans(), data=st.data())
def test_joint_order_maps_any_permutation_back(allow_extra, data):
    joints, names = data.draw(name_lists(extra=allow_extra))
    order = JointOrder(joints)
    for _ in range(2):  # computed, then from the cache
        assert [names[i] for i in order.index(names, allow_extra)] == list(joints)
    other = data.draw(st.permutations(names))  # the cache follows a changing name list
    assert [other[i] for i in order.index(other, allow_extra)] == list(joints)
    assert [names[i] for i in order.index(names, allow_extra)] == list(joints)
    fresh = JointOrder(joints).index(names, allow_extra)
    assert np.array_equal(fresh, order.index(names, allow_extra))


@settings(max_examples=100, deadline=None)
@given(
    problem=st.sampled_from(["unknown", "missing", "duplicated"]),
    allow_extra=st.booleans(),
    data=st.data(),
)
def test_joint_order_rejects_unknown_missing_and_duplicated_names(problem, allow_extra, data):
    if problem == "unknown":
        allow_extra = False  # an extra name is fine otherwise (property above)
    joints, names = data.draw(name_lists(extra=allow_extra))
    order = JointOrder(joints)
    order.index(names, allow_extra)  # valid and cached: the cache must not hide a defect
    bad = list(names)
    if problem == "missing":
        gone = data.draw(st.sampled_from(joints))
        bad.remove(gone)
        reason = f"missing joints {[gone]}"
    elif problem == "unknown":
        stranger = data.draw(NAME.filter(lambda s: s not in names))
        bad.insert(data.draw(st.integers(0, len(bad))), stranger)
        reason = f"unknown joints {[stranger]}"
        # the same list is fine where extra names are allowed
        assert [bad[i] for i in order.index(bad, True)] == list(joints)
    else:
        twice = data.draw(st.sampled_from(names))
        bad.insert(data.draw(st.integers(0, len(bad))), twice)
        reason = f"duplicated joint names {bad}"
    for o in (order, JointOrder(joints)):  # with and without a cached permutation
        with pytest.raises(ValueError) as err:
            o.index(bad, allow_extra)
        assert str(err.value) == reason


# -- JointState and command arrays -------------------------------------------------------------

FIELDS = ("position", "velocity", "effort")
#: what each conversion reads: (allow extra names, fields checked, conversion)
CONVERSIONS = {
    "state": (True, ("position", "velocity"), lambda m, o: joint_state_arrays(m, o)),
    "effort": (False, ("effort",), lambda m, o: (effort_arrays(m, o),)),
}
#: fields a conversion accepts empty (a state without measured velocity)
OPTIONAL = {"state": ("velocity",), "effort": ()}


@st.composite
def joint_states(draw, kind: str):
    """(joints, a valid JointState for the ``kind`` conversion). Fields the conversion does
    not read are empty or complete."""
    allow_extra, fields, _ = CONVERSIONS[kind]
    joints, names = draw(name_lists(extra=allow_extra))
    m = len(names)
    msg = JointState(name=names)
    for field in ("position", "velocity", "effort"):
        size = m if field in fields else draw(st.sampled_from([0, m]))
        setattr(msg, field, draw(st.lists(FINITE, min_size=size, max_size=size)))
    return joints, msg


@settings(max_examples=80, deadline=None)
@given(kind=st.sampled_from(list(CONVERSIONS)), data=st.data())
def test_valid_joint_states_come_back_in_joint_order_bit_exact(kind, data):
    joints, msg = data.draw(joint_states(kind))
    _, fields, convert = CONVERSIONS[kind]
    arrays = convert(msg, JointOrder(joints))
    assert len(arrays) == len(fields)
    for field, arr in zip(fields, arrays, strict=True):
        assert same_bits(arr, in_joint_order(list(getattr(msg, field)), msg.name, joints))


@settings(max_examples=80, deadline=None)
@given(kind=st.sampled_from(list(CONVERSIONS)), data=st.data())
def test_non_finite_values_and_wrong_sizes_are_rejected(kind, data):
    joints, msg = data.draw(joint_states(kind))
    _, fields, convert = CONVERSIONS[kind]
    field = data.draw(st.sampled_from(fields))
    values = list(getattr(msg, field))
    m = len(msg.name)
    if data.draw(st.booleans()):  # anywhere: a controlled joint or an extra one
        values[data.draw(st.integers(0, m - 1))] = data.draw(NON_FINITE)
        reason = f"non-finite {field}"
    else:
        empty_ok = field in OPTIONAL[kind]  # an empty optional array is well formed
        size = data.draw(
            st.integers(0, m + 3).filter(lambda s: s != m and (s > 0 or not empty_ok))
        )
        values = (values + data.draw(st.lists(FINITE, min_size=3, max_size=3)))[:size]
        reason = f"{size} {field} values for {m} names"
    setattr(msg, field, values)
    with pytest.raises(ValueError) as err:
        convert(msg, JointOrder(joints))
    assert str(err.value) == reason


@settings(max_examples=100, deadline=None)
@given(values=st.lists(FINITE, max_size=16))
def test_float_array_returns_finite_values_bit_exact(values):
    assert same_bits(float_array(Float64MultiArray(data=values), len(values)), values)


@settings(max_examples=100, deadline=None)
@given(values=st.lists(FINITE, min_size=1, max_size=16), data=st.data())
def test_float_array_rejects_non_finite_values_and_wrong_sizes(values, data):
    size = len(values)
    if data.draw(st.booleans()):
        values[data.draw(st.integers(0, size - 1))] = data.draw(NON_FINITE)
        reason = "non-finite command"
    else:
        size = data.draw(st.integers(0, 20).filter(lambda s: s != len(values)))
        reason = f"{len(values)} command values for {size} names"
    with pytest.raises(ValueError) as err:
        float_array(Float64MultiArray(data=values), size)
    assert str(err.value) == reason


# -- trajectories ------------------------------------------------------------------------------


def duration(ns: int) -> Duration:
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


@st.composite
def trajectories(draw):
    """(joints, message, times [ns], positions, velocities or None, accelerations or None),
    the arrays in message order. Times are strictly increasing, within 60 s."""
    joints, names = draw(name_lists(extra=False, max_names=5))
    n = len(names)
    m = draw(st.integers(1, 4))
    first = draw(st.integers(0, 10**10))
    steps = draw(st.lists(st.integers(1, 10**10), min_size=m - 1, max_size=m - 1))
    times = list(np.cumsum([first, *steps]))

    def table():
        return draw(st.lists(st.lists(FINITE, min_size=n, max_size=n), min_size=m, max_size=m))

    positions = table()
    velocities = table() if draw(st.booleans()) else None
    accelerations = table() if draw(st.booleans()) else None
    msg = JointTrajectory(joint_names=names)
    msg.points = [
        JointTrajectoryPoint(
            positions=positions[k],
            velocities=velocities[k] if velocities else [],
            accelerations=accelerations[k] if accelerations else [],
            time_from_start=duration(int(times[k])),
        )
        for k in range(m)
    ]
    return joints, msg, times, positions, velocities, accelerations


@settings(max_examples=80, deadline=None)
@given(
    case=trajectories(),
    stamp_ns=st.one_of(st.just(0), st.integers(1, 2**62)),
    origin_ns=st.integers(0, 2**62),
    now=st.floats(-1e9, 1e9),
)
def test_valid_trajectories_round_trip(case, stamp_ns, origin_ns, now):
    joints, msg, times, positions, velocities, accelerations = case
    msg.header.stamp = ns_to_stamp(stamp_ns)
    start = now if stamp_ns == 0 else (stamp_ns - origin_ns) * 1e-9
    now = min(now, start)  # not over yet
    traj = trajectory_from_msg(msg, JointOrder(joints), now, origin_ns)
    assert traj.start == start
    np.testing.assert_allclose(traj.times, np.array(times) * 1e-9, rtol=1e-15, atol=0)
    names = list(msg.joint_names)

    def reorder(table):
        return [in_joint_order(row, names, joints) for row in table]

    assert same_bits(traj.positions, reorder(positions))
    for given_, got, flag in (
        (velocities, traj.velocities, traj.velocities_given),
        (accelerations, traj.accelerations, traj.accelerations_given),
    ):
        assert flag == (given_ is not None)
        assert same_bits(got, reorder(given_) if given_ else np.zeros_like(traj.positions))


SINGULAR = {"positions": "position", "velocities": "velocity", "accelerations": "acceleration"}
DEFECTS = [
    "no points",
    "times",
    "negative time",
    "non-finite",
    "partial",
    "size",
    "unknown",
    "missing",
    "duplicated",
]


@settings(max_examples=100, deadline=None)
@given(case=trajectories(), defect=st.sampled_from(DEFECTS), data=st.data())
def test_invalid_trajectories_are_rejected_with_the_reason(case, defect, data):
    joints, msg, times, positions, velocities, accelerations = case
    points, n, m = msg.points, len(joints), len(msg.points)
    k = data.draw(st.integers(0, m - 1))
    given_ = [f for f, t in (("velocities", velocities), ("accelerations", accelerations)) if t]
    if defect == "no points":
        msg.points = []
        reason = "trajectory has no points"
    elif defect == "times":  # a point at or before the one before it
        assume(m > 1)
        k = data.draw(st.integers(1, m - 1))
        points[k].time_from_start = duration(int(times[k - 1]) - data.draw(st.integers(0, 10**9)))
        reason = "strictly increasing"
    elif defect == "negative time":
        points[0].time_from_start = Duration(sec=data.draw(st.integers(-(2**31), -1)), nanosec=0)
        reason = "strictly increasing"
    elif defect == "non-finite":
        field = data.draw(st.sampled_from(["positions", *given_]))
        values = list(getattr(points[k], field))
        values[data.draw(st.integers(0, n - 1))] = data.draw(NON_FINITE)
        setattr(points[k], field, values)
        reason = f"non-finite point {k} {SINGULAR[field]}"
    elif defect == "partial":  # velocities or accelerations on some points only
        assume(m > 1)
        field = data.draw(st.sampled_from(["velocities", "accelerations"]))
        some = data.draw(st.sets(st.integers(0, m - 1), min_size=1, max_size=m - 1))
        for j in range(m):
            complete = field in given_
            if (j in some) == complete:
                setattr(points[j], field, [] if complete else [0.0] * n)
        reason = f"{field} given on some points only"
    elif defect == "size":
        field = data.draw(st.sampled_from(["positions", *given_]))
        size = data.draw(st.integers(1, n + 2).filter(lambda s: s != n))
        setattr(points[k], field, ([0.5] * (n + 2))[:size])
        reason = f"{size} point {k} {SINGULAR[field]} values for {n} names"
    else:
        names = list(msg.joint_names)
        if defect == "unknown":
            stranger = data.draw(NAME.filter(lambda s: s not in names))
            names.insert(data.draw(st.integers(0, n)), stranger)
            reason = f"unknown joints {[stranger]}"
        elif defect == "missing":
            gone = data.draw(st.sampled_from(names))
            names.remove(gone)
            reason = f"missing joints {[gone]}"
        else:
            names.insert(data.draw(st.integers(0, n)), data.draw(st.sampled_from(names)))
            reason = f"duplicated joint names {names}"
        msg.joint_names = names
    with pytest.raises(ValueError) as err:
        trajectory_from_msg(msg, JointOrder(joints), 0.0, 0)
    assert reason in str(err.value)


@settings(max_examples=20, deadline=None)
@given(sec=st.integers(0, 86_399), nanosec=st.integers(0, 999_999_997))
def test_times_one_nanosecond_apart_stay_apart_within_the_duration_bound(sec, nanosec):
    """Three points 1 ns apart anywhere within MAX_REFERENCE_DURATION: accepted, their
    seconds (float64) strictly increasing; beyond the bound (2^24 s, where float seconds
    could no longer tell 1 ns apart) the trajectory is rejected for its duration."""
    points = [
        JointTrajectoryPoint(positions=[0.0], time_from_start=Duration(sec=sec, nanosec=ns))
        for ns in (nanosec, nanosec + 1, nanosec + 2)
    ]
    msg = JointTrajectory(joint_names=["j"], points=points)
    traj = trajectory_from_msg(msg, JointOrder(["j"]), 0.0, 0)
    assert np.all(np.diff(traj.times) > 0)
    late = [
        JointTrajectoryPoint(positions=[0.0], time_from_start=Duration(sec=2**24, nanosec=ns))
        for ns in (0, 1)
    ]
    with pytest.raises(ValueError, match="at most 86400 s"):
        trajectory_from_msg(
            JointTrajectory(joint_names=["j"], points=late), JointOrder(["j"]), 0.0, 0
        )


# -- the fast JointState reader ----------------------------------------------------------------


def reader_for(kind: str, joints) -> JointStateReader:
    allow_extra, fields, convert = CONVERSIONS[kind]
    order = JointOrder(joints)
    field_ids = tuple(FIELDS.index(f) for f in fields)
    optional = tuple(FIELDS.index(f) for f in OPTIONAL[kind])
    return JointStateReader(order, field_ids, lambda m: convert(m, order), allow_extra, optional)


def validating(kind: str, joints, raw: bytes):
    """What the ordinary path makes of ``raw``: (stamp, arrays) or the ValueError."""
    _, _, convert = CONVERSIONS[kind]
    try:
        msg = deserialize_message(raw, JointState)
    except (RuntimeError, ValueError) as err:  # rmw's error, bad UTF-8: no JointState
        return ("not a JointState", type(err))
    try:
        arrays = convert(msg, JointOrder(joints))  # its own order: no shared cache
    except ValueError as err:
        return ("rejected", str(err))
    return (msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, arrays)


def read(reader: JointStateReader, raw: bytes):
    try:
        stamp, arrays = reader.read(raw)
    except ValueError as err:
        return ("rejected", str(err))
    assert all(a.flags.writeable for a in arrays)  # copies, not views into the message
    return (stamp, arrays)


def same_outcome(got, expected) -> bool:
    if isinstance(got[0], str) or isinstance(expected[0], str):
        return got == expected
    return got[0] == expected[0] and all(
        same_bits(a, b) for a, b in zip(got[1], expected[1], strict=True)
    )


@st.composite
def joint_state_streams(draw, kind: str):
    """(joints, messages): a stream that starts in a valid layout (names, frame, array
    sizes) and mostly stays in it (what the fast path reads), sometimes moving to other
    layouts, valid or not; each message after the first has finite values or, one time in
    two, one non-finite value anywhere (often in the slot of a name that is not controlled).
    """
    allow_extra, fields, _ = CONVERSIONS[kind]
    joints, names = draw(name_lists(extra=True, max_names=6))
    pool = list(names) if allow_extra else [*joints, *[n for n in names if n not in joints]]
    extra = [n for n in pool if n not in joints] if allow_extra else []

    def sizes_for(m: int, valid: bool) -> list[int]:
        return [
            (
                draw(st.sampled_from([m, 0]))
                if valid and f in OPTIONAL[kind]
                else m
                if valid
                else draw(st.sampled_from([m, m, m - 1, m + 1, 0]))
            )
            if f in fields
            else draw(st.integers(0, m + 1))
            for f in FIELDS
        ]

    def layout(valid: bool):
        if valid or draw(st.booleans()):  # a permutation of the names
            ns = list(draw(st.permutations([*joints, *extra])))
        else:  # anything: missing, duplicated, unknown names
            ns = draw(st.lists(st.sampled_from(pool), min_size=1, max_size=len(pool) + 1))
        frame = draw(st.sampled_from(["", "base_link", "wörld"]))
        return ns, frame, sizes_for(len(ns), valid)

    shapes = [layout(True)] + [layout(False) for _ in range(draw(st.integers(0, 2)))]
    stream, shape = [], shapes[0]
    for k in range(draw(st.integers(2, 6))):
        if k and draw(st.integers(0, 3)) == 0:  # mostly the layout of the message before
            shape = draw(st.sampled_from(shapes))
        ns, frame, sizes = shape
        msg = JointState(name=ns)
        msg.header.frame_id = frame
        msg.header.stamp.sec = draw(st.integers(-(2**31), 2**31 - 1))
        msg.header.stamp.nanosec = draw(st.integers(0, 2**32 - 1))
        values = [draw(st.lists(FINITE, min_size=s, max_size=s)) for s in sizes]
        if k and sum(sizes) and draw(st.booleans()):
            read = [i for i, s in enumerate(sizes) if s and FIELDS[i] in fields]
            nonempty = [i for i, s in enumerate(sizes) if s]
            f = draw(st.sampled_from(read if read and draw(st.integers(0, 2)) else nonempty))
            others = [i for i, name in enumerate(ns[: sizes[f]]) if name not in joints]
            slots = others if others and draw(st.booleans()) else range(sizes[f])
            values[f][draw(st.sampled_from(slots))] = draw(NON_FINITE)
        msg.position, msg.velocity, msg.effort = values
        stream.append(msg)
    return joints, stream


@settings(max_examples=80, deadline=None)
@given(kind=st.sampled_from(list(CONVERSIONS)), data=st.data())
def test_fast_reader_gives_and_rejects_exactly_what_the_validating_path_does(kind, data):
    joints, stream = data.draw(joint_state_streams(kind))
    reader = reader_for(kind, joints)
    for msg in stream:
        raw = serialize_message(msg)
        assert same_outcome(read(reader, raw), validating(kind, joints, raw))


@st.composite
def byte_strings(draw, kind: str):
    """(joints, a valid message the reader learns first, bytes): arbitrary bytes, or the
    valid message's bytes truncated, extended or with some bytes overwritten."""
    joints, msg = draw(joint_states(kind))
    raw = bytearray(serialize_message(msg))
    how = draw(st.sampled_from(["random", "truncated", "extended", "overwritten"]))
    if how == "random":
        raw = bytearray(draw(st.binary(max_size=400)))
    elif how == "truncated":
        raw = raw[: draw(st.integers(0, len(raw) - 1))]
    elif how == "extended":
        raw += draw(st.binary(min_size=1, max_size=16))
    else:
        for _ in range(draw(st.integers(1, 4))):
            raw[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 255))
    return joints, msg, bytes(raw)


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(list(CONVERSIONS)), data=st.data())
def test_any_bytes_give_the_validated_arrays_or_a_value_error(kind, data):
    joints, valid, raw = data.draw(byte_strings(kind))
    reader = reader_for(kind, joints)
    reader.read(serialize_message(valid))  # the layout the fast path knows
    got = read(reader, raw)  # anything but ValueError propagates and fails the test
    expected = validating(kind, joints, raw)
    if expected[0] == "not a JointState":
        assert got[0] == "rejected"
    else:
        assert same_outcome(got, expected)


# -- the laws ----------------------------------------------------------------------------------

ROBOTS = ("planar_2dof", "iiwa")


@functools.cache
def robot_model(name: str) -> RobotModel:
    # iiwa with friction and a payload, so that every term of n̂ is exercised
    perturbation = ModelPerturbation(friction=0.5, payload_mass=1.5) if name == "iiwa" else None
    return RobotModel(resolve_robot(name), perturbation=perturbation)


@functools.cache
def pinocchio_data(name: str) -> pin.Data:
    return robot_model(name).model.createData()


def pinocchio_rnea(name: str, q, dq, ddq) -> np.ndarray:
    """τ = rnea(q, q̇, q̈) + F̂q̇ straight from Pinocchio, in the controlled-joint order."""
    model = robot_model(name)
    pm = model.model
    iv = [pm.joints[pm.getJointId(j)].idx_v for j in model.joint_names]
    v, a = np.zeros(pm.nv), np.zeros(pm.nv)
    v[iv], a[iv] = dq, ddq
    tau = pin.rnea(pm, pinocchio_data(name), model.configuration(q), v, a)
    return tau[iv] + model.friction * dq


def bounded(draw, lo, hi) -> np.ndarray:
    return np.array([draw(st.floats(a, b)) for a, b in zip(lo, hi, strict=True)])


@st.composite
def law_states(draw, kp_max: float = 1e4):
    """(robot, q, q̇, reference, gains, ξ): q and q_d within the position limits, |q̇|,
    |q̇_d| ≤ 10 rad/s, |q̈_d| ≤ 100 rad/s², K_P ≤ kp_max, K_D ≤ 500, K_I ≤ 1000, |ξ| ≤ 1."""
    name = draw(st.sampled_from(ROBOTS))
    n = robot_model(name).n
    lo, hi = robot_model(name).position_limits
    q, q_d = bounded(draw, lo, hi), bounded(draw, lo, hi)
    dq, dq_d = (bounded(draw, [-10.0] * n, [10.0] * n) for _ in range(2))
    ddq_d = bounded(draw, [-100.0] * n, [100.0] * n)
    gains = PDGains.build(
        n,
        bounded(draw, [1.0] * n, [kp_max] * n),
        bounded(draw, [0.0] * n, [500.0] * n),
        bounded(draw, [0.0] * n, [1000.0] * n),
    )
    integral = bounded(draw, [-1.0] * n, [1.0] * n)
    return name, q, dq, Sample(q_d, dq_d, ddq_d), gains, integral


def close(a, b, *terms) -> bool:
    """Equal up to rounding: 1e-9 relative to the largest term that was summed."""
    scale = 1.0 + max(float(np.max(np.abs(t))) for t in (a, b, *terms))
    return bool(np.all(np.abs(np.asarray(a) - np.asarray(b)) <= 1e-9 * scale))


def assert_finite_split(split: TorqueSplit, n: int) -> None:
    for part in (split.feedback, split.model, split.gravity, split.total):
        assert part.shape == (n,) and np.all(np.isfinite(part))
    assert same_bits(split.total, split.feedback + split.model + split.gravity)


@settings(max_examples=60, deadline=None)
@given(
    state=law_states(),
    mode=st.sampled_from(list(GravityCompensation)),
    estimate=st.floats(-100.0, 100.0),
)
def test_pd_gravity_family_split_is_finite_and_the_law(state, mode, estimate):
    """τ = ĝ + u + K_P (q_d − q) − K_D q̇ + K_I ξ with ĝ = g(q), 0 or g(q_d)."""
    name, q, dq, ref, gains, integral = state
    model = robot_model(name)
    g_hat = {
        GravityCompensation.FULL: lambda: model.gravity(q),
        GravityCompensation.NONE: lambda: np.zeros(model.n),
        GravityCompensation.DESIRED: lambda: model.gravity(ref.q),
    }[mode]() + estimate
    split = pid_torque_split(q, dq, ref.q, integral, gains, g_hat)
    assert_finite_split(split, model.n)
    assert same_bits(split.gravity, g_hat) and not np.any(split.model)
    pd = gains.kp * (ref.q - q) - gains.kd * dq
    assert close(split.total, g_hat + pd + gains.ki * integral, g_hat, pd, gains.ki * integral)
    without = pid_torque_split(q, dq, ref.q, np.zeros(model.n), gains, g_hat).total
    assert close(without, g_hat + pd, g_hat, pd)


@settings(max_examples=60, deadline=None)
@given(state=law_states())
def test_at_rest_on_the_set_point_pd_gravity_is_exactly_the_model_gravity(state):
    name, q, _, _, gains, _ = state
    model = robot_model(name)
    g, zero = model.gravity(q), np.zeros(model.n)
    split = pid_torque_split(q, zero, q.copy(), zero, gains, g)
    assert np.array_equal(split.total, g) and not np.any(split.feedback)
    # eq. 17 reduces to PD + g(q) as well, exactly; eq. 15 up to Pinocchio's rounding
    rest = Sample(q.copy(), zero, zero)
    assert np.array_equal(LAWS[ModelLaw.FEEDFORWARD_PD](model, q, zero, rest, gains).total, g)
    for law in (ModelLaw.INVERSE_DYNAMICS, ModelLaw.PRECOMPUTED_FEEDFORWARD):
        assert close(LAWS[law](model, q, zero, rest, gains).total, g)


@settings(max_examples=60, deadline=None)
@given(state=law_states(), law=st.sampled_from(list(ModelLaw)))
def test_model_law_split_is_finite_and_the_law(state, law):
    """Eq. 15, eq. 17 and the precomputed feedforward against Pinocchio's own terms."""
    name, q, dq, ref, gains, _ = state
    model = robot_model(name)
    split = LAWS[law](model, q, dq, ref, gains)
    assert_finite_split(split, model.n)
    assert np.array_equal(split.gravity, model.gravity(q))
    pd = gains.kd * (ref.dq - dq) + gains.kp * (ref.q - q)
    if law is ModelLaw.INVERSE_DYNAMICS:
        B = model.inertia(q)
        assert close(split.feedback, B @ pd, B @ pd)
        expected = pinocchio_rnea(name, q, dq, ref.ddq + pd)
    else:
        assert np.array_equal(split.feedback, pd_acceleration(q, dq, ref, gains))
        if law is ModelLaw.FEEDFORWARD_PD:
            ff = (
                model.inertia(q) @ ref.ddq
                + model.coriolis(q, dq) @ ref.dq
                + model.friction * ref.dq
            )
        else:  # on the reference
            ff = pinocchio_rnea(name, ref.q, ref.dq, ref.ddq) - model.gravity(ref.q)
        expected = ff + model.gravity(q) + pd
    assert close(split.total, expected, split.feedback, split.model, split.gravity)


@settings(max_examples=60, deadline=None)
@given(state=law_states())
def test_inverse_dynamics_is_pinocchio_rnea_of_the_commanded_acceleration(state):
    """Eq. 15: τ = B̂(q) y + n̂(q, q̇) = rnea(q, q̇, y), y = q̈_d + K_D ė + K_P e."""
    name, q, dq, ref, gains, _ = state
    y = ref.ddq + gains.kd * (ref.dq - dq) + gains.kp * (ref.q - q)
    split = LAWS[ModelLaw.INVERSE_DYNAMICS](robot_model(name), q, dq, ref, gains)
    expected = pinocchio_rnea(name, q, dq, y)
    assert close(split.total, expected, split.feedback, split.model, split.gravity)


class _Fixed(Controller):
    """The controller core with a given reference sample and torque split (no ROS graph):
    what is checked is the step's gate and clamp, then the node's message images."""

    def __init__(self, limits, ref: Sample, split: TorqueSplit) -> None:
        super().__init__(types.SimpleNamespace(gains="given"), limits)
        self._ref, self._split = ref, split

    def sample(self, t: float, q) -> Sample:
        return self._ref

    def compute(self, q, dq, ref, dt) -> TorqueSplit:
        return self._split


def published(joints, limits, q, dq, ref: Sample, split: TorqueSplit):
    """The command and ``~/state`` bytes a node sends for one step (None: nothing sent)."""
    n = len(joints)
    step = _Fixed(limits, ref, split).step(1.5, q, dq)
    if step.tau is None:
        return None
    command = JointStateImage(joints, (0, 0, n))
    state = Float64ArrayImage(state_message(joints), 1 + len(STATE_FIELDS) * n)
    fill_images(command, state, 1_500_000_000, step)
    return command.to_bytes(), state.to_bytes()


@settings(max_examples=60, deadline=None)
@given(
    state=law_states(kp_max=1e6),  # stiff gains: saturation is common
    law=st.sampled_from(["pd_gravity", *ModelLaw]),
    scale=st.sampled_from([1.0, 1e3, 1e9]),
    data=st.data(),
)
def test_published_command_never_exceeds_the_effort_limits(state, law, scale, data):
    name, q, dq, ref, gains, integral = state
    model = robot_model(name)
    if law == "pd_gravity":
        split = pid_torque_split(q, dq, ref.q, integral, gains, model.gravity(q))
    else:
        split = LAWS[law](model, q, dq, ref, gains)
    split = TorqueSplit(scale * split.feedback, split.model, split.gravity)
    limits = model.effort_limits
    if data.draw(st.booleans()):  # any positive limits, absent ones (inf) included
        limits = np.array(
            [data.draw(st.one_of(st.floats(1e-3, 1e4), st.just(math.inf))) for _ in limits]
        )
    raw, state_raw = published(model.joint_names, limits, q, dq, ref, split)
    tau = np.array(deserialize_message(raw, JointState).effort)
    unclamped = split.total
    assert np.all(np.abs(tau) <= limits)
    within = np.abs(unclamped) <= limits
    assert np.array_equal(tau[within], unclamped[within])  # untouched where allowed
    assert np.array_equal(tau[~within], np.copysign(limits, unclamped)[~within])
    rows = np.array(deserialize_message(state_raw, Float64MultiArray).data[1:]).reshape(
        len(STATE_FIELDS), -1
    )
    assert same_bits(rows[STATE_FIELDS.index("tau")], tau)
    assert same_bits(rows[STATE_FIELDS.index("tau_unclamped")], unclamped)


@settings(max_examples=40, deadline=None)
@given(
    state=law_states(),
    part=st.sampled_from(["feedback", "model", "gravity"]),
    bad=NON_FINITE,
    data=st.data(),
)
def test_a_non_finite_torque_is_never_published(state, part, bad, data):
    """NaN passes through np.clip: the tick must drop such a command, whatever the part and
    the joint it comes from."""
    name, q, dq, ref, gains, integral = state
    model = robot_model(name)
    split = pid_torque_split(q, dq, ref.q, integral, gains, model.gravity(q))
    values = getattr(split, part).copy()
    values[data.draw(st.integers(0, model.n - 1))] = bad
    split = TorqueSplit(**{**vars(split), part: values})
    core = _Fixed(model.effort_limits, ref, split)
    step = core.step(1.5, q, dq)
    assert step.tau is None  # nothing to publish
    assert published(model.joint_names, model.effort_limits, q, dq, ref, split) is None
    assert core._t_last is None  # nothing integrated across the gap
