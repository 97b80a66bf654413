"""Recovery of a bag whose recorder died without closing it (SIGKILL, crash, power loss).

A killed recorder leaves a storage file without its ending and no ``metadata.yaml``:

- MCAP: the header and the chunks written so far, perhaps a partial last record, no summary
  or footer. The file is read record by record with the ``mcap`` package's stream reader
  (which needs no summary) until the first record that is cut off or unreadable;
- sqlite3: the database with the transactions committed so far and a hot journal of the
  open one, which SQLite rolls back when the copy is opened (the input is not modified).

What was read goes into a new, complete bag of the same storage, topics, types, message
definitions and offered QoS, written by ``rosbags`` with its ``metadata.yaml``. No ROS
import: this runs wherever the bag is.
"""

from __future__ import annotations

import shutil
import sqlite3
import struct
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import Writer, WriterError
from rosbags.rosbag2.errors import ReaderError
from rosbags.rosbag2.metadata import parse_qos
from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore

from joint_space_control.recording.bag_writer import BAG_VERSION, STORAGES, jazzy_typestore

_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}
#: Separator of the definitions in a rosbag2 ``ros2msg`` message definition.
_SECTION = "=" * 80 + "\n"


class RecoveryError(ValueError):
    """The input holds nothing that can be recovered (or the output cannot be written)."""


@dataclass
class TopicInfo:
    """A topic of the damaged bag as its storage describes it."""

    name: str
    msgtype: str
    msgdef: str  # rosbag2 form: the type's .msg text, then its dependencies
    encoding: str  # 'ros2msg' | 'ros2idl'
    rihs01: str  # type hash ('' when the storage has none)
    serialization_format: str = "cdr"
    offered_qos: list[Qos] = field(default_factory=list)


@dataclass
class Recovery:
    """What was recovered from ``source`` into the bag ``path``."""

    source: Path
    path: Path
    storage: str
    counts: dict[str, int]  # messages per topic (every topic of the input, also empty ones)
    start_ns: int
    end_ns: int
    complete: bool  # the input was complete: nothing was cut off
    stopped: str  # why reading stopped (truncation, unreadable record) or 'end of file'
    skipped: list[str] = field(default_factory=list)  # topics whose type could not be rebuilt

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())


def storage_file(bag: Path) -> tuple[Path, str]:
    """The storage file of ``bag`` (a bag directory or the file itself) and its storage."""
    bag = Path(bag)
    if bag.is_file():
        files = [bag]
    elif bag.is_dir():
        files = sorted(p for p in bag.iterdir() if p.suffix in _SUFFIXES and p.is_file())
    else:
        raise RecoveryError(f"{str(bag)!r} does not exist")
    if not files or files[0].suffix not in _SUFFIXES:
        raise RecoveryError(f"no .mcap or .db3 storage file in {str(bag)!r}")
    if len(files) > 1:
        raise RecoveryError(
            f"{str(bag)!r} holds several storage files ({', '.join(p.name for p in files)}): "
            "recover them one by one"
        )
    return files[0], _SUFFIXES[files[0].suffix]


def recover(bag: Path | str, out: Path | str | None = None) -> Recovery:
    """Rewrite what is readable of the bag ``bag`` into the new bag ``out`` (default:
    ``<bag>_recovered`` next to it).

    Raises:
        RecoveryError: no storage file, not a bag of its storage, no complete message, or
            ``out`` exists or cannot be created.
    """
    source, storage = storage_file(Path(bag))
    if out is None:
        base = Path(bag) if Path(bag).is_dir() else source.with_suffix("")
        out = base.with_name(base.name + "_recovered")
    out = Path(out)
    if out.exists():
        raise RecoveryError(f"output {str(out)!r} exists already: choose a new path")
    with tempfile.TemporaryDirectory(prefix="jsc_recover_") as scratch:
        if storage == "mcap":
            reader = _McapSalvage(source)
        else:
            reader = _SqliteSalvage(source, Path(scratch))
        try:
            return _rewrite(reader, Path(bag), out, storage)
        finally:
            reader.close()


