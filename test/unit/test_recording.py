"""Recording library: CDR framing, the bag writer (both storages, both readers), topic
selection, and the recorder's QoS adaptation."""

from __future__ import annotations

import errno
import shutil
import sqlite3
import threading
from pathlib import Path

import pytest
from mcap_ros2.reader import read_ros2_messages
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from rosbags.serde import SerdeError
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String

from joint_space_control.nodes.recorder import subscription_qos
from joint_space_control.recording.bag_writer import (
    BagWriteError,
    BagWriter,
    CdrFraming,
    free_space_mb,
    jazzy_typestore,
)
from joint_space_control.recording.recover import recover
from joint_space_control.recording.selection import DEFAULT_TOPICS, TopicSelection, world_topics

TYPESTORE = jazzy_typestore()
JS = "sensor_msgs/msg/JointState"


def command_message(effort: list[float]) -> bytes:
    """An effort command as the controllers send it: position and velocity empty."""
    msg = JointState(name=[f"j{i}" for i in range(len(effort))], effort=effort)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 500
    return serialize_message(msg)


def full_state_message() -> bytes:
    msg = JointState(name=["a", "b"], position=[1.0, 2.0], velocity=[3.0, 4.0], effort=[5.0, 6.0])
    return serialize_message(msg)


# --------------------------------------------------------------------------- CDR framing
def test_rclpy_pads_empty_sequences_beyond_what_rosbags_accepts():
    raw = command_message([1.0, -2.0])
    with pytest.raises(SerdeError, match="size mismatch"):
        TYPESTORE.deserialize_cdr(raw, JS)  # the problem the framing exists for


def test_framing_cuts_the_padding_and_keeps_the_content():
    raw = command_message([1.0, -2.0])
    framed = CdrFraming(TYPESTORE, JS).frame(raw)
    assert len(framed) == len(raw) - 8  # 4 bytes for each of the two empty sequences
    msg = TYPESTORE.deserialize_cdr(framed, JS)
    assert list(msg.name) == ["j0", "j1"]
    assert msg.effort.tolist() == [1.0, -2.0]
    assert msg.position.size == 0 and msg.velocity.size == 0
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (3, 500)


def test_framing_leaves_a_well_formed_message_untouched():
    raw = full_state_message()
    assert CdrFraming(TYPESTORE, JS).frame(raw) == raw


