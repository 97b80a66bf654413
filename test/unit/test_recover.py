"""``jsc recover``: synthetic bags cut the way a killed recorder leaves them are rewritten
into complete bags holding exactly the messages that reached the disk."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_types_from_msg

from joint_space_control.cli import main as cli
from joint_space_control.recording.bag_writer import BagWriter, jazzy_typestore
from joint_space_control.recording.recover import RecoveryError, recover

TYPESTORE = jazzy_typestore()
JS = "sensor_msgs/msg/JointState"
STRING = "std_msgs/msg/String"
PERIOD_NS = 1_000_000  # 1 kHz, like the lockstep loop


def joint_state(k: int) -> bytes:
    types = TYPESTORE.types
    stamp = types["builtin_interfaces/msg/Time"](sec=k // 1000, nanosec=(k % 1000) * PERIOD_NS)
    header = types["std_msgs/msg/Header"](stamp=stamp, frame_id="")
    msg = types[JS](
        header=header,
        name=["joint1", "joint2"],
        position=np.array([1e-3 * k, -1e-3 * k]),
        velocity=np.array([0.5, -0.5]),
        effort=np.array([10.0, 20.0]),
    )
    return bytes(TYPESTORE.serialize_cdr(msg, JS))


def config() -> bytes:
    return bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data='{"law": "pd"}'), STRING))


def record(
    tmp: Path, storage: str, count: int, flush_period: float, kill_at: int | None
) -> tuple[Path, Path | None]:
    """A bag of ``count`` joint states at 1 kHz (bag stamp = sample time) and one config;
    with ``kill_at``, also a copy of the bag directory as it is on disk after that many
    messages, which is what a SIGKILL of the recorder leaves (the OS keeps what was written
    to it)."""
    bag, killed = tmp / "bag", None
    with BagWriter(bag, storage, flush_period=flush_period) as writer:
        states = writer.add_topic("/joint_states", JS)
        writer.write(writer.add_topic("/ctrl/config", STRING), 0, config())
        for k in range(count):
            if k == kill_at:
                killed = tmp / "killed"
                shutil.copytree(bag, killed)
            writer.write(states, k * PERIOD_NS, joint_state(k))
    return bag, killed


def read(bag: Path) -> dict[str, list[tuple[int, bytes, str]]]:
    """Per topic: (bag stamp, raw message, type), every message deserialized strictly."""
    topics: dict[str, list] = {}
    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        for conn, stamp, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)
            topics.setdefault(conn.topic, []).append((stamp, bytes(raw), conn.msgtype))
    return topics


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_killed_bag_is_recovered_up_to_the_last_flush(tmp_path, storage):
    flush_period = 0.1
    original, killed = record(tmp_path, storage, 3000, flush_period, kill_at=2500)
    assert not (killed / "metadata.yaml").exists()  # as a killed recorder leaves it

    result = recover(killed, tmp_path / "recovered")

    assert not result.complete and result.storage == storage
    assert (result.path / "metadata.yaml").is_file()
    got, full = read(result.path), read(original)
    states = got["/joint_states"]
    # the first messages exactly as recorded, contiguous from the first …
    assert states == full["/joint_states"][: len(states)]
    assert got["/ctrl/config"] == full["/ctrl/config"]
    # … to within one flush period of where the recorder was killed
    killed_at = 2499 * PERIOD_NS
    assert killed_at - states[-1][0] <= flush_period * 1e9
    assert result.counts == {"/joint_states": len(states), "/ctrl/config": 1}
    assert result.end_ns == states[-1][0]
    with AnyReader([result.path], default_typestore=TYPESTORE) as reader:
        conns = {c.topic: c for c in reader.connections}
    with AnyReader([original], default_typestore=TYPESTORE) as reader:
        for conn in reader.connections:
            assert conns[conn.topic].msgtype == conn.msgtype
            assert conns[conn.topic].digest == conn.digest


def test_without_flushing_a_killed_mcap_bag_has_nothing_on_disk(tmp_path):
    # The library's own buffering: a 1 MiB chunk in memory, the file header in the buffer.
    _, killed = record(tmp_path, "mcap", 3000, flush_period=0.0, kill_at=2500)
    (mcap,) = killed.glob("*.mcap")
    assert mcap.stat().st_size == 0
    with pytest.raises(RecoveryError, match="nothing of the recording reached the disk"):
        recover(killed)


def test_without_flushing_a_killed_sqlite3_bag_has_no_committed_row(tmp_path):
    _, killed = record(tmp_path, "sqlite3", 300, flush_period=0.0, kill_at=250)
    with pytest.raises(RecoveryError, match="no complete message"):
        recover(killed)
    assert not (tmp_path / "killed_recovered").exists()  # nothing half-made left behind


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_complete_bag_is_rewritten_whole(tmp_path, storage):
    original, _ = record(tmp_path, storage, 500, 0.05, kill_at=None)
    result = recover(original)
    assert result.complete
    assert result.path == tmp_path / "bag_recovered"
    assert read(result.path) == read(original)


def test_an_mcap_file_cut_anywhere_recovers_a_prefix(tmp_path):
    original, _ = record(tmp_path, "mcap", 2000, 0.05, kill_at=None)
    (mcap,) = original.glob("*.mcap")
    data = mcap.read_bytes()
    full = read(original)["/joint_states"]
    counts = []
    for k, fraction in enumerate((0.2, 0.5, 0.77, 0.95)):
        cut = tmp_path / f"cut{k}"
        cut.mkdir()
        (cut / "cut.mcap").write_bytes(data[: int(fraction * len(data))])
        states = read(recover(cut).path)["/joint_states"]
        assert states == full[: len(states)]
        counts.append(len(states))
    assert counts == sorted(counts) and counts[0] > 0 and counts[-1] < len(full)


def test_the_input_is_left_as_it_was(tmp_path):
    _, killed = record(tmp_path, "sqlite3", 1000, 0.1, kill_at=800)
    before = {p.name: p.read_bytes() for p in killed.iterdir()}
    assert any(name.endswith("-journal") for name in before)  # a transaction was open
    recover(killed)
    assert {p.name: p.read_bytes() for p in killed.iterdir()} == before


def test_a_type_outside_the_jazzy_definitions_is_rebuilt_from_the_stored_one(tmp_path):
    typestore = jazzy_typestore()
    typestore.register(get_types_from_msg("float64 x\nstd_msgs/Header header", "my_msgs/msg/X"))
    msg = typestore.types["my_msgs/msg/X"](
        x=2.5,
        header=TYPESTORE.types["std_msgs/msg/Header"](
            stamp=TYPESTORE.types["builtin_interfaces/msg/Time"](sec=1, nanosec=2), frame_id="f"
        ),
    )
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/x", "my_msgs/msg/X", typestore=typestore)
        writer.write(conn, 7, bytes(typestore.serialize_cdr(msg, "my_msgs/msg/X")))
    result = recover(bag)
    assert result.counts == {"/x": 1} and not result.skipped
    (mcap,) = result.path.glob("*.mcap")
    ((stamp, item),) = [(m.log_time_ns, m.ros_msg) for m in read_ros2_messages(str(mcap))]
    assert stamp == 7 and item.x == 2.5 and item.header.frame_id == "f"


# --------------------------------------------------------------------------- command line
def test_jsc_recover_reports_what_it_wrote(tmp_path, capsys):
    _, killed = record(tmp_path, "mcap", 1000, 0.1, kill_at=900)
    assert cli.main(["recover", str(killed), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "incomplete, cut off at byte" in out and "/joint_states:" in out
    assert f"wrote {tmp_path / 'out'}" in out


def _empty_mcap(path: Path) -> Path:
    path.mkdir()
    (path / "x.mcap").write_bytes(b"")
    return path


def _garbage(path: Path) -> Path:
    path.mkdir()
    (path / "x.mcap").write_bytes(b"not an mcap file at all")
    return path


def _header_only(path: Path) -> Path:
    # a recorder killed after the file header reached the disk but before any chunk did
    bag, _ = record(path.parent, "mcap", 10, 0.0, kill_at=None)
    (mcap,) = bag.glob("*.mcap")
    path.mkdir()
    (path / "x.mcap").write_bytes(mcap.read_bytes()[:30])
    return path


def _bad_sqlite(path: Path) -> Path:
    path.mkdir()
    (path / "x.db3").write_bytes(b"SQLite format 3\x00" + bytes(200))
    return path


def _two_files(path: Path) -> Path:
    path.mkdir()
    (path / "a.mcap").write_bytes(b"")
    (path / "b.mcap").write_bytes(b"")
    return path


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p, "does not exist"),
        (lambda p: (p.mkdir(), p)[1], "no .mcap or .db3"),
        (_empty_mcap, "nothing of the recording reached the disk"),
        (_garbage, "not an MCAP file"),
        (_header_only, "no complete message"),
        (_bad_sqlite, "not a"),
        (_two_files, "several storage files"),
    ],
    ids=["missing", "empty-dir", "empty-file", "garbage", "header-only", "bad-sqlite", "split"],
)
def test_an_unrecoverable_input_is_one_error_line_and_exit_2(tmp_path, capsys, make, message):
    bag = make(tmp_path / "in")
    assert cli.main(["recover", str(bag), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_an_existing_output_is_refused(tmp_path):
    _, killed = record(tmp_path, "mcap", 300, 0.1, kill_at=200)
    (tmp_path / "out").mkdir()
    with pytest.raises(RecoveryError, match="exists already"):
        recover(killed, tmp_path / "out")
