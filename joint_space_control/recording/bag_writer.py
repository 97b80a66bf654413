"""A rosbag2 bag being recorded: topics, raw CDR messages, a clean close.

The :class:`BagWriter` wraps the ``rosbags`` writer with what a recorder needs on top:

- the storage is chosen by name (``mcap``, the rosbag2 default, or ``sqlite3``) and the bag
  is created at construction, so that an existing or unwritable output fails before
  anything runs;
- message definitions come from the ``rosbags`` typestore of ROS 2 Jazzy, so the bag is
  self-describing (MCAP schemas, metadata type hashes) for ``ros2 bag``, Foxglove,
  PlotJuggler and the ``mcap`` tools;
- every message is written with its exact CDR length (:class:`CdrFraming`): rclpy hands out
  some messages with trailing bytes that strict readers reject (see there);
- what was written reaches the file at least every ``flush_period`` of recorded time (and of
  wall time), so a recorder killed outright (SIGKILL, power cut of the process) loses at
  most about that much; ``jsc recover`` (:mod:`.recover`) turns what is on disk into a
  complete bag;
- a write error of the storage (disk full, I/O error) is raised as :class:`BagWriteError`
  once; the bag is then closed as far as it can be and takes no more messages;
- :meth:`BagWriter.close` is idempotent and writes the storage summary and
  ``metadata.yaml``.

What a killed writer leaves without periodic flushing (rosbags 0.11, read from its source):
the MCAP writer collects messages in an in-memory chunk and writes it only when it exceeds
1 MiB, so the last ≤ 1 MiB of messages is lost and the file has no summary or footer; the
sqlite3 writer keeps every row in one transaction committed at close, so nothing but the
empty tables survives. A flush therefore closes the MCAP chunk early (the writer's own
``close_chunk``, one chunk per flush) and pushes the file buffer to the OS, or commits the
sqlite3 transaction. Neither calls fsync: a killed process loses nothing the OS holds, a
power failure may.
"""

from __future__ import annotations