def test_framing_a_long_reference_ends_where_its_deserializer_ends():
    """The size walk (no message built) and the deserializer agree on where the content of a
    1000-point reference with empty velocity, acceleration and effort sequences ends."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    kind = "trajectory_msgs/msg/JointTrajectory"
    msg = JointTrajectory(joint_names=["a", "b", "c"])
    for k in range(1000):
        point = JointTrajectoryPoint(positions=[0.001 * k, -1.0, 2.5])
        point.time_from_start = Duration(sec=k // 1000, nanosec=(k % 1000) * 1_000_000)
        msg.points.append(point)
    raw = serialize_message(msg)
    framed = CdrFraming(TYPESTORE, kind).frame(raw)
    msgdef = TYPESTORE.get_msgdef(kind)
    _, end = msgdef.deserialize_cdr_le(memoryview(raw)[4:], 0, msgdef.cls, TYPESTORE)
    assert len(framed) == end + 4 < len(raw)  # rclpy's padding was cut
    back = TYPESTORE.deserialize_cdr(framed, kind)
    assert len(back.points) == 1000 and back.points[999].positions.tolist() == [0.999, -1.0, 2.5]


@pytest.mark.parametrize(
    "raw",
    [b"", b"\x00\x01", b"\x07\x07\x00\x00" + bytes(40), command_message([1.0, 2.0])[:30]],
    ids=["empty", "short", "bad-header", "truncated"],
)
def test_framing_rejects_malformed_bytes(raw):
    with pytest.raises(SerdeError):
        CdrFraming(TYPESTORE, JS).frame(raw)


# --------------------------------------------------------------------------- bag writer
def write_sample_bag(path: Path, storage: str) -> dict[str, int]:
    with BagWriter(path, storage) as bag:
        cmd = bag.add_topic("/effort_command", JS)
        state = bag.add_topic("/ctrl/state", "std_msgs/msg/Float64MultiArray")
        config = bag.add_topic("/ctrl/config", "std_msgs/msg/String")
        for k in range(50):
            assert bag.write(cmd, 1_000_000 * k, command_message([0.1 * k, -0.1 * k]))
            arr = Float64MultiArray(data=[k * 1e-3, float(k), 2.0 * k])
            assert bag.write(state, 1_000_000 * k + 10, serialize_message(arr))
        assert bag.write(config, 5, serialize_message(String(data='{"law": "pd_gravity"}')))
        assert not bag.write(cmd, 99, b"\x00\x01\x00\x00garbage")
        assert cmd.rejected == 1
        assert bag.message_count == 101
    return {"/effort_command": 50, "/ctrl/state": 50, "/ctrl/config": 1}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_reads_back_with_rosbags(tmp_path, storage):
    path = tmp_path / "bag"
    expected = write_sample_bag(path, storage)
    assert (path / "metadata.yaml").is_file()
    counts: dict[str, int] = {}
    efforts = []
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        assert reader.message_count == sum(expected.values())
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)  # strict: raises on size mismatch
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/effort_command":
                efforts.append((stamp, msg.effort.tolist()))
    assert counts == expected
    assert efforts[7] == (7_000_000, [pytest.approx(0.7), pytest.approx(-0.7)])


def test_mcap_bag_reads_back_with_the_independent_mcap_reader(tmp_path):
    path = tmp_path / "bag"
    expected = write_sample_bag(path, "mcap")
    counts: dict[str, int] = {}
    last = None
    for item in read_ros2_messages(str(path / "bag.mcap")):
        counts[item.channel.topic] = counts.get(item.channel.topic, 0) + 1
        if item.channel.topic == "/effort_command":
            last = item.ros_msg
    assert counts == expected
    assert list(last.effort) == pytest.approx([4.9, -4.9])
    assert list(last.name) == ["j0", "j1"]


def test_bag_writer_refuses_bad_outputs(tmp_path):
    (tmp_path / "taken").mkdir()
    with pytest.raises(ValueError, match="exists already"):
        BagWriter(tmp_path / "taken")
    with pytest.raises(ValueError, match="not a directory"):
        BagWriter(tmp_path / "missing" / "bag")
    with pytest.raises(ValueError, match="unknown storage"):
        BagWriter(tmp_path / "bag", "rosbag1")
    assert not (tmp_path / "bag").exists()


def test_bag_writer_refuses_unknown_types_and_duplicate_topics(tmp_path):
    with BagWriter(tmp_path / "bag") as bag:
        assert not bag.knows("my_msgs/msg/Unknown")
        with pytest.raises(ValueError, match="no message definition"):
            bag.add_topic("/x", "my_msgs/msg/Unknown")
        bag.add_topic("/joint_states", JS)
        with pytest.raises(ValueError, match="already recorded"):
            bag.add_topic("/joint_states", JS)


def test_close_is_idempotent_and_stops_writing(tmp_path):
    bag = BagWriter(tmp_path / "bag")
    topic = bag.add_topic("/joint_states", JS)
    assert bag.write(topic, 1, full_state_message())
    bag.close()
    bag.close()
    assert not bag.write(topic, 2, full_state_message())
    with AnyReader([tmp_path / "bag"], default_typestore=TYPESTORE) as reader:
        assert reader.message_count == 1


# --------------------------------------------------------------------------- faults
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_flushing_bounds_what_a_kill_loses_in_bag_time(tmp_path, storage):
    # Stamps 1 ms apart written much faster than 1 kHz: the bag-time criterion flushes.
    flush_period, loss = 0.25, []
    with BagWriter(tmp_path / "bag", storage, flush_period=flush_period) as bag:
        topic = bag.add_topic("/joint_states", JS)
        for k in range(2000):
            if k and k % 400 == 0:  # a SIGKILL leaves what the OS holds: copy it now
                killed = tmp_path / f"killed{k}"
                shutil.copytree(tmp_path / "bag", killed)
                result = recover(killed)
                loss.append((k - 1) * 1e-3 - result.end_ns * 1e-9)
                assert result.counts["/joint_states"] == round(result.end_ns / 1e6) + 1
            bag.write(topic, k * 1_000_000, full_state_message())
    assert all(0 <= lost <= flush_period for lost in loss), loss


def test_flush_sends_an_idle_recorders_messages_to_the_file(tmp_path):
    with BagWriter(tmp_path / "bag", "mcap", flush_period=10.0) as bag:
        topic = bag.add_topic("/joint_states", JS)
        bag.write(topic, 0, full_state_message())  # flushed: the first one always is
        for k in range(1, 5):
            bag.write(topic, k, full_state_message())
        shutil.copytree(tmp_path / "bag", tmp_path / "before")
        bag.flush()  # the recorder's wall-time timer
        shutil.copytree(tmp_path / "bag", tmp_path / "after")
    assert recover(tmp_path / "before").counts["/joint_states"] == 1
    assert recover(tmp_path / "after").counts["/joint_states"] == 5


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_topics_messages_and_flushes_may_come_from_other_threads(tmp_path, storage):
    # The recorder creates the bag in its main thread, adds topics and flushes from its
    # executor thread and writes from its control path.
    bag = BagWriter(tmp_path / "bag", storage, flush_period=1e-3)
    failures: list[BaseException] = []

    def other_thread():
        try:
            topic = bag.add_topic("/joint_states", JS)
            for k in range(20):
                bag.write(topic, k * 1_000_000, full_state_message())
            bag.flush()
        except BaseException as err:  # noqa: BLE001 - reported by the test thread
            failures.append(err)

    thread = threading.Thread(target=other_thread)
    thread.start()
    thread.join()
    bag.close()
    assert not failures and bag.error is None
    with AnyReader([tmp_path / "bag"], default_typestore=TYPESTORE) as reader:
        assert reader.message_count == 20


def test_too_little_free_space_is_refused_at_start(tmp_path):
    free = free_space_mb(tmp_path)
    with pytest.raises(ValueError, match=r"MB free on .* less than min_free_space_mb"):
        BagWriter(tmp_path / "bag", min_free_space_mb=free * 2 + 1)
    assert not (tmp_path / "bag").exists()
    with BagWriter(tmp_path / "bag", min_free_space_mb=1e-3):  # enough: created
        pass
    assert (tmp_path / "bag" / "metadata.yaml").is_file()


class _FullDisk:
    """A file object whose writes fail as on a full disk."""

    def __init__(self, file):
        self._file = file

    def write(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    flush = write

    def tell(self):
        return self._file.tell()

    def close(self):
        self._file.close()


def test_a_disk_full_mid_run_is_one_error_and_stops_the_bag(tmp_path):
    bag = BagWriter(tmp_path / "bag", "mcap", flush_period=0.01)
    topic = bag.add_topic("/joint_states", JS)
    for k in range(10):  # 10 ms apart: each one flushed
        assert bag.write(topic, k * 10_000_000, full_state_message())
    storage = bag._writer.storage
    storage.bio = _FullDisk(storage.bio)
    with pytest.raises(BagWriteError, match="No space left on device.*jsc recover"):
        for k in range(10, 100):
            bag.write(topic, k * 10_000_000, full_state_message())
    assert isinstance(bag.error, BagWriteError)
    assert not bag.write(topic, 10**9, full_state_message())  # no second error
    bag.flush()
    bag.close()  # nothing left to fail
    # what reached the disk before the error is recoverable
    assert recover(tmp_path / "bag").counts["/joint_states"] == 10


def test_a_sqlite3_disk_full_is_the_same_error(tmp_path):
    bag = BagWriter(tmp_path / "bag", "sqlite3", flush_period=0.0)
    topic = bag.add_topic("/joint_states", JS)
    assert bag.write(topic, 0, full_state_message())

    class FullCursor:
        def execute(self, *args):
            raise sqlite3.OperationalError("database or disk is full")

    bag._writer.storage.cursor = FullCursor()
    with pytest.raises(BagWriteError, match="database or disk is full"):
        bag.write(topic, 1, full_state_message())
    assert not bag.write(topic, 2, full_state_message())
    with pytest.raises(ValueError, match="is closed"):
        bag.add_topic("/other", JS)
    bag.close()


def test_a_topic_that_cannot_be_stored_is_the_same_error(tmp_path):
    bag = BagWriter(tmp_path / "bag", "sqlite3")

    class FullCursor:
        def execute(self, *args):
            raise sqlite3.OperationalError("database or disk is full")

    bag._writer.storage.cursor = FullCursor()
    with pytest.raises(BagWriteError, match="database or disk is full"):
        bag.add_topic("/joint_states", JS)
    assert bag.error is not None
    bag.close()


# --------------------------------------------------------------------------- selection, QoS
def test_selection_resolves_relative_names_in_the_namespace():
    sel = TopicSelection(["joint_states", "/clock", "*/state"], "/robot1")
    assert sel.patterns == ["/robot1/joint_states", "/clock", "/robot1/*/state"]
    assert sel.matches("/robot1/joint_states")
    assert not sel.matches("/joint_states")
    assert sel.matches("/robot1/pd_gravity_controller/state")
    assert sel.matches("/clock")
    assert not sel.matches("/robot2/pd_gravity_controller/state")


def test_empty_selection_is_the_default_set():
    sel = TopicSelection([], "/")
    assert len(sel.patterns) == len(DEFAULT_TOPICS)
    for topic in [
        "/joint_states",
        "/effort_command",
        "/reference",
        "/pd_gravity_controller/state",
        "/inverse_dynamics_controller/config",
        "/clock",
        "/parameter_events",
        "/diagnostics",
    ]:
        assert sel.matches(topic), topic
    assert not sel.matches("/rosout")


def test_world_topics_record_each_robot_in_its_namespace():
    sel = TopicSelection(world_topics(["iiwa", "arm"]), "/")
    for ns in ("iiwa", "arm"):
        for topic in [
            "joint_states",
            "effort_command",
            "reference",
            "sim_bridge/true_joint_states",
        ]:
            assert sel.matches(f"/{ns}/{topic}"), (ns, topic)
    assert sel.matches("/iiwa/pd_gravity_controller/state")
    assert sel.matches("/arm/inverse_dynamics_controller/config")
    for topic in ["/clock", "/parameter_events", "/diagnostics"]:
        assert sel.matches(topic)
    assert not sel.matches("/joint_states") and not sel.matches("/other/joint_states")


@pytest.mark.parametrize("entry", ["", "~/state", "bad name", "/a//b"])
def test_selection_rejects_invalid_entries(entry):
    with pytest.raises(ValueError):
        TopicSelection([entry])


def _offered(reliability, durability) -> QoSProfile:
    return QoSProfile(depth=1, reliability=reliability, durability=durability)


def test_subscription_qos_follows_the_publishers():
    rel, be = ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT
    vol, tl = DurabilityPolicy.VOLATILE, DurabilityPolicy.TRANSIENT_LOCAL
    none = subscription_qos([])
    assert (none.reliability, none.durability) == (rel, vol)
    mixed = subscription_qos([_offered(rel, vol), _offered(be, vol)])
    assert mixed.reliability == be
    latched = subscription_qos([_offered(rel, tl)])
    assert (latched.reliability, latched.durability) == (rel, tl)
    partly = subscription_qos([_offered(rel, tl), _offered(rel, vol)])
    assert partly.durability == vol
    assert none.depth >= 100