def _rewrite(
    reader: _McapSalvage | _SqliteSalvage, bag: Path, out: Path, storage: str
) -> Recovery:
    writer = Writer(out, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    try:
        writer.open()
    except (OSError, WriterError) as err:
        raise RecoveryError(f"cannot create {str(out)!r}: {err}") from err
    typestore = jazzy_typestore()
    connections: dict[int, Connection | None] = {}
    counts: dict[str, int] = {}
    skipped: list[str] = []
    start, end = 2**63 - 1, 0
    try:
        for key, item in reader.items():
            if isinstance(item, TopicInfo):
                connections[key] = _connection(writer, typestore, item)
                if connections[key] is None:
                    skipped.append(f"{item.name} [{item.msgtype}]")
                else:
                    counts.setdefault(item.name, 0)
                continue
            connection = connections.get(key)
            if connection is None:
                continue
            stamp, data = item
            writer.write(connection, stamp, data)
            counts[connection.topic] += 1
            start, end = min(start, stamp), max(end, stamp)
        if not sum(counts.values()):
            raise RecoveryError(f"no complete message in {str(reader.path)!r}: {reader.stopped}")
        writer.close()
    except BaseException:
        writer.abort()
        shutil.rmtree(out, ignore_errors=True)
        raise
    return Recovery(
        bag, out, storage, counts, start, end, reader.complete, reader.stopped, skipped
    )


def _connection(writer: Writer, typestore: Typestore, topic: TopicInfo) -> Connection | None:
    """The output connection of ``topic``: its stored definition, with the type hash of
    the storage, else of the Jazzy definitions, else of the stored definition parsed; None
    when no hash can be had."""
    try:
        if topic.msgtype not in typestore.fielddefs and topic.encoding == "ros2msg":
            typestore.register(_types_of_msgdef(topic.msgtype, topic.msgdef))
        rihs01 = topic.rihs01 or typestore.hash_rihs01(topic.msgtype)
        return writer.add_connection(
            topic.name,
            topic.msgtype,
            msgdef=topic.msgdef or None,
            rihs01=rihs01,
            typestore=typestore,
            serialization_format=topic.serialization_format,
            offered_qos_profiles=topic.offered_qos,
        )
    except Exception:  # noqa: BLE001 - no usable definition (or a duplicate): skip the topic
        return None


def _types_of_msgdef(msgtype: str, msgdef: str) -> dict:
    """The types of a rosbag2 ``ros2msg`` definition (the type, then ``MSG: dep`` parts)."""
    types: dict = {}
    name = msgtype
    for k, part in enumerate(msgdef.split(_SECTION)):
        if k:
            header, _, part = part.partition("\n")
            name = header.removeprefix("MSG: ").strip()
        types.update(get_types_from_msg(part, name))
    return types


def _qos(text: str) -> list[Qos]:
    try:
        return parse_qos(text)
    except (ReaderError, KeyError, TypeError, ValueError):
        return []


class _McapSalvage:
    """The records of an MCAP file, read in order until the first damaged one."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file = path.open("rb")
        magic = self._file.read(8)
        if magic != b"\x89MCAP0\r\n":
            self._file.close()
            if len(magic) < 8:
                raise RecoveryError(
                    f"{str(path)!r} has {len(magic)} bytes: nothing of the recording reached "
                    "the disk"
                )
            raise RecoveryError(f"{str(path)!r} is not an MCAP file (bad magic)")
        self._file.seek(0)
        self.complete = False
        self.stopped = "not read"

    def items(self) -> Iterator[tuple[int, TopicInfo | tuple[int, bytes]]]:
        """(channel id, TopicInfo) for each channel, (channel id, (log time, data)) for each
        message."""
        schemas: dict[int, Schema] = {}
        channels: set[int] = set()
        records = StreamReader(self._file, record_size_limit=None).records
        try:
            for record in records:
                if isinstance(record, Message):
                    yield record.channel_id, (record.log_time, record.data)
                elif isinstance(record, Schema):
                    schemas.setdefault(record.id, record)
                elif isinstance(record, Channel) and record.id not in channels:
                    channels.add(record.id)
                    schema = schemas.get(record.schema_id)
                    if schema is None:
                        continue
                    yield (
                        record.id,
                        TopicInfo(
                            record.topic,
                            schema.name,
                            schema.data.decode("utf-8", errors="replace"),
                            schema.encoding,
                            "",
                            record.message_encoding,
                            _qos(record.metadata.get("offered_qos_profiles", "")),
                        ),
                    )
                elif isinstance(record, Footer):
                    self.complete = True
            self.stopped = "end of file"
        except EndOfFile:
            self.stopped = f"cut off at byte {self._file.tell()}"
        except (McapError, struct.error, ValueError, UnicodeDecodeError, MemoryError) as err:
            self.stopped = f"unreadable record before byte {self._file.tell()}: {err}"

    def close(self) -> None:
        self._file.close()


class _SqliteSalvage:
    """The committed rows of a rosbag2 sqlite3 database, read from a copy (with its
    journal, so that SQLite rolls back the transaction the recorder left open)."""

    def __init__(self, path: Path, scratch: Path) -> None:
        self.path = path
        copy = scratch / path.name
        for companion in ("", "-journal", "-wal", "-shm"):
            src = path.with_name(path.name + companion)
            if src.is_file():
                shutil.copyfile(src, scratch / src.name)
        self.stopped = "not read"
        try:
            self._db = sqlite3.connect(f"file:{copy}", uri=True)
            self._db.row_factory = sqlite3.Row
            tables = {r[0] for r in self._db.execute("SELECT name FROM sqlite_master")}
            if not {"topics", "messages"} <= tables:
                raise RecoveryError(f"{str(path)!r} is not a rosbag2 sqlite3 bag (no topics)")
            # a closed bag has its metadata row (written in the last transaction)
            self.complete = "metadata" in tables and bool(
                self._db.execute("SELECT count(*) FROM metadata").fetchone()[0]
            )
        except (sqlite3.Error, RecoveryError) as err:
            if hasattr(self, "_db"):
                self._db.close()
            if isinstance(err, RecoveryError):
                raise
            raise RecoveryError(f"{str(path)!r} is not a readable sqlite3 bag: {err}") from err
        self._has_definitions = "message_definitions" in tables

    def items(self) -> Iterator[tuple[int, TopicInfo | tuple[int, bytes]]]:
        definitions: dict[str, sqlite3.Row] = {}
        try:
            if self._has_definitions:
                for row in self._db.execute("SELECT * FROM message_definitions"):
                    definitions[row["topic_type"]] = row
            for row in self._db.execute("SELECT * FROM topics ORDER BY id"):
                columns = row.keys()
                msgtype = row["type"]
                definition = definitions.get(msgtype)
                if definition is not None and definition["encoded_message_definition"]:
                    msgdef = definition["encoded_message_definition"]
                    encoding = definition["encoding"]
                else:  # an older schema: the Jazzy definition, if the type has one
                    msgdef, encoding = "", "ros2msg"
                yield (
                    row["id"],
                    TopicInfo(
                        row["name"],
                        msgtype,
                        msgdef,
                        encoding,
                        row["type_description_hash"] if "type_description_hash" in columns else "",
                        row["serialization_format"],
                        _qos(row["offered_qos_profiles"]),
                    ),
                )
            query = "SELECT topic_id, timestamp, data FROM messages ORDER BY id"
            for topic_id, stamp, data in self._db.execute(query):
                yield topic_id, (stamp, bytes(data))
            self.stopped = "end of the committed rows"
        except sqlite3.Error as err:
            self.stopped = f"unreadable database: {err}"

    def close(self) -> None:
        self._db.close()
