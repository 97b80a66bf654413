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
- :meth:`BagWriter.close` is idempotent and writes the storage summary and
  ``metadata.yaml``.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (Jazzy's).
BAG_VERSION = 9
#: Padding a CDR reader accepts after the last field (alignment of the next message).
_CDR_SLACK = 3


def jazzy_typestore() -> Typestore:
    """The message definitions of ROS 2 Jazzy (rcl_interfaces, std_msgs, sensor_msgs, …)."""
    return get_typestore(Stores.ROS2_JAZZY)


class CdrFraming:
    """Cuts a serialized message to the length its fields actually use.

    rclpy (Fast CDR) reserves 4 bytes of alignment for every *empty* sequence of 8-byte
    values and sends them as trailing bytes: a JointState with empty velocity and effort
    arrives 8 bytes longer than its content. ``ros2 bag`` copes, but rosbags and other
    strict readers reject the message ("CDR message size mismatch"). Parsing the message
    with the typestore's deserializer gives the true end of the content.
    """

    def __init__(self, typestore: Typestore, msgtype: str) -> None:
        msgdef = typestore.get_msgdef(msgtype)
        self._typestore = typestore
        self._cls = msgdef.cls
        self._le = msgdef.deserialize_cdr_le
        self._be = msgdef.deserialize_cdr_be
        self.msgtype = msgtype

    def frame(self, raw: bytes) -> bytes:
        """``raw`` without trailing bytes beyond the CDR alignment slack.

        Raises:
            SerdeError: the bytes are not a valid message of this type.
        """
        if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
            raise SerdeError(f"invalid CDR header for {self.msgtype}")
        parse = self._le if raw[1] else self._be
        try:
            _, end = parse(memoryview(raw)[4:], 0, self._cls, self._typestore)
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


class BagWriter:
    """A new rosbag2 bag at ``path`` (which must not exist yet) in ``storage`` format."""

    def __init__(self, path: Path | str, storage: str = "mcap") -> None:
        if storage not in STORAGES:
            raise ValueError(f"unknown storage {storage!r}: use one of {sorted(STORAGES)}")
        self.path = Path(path)
        self.storage = storage
        if self.path.exists():
            raise ValueError(f"output {str(self.path)!r} exists already: choose a new bag path")
        parent = self.path.absolute().parent
        if not parent.is_dir():
            raise ValueError(f"cannot create bag {str(self.path)!r}: {parent} is not a directory")
        self.typestore = jazzy_typestore()
        self._writer = Writer(self.path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        try:
            self._writer.open()
        except (OSError, WriterError) as err:
            raise ValueError(f"cannot create bag {str(self.path)!r}: {err}") from err
        self.topics: dict[str, RecordedTopic] = {}
        self._open = True

    def knows(self, msgtype: str) -> bool:
        """Whether the message definition of ``msgtype`` is known (it can be recorded)."""
        return msgtype in self.typestore.fielddefs

    def add_topic(self, name: str, msgtype: str, offered_qos: Sequence[Qos] = ()) -> RecordedTopic:
        """Register a topic (once); its metadata carries the publishers' offered QoS."""
        if name in self.topics:
            raise ValueError(f"topic {name!r} is already recorded")
        if not self.knows(msgtype):
            raise ValueError(f"no message definition for {msgtype!r} (topic {name!r})")
        connection = self._writer.add_connection(
            name, msgtype, typestore=self.typestore, offered_qos_profiles=list(offered_qos)
        )
        topic = RecordedTopic(name, msgtype, connection, CdrFraming(self.typestore, msgtype))
        self.topics[name] = topic
        return topic

    def write(self, topic: RecordedTopic, stamp_ns: int, raw: bytes) -> bool:
        """Append one serialized message received at ``stamp_ns``. A message that does not
        parse as its type is not written (``False``; counted in ``topic.rejected``)."""
        if not self._open:
            return False
        try:
            data = topic.framing.frame(raw)
        except SerdeError:
            topic.rejected += 1
            return False
        self._writer.write(topic.connection, stamp_ns, data)
        topic.count += 1
        return True

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    def close(self) -> None:
        """Finish the storage file and write ``metadata.yaml`` (safe to call twice)."""
        if self._open:
            self._open = False
            self._writer.close()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
