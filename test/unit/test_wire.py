"""Serialized message images against the rosidl serializer (no ROS graph)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from joint_space_control.ros.messages import (
    JointOrder,
    effort_arrays,
    joint_state_arrays,
    paused_message,
    paused_stamp,
    state_message,
)
from joint_space_control.ros.wire import (
    Float64ArrayImage,
    JointStateImage,
    JointStateReader,
    clock_bytes,
)

NAME_SETS = [
    ["j"],
    ["joint1", "joint2"],
    [f"lbr_iiwa_joint_{i}" for i in range(1, 8)],
    ["a", "bb", "ccc", "dddd", "eeeee"],  # every padding length
]


def message(names, sizes, frame="", stamp=(12, 345), seed=0):
    rng = np.random.default_rng(seed)
    msg = JointState(name=list(names))
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    msg.position, msg.velocity, msg.effort = (rng.normal(size=s).tolist() for s in sizes)
    return msg


LAYOUTS = {"state": (1, 1, 1), "command": (0, 0, 1), "no_effort": (1, 1, 0)}


@pytest.mark.parametrize(
    ("names", "layout", "frame"), list(itertools.product(NAME_SETS, LAYOUTS, ["", "base_link"]))
)
def test_image_deserializes_to_the_message_it_stands_for(names, layout, frame):
    sizes = tuple(len(names) * k for k in LAYOUTS[layout])
    expected = message(names, sizes, frame, stamp=(1_700_000_000, 999_999_999))
    image = JointStateImage(names, sizes, frame)
    image.set_stamp(1_700_000_000 * 1_000_000_000 + 999_999_999)
    image.position[:], image.velocity[:], image.effort[:] = (
        expected.position,
        expected.velocity,
        expected.effort,
    )
    got = deserialize_message(image.to_bytes(), JointState)
    assert got == expected
    # the rosidl serializer writes the same layout: the image recognises its bytes
    raw = serialize_message(expected)
    assert image.matches(raw)
    assert JointStateImage.stamp(raw) == 1_700_000_000 * 1_000_000_000 + 999_999_999
    for k, field in enumerate(("position", "velocity", "effort")):
        np.testing.assert_array_equal(image.read(raw, k), getattr(expected, field))


def test_other_layouts_do_not_match():
    names = ["joint1", "joint2"]
    image = JointStateImage(names)
    assert image.matches(serialize_message(message(names, (2, 2, 2))))
    others = [
        message(["joint1", "joint3"], (2, 2, 2)),  # same lengths, other name
        message(["joint2", "joint1"], (2, 2, 2)),  # other order
        message(names, (2, 2, 0)),
        message(names, (2, 2, 2), frame="x"),
        message(["joint1", "joint2", "joint3"], (3, 3, 3)),
    ]
    for msg in others:
        assert not image.matches(serialize_message(msg)), msg
    assert not image.matches(image.to_bytes()[:-1])


def test_image_views_write_the_bytes_published():
    image = JointStateImage(["a", "b", "c"], (0, 0, 3))
    image.effort[:] = [1.0, -2.0, 3.5]
    image.set_stamp(5_000_000_001)
    msg = deserialize_message(image.to_bytes(), JointState)
    assert list(msg.effort) == [1.0, -2.0, 3.5] and len(msg.position) == 0
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (5, 1)


@pytest.mark.parametrize("joints", [("j1",), ("joint1", "joint2"), tuple(NAME_SETS[2])])
def test_state_image_is_the_state_message(joints):
    template = state_message(joints)
    size = 1 + 12 * len(joints)
    image = Float64ArrayImage(template, size)
    values = np.linspace(-1.0, 1.0, size)
    image.data[:] = values
    got = deserialize_message(image.to_bytes(), Float64MultiArray)
    assert got.layout == template.layout
    np.testing.assert_array_equal(got.data, values)


class TestReader:
    JOINTS = ("j1", "j2", "j3")

    def reader(self):
        order = JointOrder(self.JOINTS)
        return JointStateReader(
            order, (0, 1), lambda m: joint_state_arrays(m, order), allow_extra=True, optional=(1,)
        )

    def test_states_without_velocity_are_read_on_either_path(self):
        """An empty velocity array (velocity not measured) gives an empty q̇ on the ordinary
        and the in-place path; a wrong size is still rejected; layouts alternate freely."""
        reader = self.reader()
        names = ["j3", "finger", "j1", "j2"]
        for k in range(3):
            msg = message(names, (4, 0, 4), stamp=(k, 1), seed=k)
            stamp, (q, dq) = reader.read(serialize_message(msg))
            np.testing.assert_array_equal(q, np.array(msg.position)[[2, 3, 0]])
            assert dq.shape == (0,) and stamp == k * 1_000_000_000 + 1
        with pytest.raises(ValueError, match="2 velocity values for 4 names"):
            reader.read(serialize_message(message(names, (4, 2, 4))))
        full = message(names, (4, 4, 4), seed=5)
        _, (q, dq) = reader.read(serialize_message(full))
        np.testing.assert_array_equal(dq, np.array(full.velocity)[[2, 3, 0]])
        _, (q, dq) = reader.read(serialize_message(message(names, (4, 0, 0))))
        assert dq.shape == (0,)

    def test_fast_and_ordinary_paths_agree_with_extra_and_permuted_names(self):
        names = ["j3", "finger", "j1", "j2"]
        reader = self.reader()
        order = JointOrder(self.JOINTS)
        for k in range(3):  # first ordinary, then in place
            msg = message(names, (4, 4, 4), stamp=(k, 7), seed=k)
            stamp, (q, dq) = reader.read(serialize_message(msg))
            q_ref, dq_ref = joint_state_arrays(msg, order)
            assert stamp == k * 1_000_000_000 + 7
            np.testing.assert_array_equal(q, q_ref)
            np.testing.assert_array_equal(dq, dq_ref)
            assert q.flags.writeable  # a copy, not a view into the message

    def test_invalid_messages_raise_with_the_reason_on_either_path(self):
        reader = self.reader()
        good = message(self.JOINTS, (3, 3, 3))
        reader.read(serialize_message(good))
        bad = message(self.JOINTS, (3, 3, 3))
        bad.position = [0.0, float("nan"), 1.0]  # same layout: found on the fast path
        with pytest.raises(ValueError, match="non-finite position"):
            reader.read(serialize_message(bad))
        with pytest.raises(ValueError, match="missing joints"):
            reader.read(serialize_message(message(["j1", "j2"], (2, 2, 2))))
        # the last valid layout still reads in place
        stamp, (q, _) = reader.read(serialize_message(good))
        np.testing.assert_array_equal(q, good.position)

    def test_layout_changes_are_learned(self):
        reader = self.reader()
        for names in (["j1", "j2", "j3"], ["j2", "j3", "j1"], ["j1", "j2", "j3"]):
            msg = message(names, (3, 3, 0))
            _, (q, _) = reader.read(serialize_message(msg))
            np.testing.assert_array_equal(q, joint_state_arrays(msg, JointOrder(self.JOINTS))[0])

    def test_effort_reader_rejects_unknown_names(self):
        order = JointOrder(self.JOINTS)
        reader = JointStateReader(
            order, (2,), lambda m: (effort_arrays(m, order),), allow_extra=False
        )
        msg = message(["j2", "j1", "j3"], (0, 0, 3))
        _, (tau,) = reader.read(serialize_message(msg))
        np.testing.assert_array_equal(tau, np.array(msg.effort)[[1, 0, 2]])
        with pytest.raises(ValueError, match="unknown joints"):
            reader.read(serialize_message(message(["j1", "j2", "j3", "x"], (0, 0, 4))))


@pytest.mark.parametrize("ns", [0, 1, 999_999_999, 1_000_000_000, 12_345_678_901_234])
def test_clock_bytes_are_what_rclpy_serializes(ns):
    from rosgraph_msgs.msg import Clock

    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(ns, 1_000_000_000)
    assert clock_bytes(ns) == serialize_message(msg)
    back = deserialize_message(clock_bytes(ns), Clock)
    assert back.clock.sec * 1_000_000_000 + back.clock.nanosec == ns


@pytest.mark.parametrize("stamp_ns", [0, 1, 2_016_000_000, 10**18])
def test_the_pause_answer_names_the_last_state_and_reads_back(stamp_ns):
    assert paused_stamp(paused_message(stamp_ns)) == stamp_ns


@pytest.mark.parametrize("message", ["paused", "", "paused; last state stamped x ns", "running"])
def test_a_pause_answer_without_a_stamp_reads_as_none(message):
    assert paused_stamp(message) is None
    assert paused_message(None) == "paused"