import shutil
import sqlite3
import struct
import threading
import time
from collections.abc import Sequence
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (Jazzy's).
BAG_VERSION = 9
#: Padding a CDR reader accepts after the last field (alignment of the next message).
_CDR_SLACK = 3
#: Default of the recorder's ``flush_period`` [s].
FLUSH_PERIOD = 0.5
#: Default of the recorder's ``min_free_space_mb``.
MIN_FREE_SPACE_MB = 100.0
#: Errors of the storage when writing: OSError (ENOSPC, EIO, …) from the MCAP file,
#: sqlite3.Error ("database or disk is full", …) from the sqlite3 database.
_STORAGE_ERRORS = (OSError, sqlite3.Error, WriterError)


class BagWriteError(RuntimeError):
    """The storage failed while recording (disk full, I/O error): the bag is incomplete."""


def jazzy_typestore() -> Typestore:
    """The message definitions of ROS 2 Jazzy (rcl_interfaces, std_msgs, sensor_msgs, …)."""
    return get_typestore(Stores.ROS2_JAZZY)


class CdrFraming:
    """Cuts a serialized message to the length its fields actually use.

    rclpy (Fast CDR) reserves 4 bytes of alignment for every *empty* sequence of 8-byte
    values and sends them as trailing bytes: a JointState with empty velocity and effort
    arrives 8 bytes longer than its content. ``ros2 bag`` copes, but rosbags and other
    strict readers reject the message ("CDR message size mismatch"). Walking the message's
    fields gives the true end of the content: little-endian CDR (what rclpy sends) with the
    typestore's generated size walk, which skips over arrays without building the message
    (a 100,000-point reference: 0.2 s instead of 1.4 s of parsing, during which the
    recorder took nothing else); big-endian with its deserializer.
    """

    def __init__(self, typestore: Typestore, msgtype: str) -> None:
        msgdef = typestore.get_msgdef(msgtype)
        self._typestore = typestore
        self._cls = msgdef.cls
        self._walk = msgdef.getsize_cdr_to_ros1  # (input, ipos, _, opos, typestore) -> ends
        self._be = msgdef.deserialize_cdr_be
        self.msgtype = msgtype

    def frame(self, raw: bytes) -> bytes:
        """``raw`` without trailing bytes beyond the CDR alignment slack.

        Raises:
            SerdeError: the bytes are not a valid message of this type.
        """
        if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
            raise SerdeError(f"invalid CDR header for {self.msgtype}")
        body = memoryview(raw)[4:]
        try:
            if raw[1]:
                end, _ = self._walk(body, 0, None, 0, self._typestore)
            else:
                _, end = self._be(body, 0, self._cls, self._typestore)
        except (struct.error, ValueError, IndexError, UnicodeDecodeError) as err:
            raise SerdeError(f"cannot parse {self.msgtype}: {err}") from err
        end += 4
        if end > len(raw):
            raise SerdeError(f"truncated {self.msgtype}")
        return raw[:end] if len(raw) > end + _CDR_SLACK else raw


@dataclass
class RecordedTopic:
    name: str
    msgtype: str
    connection: Connection
    framing: CdrFraming
    count: int = 0
    rejected: int = 0


def free_space_mb(directory: Path) -> float:
    """Space available to this user on the file system of ``directory`` [MB = 10⁶ bytes]."""
    return shutil.disk_usage(directory).free / 1e6


class BagWriter:
    """A new rosbag2 bag at ``path`` (which must not exist yet) in ``storage`` format.

    ``flush_period`` [s]: what was written is flushed to the file once the bag time stamp or
    the wall time has advanced this much since the last flush (0: only at close, the
    library's own buffering). ``min_free_space_mb``: the bag is not created on a file
    system with less free space (0: no check).
    """

    def __init__(
        self,
        path: Path | str,
        storage: str = "mcap",
        flush_period: float = FLUSH_PERIOD,
        min_free_space_mb: float = 0.0,
    ) -> None:
        if storage not in STORAGES:
            raise ValueError(f"unknown storage {storage!r}: use one of {sorted(STORAGES)}")
        if not flush_period >= 0 or not min_free_space_mb >= 0:
            raise ValueError("flush_period and min_free_space_mb must be >= 0")
        self.path = Path(path)
        self.storage = storage
        if self.path.exists():
            raise ValueError(f"output {str(self.path)!r} exists already: choose a new bag path")
        parent = self.path.absolute().parent
        if not parent.is_dir():
            raise ValueError(f"cannot create bag {str(self.path)!r}: {parent} is not a directory")
        if min_free_space_mb > 0:
            free = free_space_mb(parent)
            if free < min_free_space_mb:
                raise ValueError(
                    f"only {free:.0f} MB free on the file system of {parent}, "
                    f"less than min_free_space_mb = {min_free_space_mb:g}: free space or "
                    "record elsewhere"
                )
        self.typestore = jazzy_typestore()
        self._writer = Writer(self.path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        try:
            self._writer.open()
            storage_writer = self._writer.storage
            if isinstance(storage_writer, Sqlite3Writer):
                # The recorder writes from its control path and adds topics and flushes from
                # its executor thread, one at a time (self._lock); Python's sqlite3 refuses a
                # connection used by another thread than its creator unless told otherwise.
                storage_writer.conn.close()
                storage_writer.conn = sqlite3.connect(
                    f"file:{storage_writer.path}", uri=True, check_same_thread=False
                )
                storage_writer.cursor = storage_writer.conn.cursor()
        except (OSError, WriterError, sqlite3.Error) as err:
            raise ValueError(f"cannot create bag {str(self.path)!r}: {err}") from err
        self.topics: dict[str, RecordedTopic] = {}
        self._open = True
        self.error: BagWriteError | None = None
        # write() (the recording thread) and flush() (a timer) may run in different threads
        self._lock = threading.Lock()
        self._period_ns = round(flush_period * 1e9)
        self._pending = False  # messages written since the last flush
        self._next_stamp = 0  # flush when a bag stamp reaches this …
        self._next_wall = 0  # … or the monotonic clock [ns] does

    def knows(self, msgtype: str) -> bool:
        """Whether the message definition of ``msgtype`` is known (it can be recorded)."""
        return msgtype in self.typestore.fielddefs

    def add_topic(self, name: str, msgtype: str, offered_qos: Sequence[Qos] = ()) -> RecordedTopic:
        """Register a topic (once); its metadata carries the publishers' offered QoS.

        Raises:
            ValueError: known already, no message definition, or the bag is closed.
            BagWriteError: as :meth:`write`.
        """
        if name in self.topics:
            raise ValueError(f"topic {name!r} is already recorded")
        if not self.knows(msgtype):
            raise ValueError(f"no message definition for {msgtype!r} (topic {name!r})")
        with self._lock:
            if not self._open:
                raise ValueError(f"bag {str(self.path)!r} is closed")
            try:
                connection = self._writer.add_connection(
                    name, msgtype, typestore=self.typestore, offered_qos_profiles=list(offered_qos)
                )
            except (OSError, sqlite3.Error) as err:  # sqlite3 writes the topic row now
                raise self._failed(err) from err
        topic = RecordedTopic(name, msgtype, connection, CdrFraming(self.typestore, msgtype))
        self.topics[name] = topic
        return topic

    def write(self, topic: RecordedTopic, stamp_ns: int, raw: bytes, exact: bool = False) -> bool:
        """Append one serialized message received at ``stamp_ns``. A message that does not
        parse as its type is not written (``False``; counted in ``topic.rejected``).
        ``exact``: the bytes were serialized in this process by a wire image
        (:mod:`joint_space_control.ros.wire`), whose content ends where the bytes do; they
        are written as they are, without the parse that frames a received message (two
        thirds of the cost of writing a message).

        Raises:
            BagWriteError: the storage failed (once; the bag is closed as far as it can be
                and later calls return ``False``).
        """
        if not self._open:
            return False
        try:
            data = raw if exact else topic.framing.frame(raw)
        except SerdeError:
            topic.rejected += 1
            return False
        with self._lock:
            if not self._open:
                return False
            try:
                self._writer.write(topic.connection, stamp_ns, data)
                topic.count += 1
                self._pending = True
                if self._period_ns and (
                    stamp_ns >= self._next_stamp or time.monotonic_ns() >= self._next_wall
                ):
                    self._flush(stamp_ns)
            except _STORAGE_ERRORS as err:
                raise self._failed(err) from err
        return True

    def flush(self) -> None:
        """Push what was written since the last flush to the file (e.g. from a wall-time
        timer, so that an idle recorder does not hold messages back).

        Raises:
            BagWriteError: as :meth:`write`.
        """
        with self._lock:
            if not (self._open and self._pending):
                return
            try:
                self._flush(self._next_stamp - self._period_ns)
            except _STORAGE_ERRORS as err:
                raise self._failed(err) from err

    def _flush(self, stamp_ns: int) -> None:
        storage = self._writer.storage
        if isinstance(storage, McapWriter):
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()
        elif isinstance(storage, Sqlite3Writer):
            storage.conn.commit()
        self._pending = False
        self._next_stamp = stamp_ns + self._period_ns
        self._next_wall = time.monotonic_ns() + self._period_ns

    def _failed(self, err: BaseException) -> BagWriteError:
        """After a storage error: close what can be closed, take no more messages."""
        self._open = False
        self.error = BagWriteError(
            f"cannot write to bag {str(self.path)!r}: {err}; recording stopped, the bag is "
            "incomplete (jsc recover BAG rewrites what reached the disk)"
        )
        try:  # the summary and metadata.yaml, if the disk takes them after all
            self._writer.close()
        except _STORAGE_ERRORS:
            with suppress(*_STORAGE_ERRORS):
                self._writer.abort()
        return self.error

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    def close(self) -> None:
        """Finish the storage file and write ``metadata.yaml`` (safe to call twice).

        Raises:
            BagWriteError: the storage failed to write the rest (the bag is incomplete).
        """
        with self._lock:
            if self._open:
                self._open = False
                try:
                    self._writer.close()
                except _STORAGE_ERRORS as err:
                    self._open = True  # let _failed() abort what is still open
                    raise self._failed(err) from err

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
