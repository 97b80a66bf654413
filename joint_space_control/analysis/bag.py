"""rosbag2 bags → numpy arrays per topic (I/O only: no metrics, no plots, no ROS).

A bag is a rosbag2 directory (``metadata.yaml`` + ``.mcap`` or ``.db3`` files), read with
``rosbags`` and the ROS 2 Jazzy type store. Log times (bag timestamps) are the recorder's
receive times [ns]; message stamps are simulation time [s].

- :func:`read_bag`: the messages of some (or all) topics, deserialised, with their log times;
- :func:`read_controller_bag`: only the controller ``…/state`` and ``…/config`` topics, found
  by type and layout, not by name (the fast path of ``jsc analyze``);
- typed converters: :func:`controller_state` (the self-describing state matrix, see README),
  :func:`controller_configs` (the JSON configurations), :func:`joint_states`
  (``sensor_msgs/JointState`` with NaN where a field is absent).

Every problem with the bag itself raises :class:`BagError`, whose message names the path.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

STATE_TYPE = "std_msgs/msg/Float64MultiArray"
CONFIG_TYPE = "std_msgs/msg/String"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
STATE_REQUIRED_FIELDS = ("q_d", "q", "tau")
"""Rows a controller state must carry; the others are optional (the layout names them)."""
PROGRESS_EVERY = 5000
"""Messages between two calls of a ``progress`` callback."""

Progress = Callable[[int, int], None]
"""``progress(messages_done, messages_total)``."""

_TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
_STORAGE_SUFFIXES = (".mcap", ".db3")


class BagError(ValueError):
    """The bag is missing, unreadable, empty, or lacks the topics the analysis needs."""


@dataclass(frozen=True)
class TopicInfo:
    """A topic of the bag: name, message type, message count (from the metadata)."""

    name: str
    msgtype: str
    count: int


@dataclass
class TopicMessages:
    """Deserialised messages of one topic in log-time order; ``log_time`` [ns], int64."""

    topic: str
    msgtype: str
    log_time: np.ndarray
    messages: list


@dataclass
class BagContents:
    """What :func:`read_bag` returns: the bag's description and the topics read."""

    path: Path
    storage: str
    start_ns: int
    end_ns: int
    message_count: int
    topics: dict[str, TopicInfo]
    data: dict[str, TopicMessages] = field(default_factory=dict)
    controllers: list[tuple[str, str | None]] = field(default_factory=list)
    """(state topic, config topic or None) per controller, when read by
    :func:`read_controller_bag`."""

    @property
    def duration(self) -> float:
        """Time from the first to the last message [s] (log time)."""
        return max(self.end_ns - self.start_ns, 0) * 1e-9


@dataclass(frozen=True)
class ControllerState:
    """A controller's ``~/state`` topic as arrays (one entry per message, log-time order).

    - ``stamp`` (N,): stamp [s] (simulation time) of the joint state the controller answered;
    - ``log_time`` (N,): receive time [ns], int64;
    - ``rows``: field name → (N, n_joints) array, in the order of ``joints``;
    - ``skipped``: messages left out because their layout or size differed from the first.
    """

    topic: str
    joints: tuple[str, ...]
    fields: tuple[str, ...]
    stamp: np.ndarray
    log_time: np.ndarray
    rows: dict[str, np.ndarray]
    skipped: int = 0

    @property
    def node(self) -> str:
        """The controller's node name: the topic without its last component."""
        return self.topic.rsplit("/", 1)[0] or "/"

    def __len__(self) -> int:
        return int(self.stamp.size)

    def take(self, index: np.ndarray | slice) -> ControllerState:
        """The samples selected by ``index`` (a slice, index array or boolean mask)."""
        return ControllerState(
            self.topic,
            self.joints,
            self.fields,
            self.stamp[index],
            self.log_time[index],
            {k: v[index] for k, v in self.rows.items()},
            self.skipped,
        )


@dataclass(frozen=True)
class JointStates:
    """A ``sensor_msgs/JointState`` topic as arrays, joints in ``names`` order.

    ``stamp`` (N,) is the header stamp [s], ``log_time`` (N,) the receive time [ns];
    ``position``, ``velocity``, ``effort`` are (N, n_joints), NaN where a message does not
    carry the field (an empty array) or the joint.
    """

    topic: str
    names: tuple[str, ...]
    stamp: np.ndarray
    log_time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


# --------------------------------------------------------------------------- reading


class BagReader:
    """An open rosbag2 bag: its topics, and the messages of the topics asked for.

    ``with BagReader(path) as bag: bag.read(["/a/state"])``. Opening checks the path, the
    metadata and the storage files and raises :class:`BagError` with the reason.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._reader = _open(self.path)
        try:
            self.topics = {
                name: TopicInfo(name, info.msgtype or "?", int(info.msgcount))
                for name, info in sorted(self._reader.topics.items())
            }
            self.message_count = int(self._reader.message_count)
            self.start_ns = int(self._reader.start_time) if self.message_count else 0
            # rosbags' end_time is one past the last message
            self.end_ns = int(self._reader.end_time) - 1 if self.message_count else 0
            self.storage = _storage_name(self.path)
        except Exception:
            self.close()
            raise

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._reader.is_open:
            self._reader.close()

    def contents(self) -> BagContents:
        """The bag's description, with no topic read yet."""
        return BagContents(
            self.path, self.storage, self.start_ns, self.end_ns, self.message_count, self.topics
        )

    def first(self, topic: str):
        """The first message of ``topic`` (deserialised), or None if it has none."""
        for _, _, msg in self._messages([topic]):
            return msg
        return None

    def messages(self, topics: Sequence[str]) -> Iterator[tuple[str, int, object]]:
        """(topic, log time [ns], deserialised message) of ``topics`` in log-time order, one
        at a time: for bags too long to hold every message at once (see :meth:`read`).

        Raises:
            BagError: a topic is not in the bag, or a message cannot be read.
        """
        if unknown := [t for t in topics if t not in self.topics]:
            raise BagError(f"{self.path}: no topic {', '.join(unknown)} in the bag")
        return self._messages(topics)

    def read(
        self, topics: Iterable[str] | None = None, progress: Progress | None = None
    ) -> dict[str, TopicMessages]:
        """Deserialise every message of ``topics`` in log-time order (default: every topic
        whose type is a ROS 2 Jazzy standard message; asking for another one is an error).

        ``progress(done, total)`` is called every :data:`PROGRESS_EVERY` messages and at the
        end; ``total`` is the metadata's message count of those topics.
        """
        if topics is None:
            names = [t for t, info in self.topics.items() if info.msgtype in _TYPESTORE.types]
        else:
            names = list(dict.fromkeys(topics))
        if unknown := [t for t in names if t not in self.topics]:
            raise BagError(
                f"{self.path}: no topic {', '.join(unknown)} in the bag "
                f"(topics: {', '.join(self.topics) or 'none'})"
            )
        for name in names:
            if self.topics[name].msgtype not in _TYPESTORE.types:
                raise BagError(
                    f"{self.path}: topic {name} has type {self.topics[name].msgtype}, "
                    "which is not a ROS 2 Jazzy standard message"
                )
        total = sum(self.topics[t].count for t in names)
        logs: dict[str, list[int]] = {t: [] for t in names}
        msgs: dict[str, list] = {t: [] for t in names}
        done = 0
        for topic, log, msg in self._messages(names):
            logs[topic].append(log)
            msgs[topic].append(msg)
            done += 1
            if progress is not None and done % PROGRESS_EVERY == 0:
                progress(done, total)
        if progress is not None:
            progress(done, max(total, done))
        return {
            t: TopicMessages(
                t, self.topics[t].msgtype, np.asarray(logs[t], dtype=np.int64), msgs[t]
            )
            for t in names
        }

    def controller_topics(self) -> list[tuple[str, str | None]]:
        """(state topic, config topic or None) of every controller in the bag.

        A state topic is a ``Float64MultiArray`` topic whose first message has the controller
        state layout (:func:`state_layout`); its config topic is ``<node>/config`` when that
        exists with type ``std_msgs/String``.
        """
        found = []
        for name, info in self.topics.items():
            if info.msgtype != STATE_TYPE or info.count == 0:
                continue
            first = self.first(name)
            if first is None or state_layout(first) is None:
                continue
            config = name.rsplit("/", 1)[0] + "/config"
            has_config = self.topics.get(config, TopicInfo(config, "", 0)).msgtype == CONFIG_TYPE
            found.append((name, config if has_config else None))
        return found

    def _messages(self, topics: Sequence[str]) -> Iterator[tuple[str, int, object]]:
        """(topic, log time [ns], deserialised message) of ``topics``, in log-time order."""
        wanted = set(topics)
        connections = [c for c in self._reader.connections if c.topic in wanted]
        deserialize = _TYPESTORE.deserialize_cdr
        try:
            for conn, log, raw in self._reader.messages(connections=connections):
                yield conn.topic, log, deserialize(raw, conn.msgtype)
        except Exception as err:  # rosbags, and the storage back ends' own (apsw, struct, ...)
            raise BagError(
                f"{self.path}: cannot read {', '.join(topics)}: {_reason(err)}"
            ) from err


def _reason(err: BaseException) -> str:
    """An exception from rosbags or a storage back end as one line (YAML errors span four)."""
    text = " ".join(str(err).split())
    return text if text else type(err).__name__


def _storage_name(path: Path) -> str:
    suffixes = {p.suffix for p in path.iterdir()}
    return "mcap" if ".mcap" in suffixes else "sqlite3" if ".db3" in suffixes else "?"


def _open(path: Path) -> Reader:
    if not path.exists():
        raise BagError(f"{path}: no such file or directory")
    if not path.is_dir():
        hint = (
            f"; pass the bag directory {path.parent}"
            if path.suffix in _STORAGE_SUFFIXES and (path.parent / "metadata.yaml").exists()
            else ""
        )
        raise BagError(
            f"{path}: not a rosbag2 directory (expected a directory with metadata.yaml "
            f"and .mcap or .db3 files){hint}"
        )
    if not (path / "metadata.yaml").is_file():
        storage = sorted(p.name for p in path.iterdir() if p.suffix in _STORAGE_SUFFIXES)
        hint = (
            f" but has {', '.join(storage)} (if the recording was killed, "
            f"`ros2 bag reindex {path}` rebuilds the metadata)"
            if storage
            else ""
        )
        raise BagError(f"{path}: not a rosbag2 directory: no metadata.yaml{hint}")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as err:  # rosbags, and the storage back ends' own (apsw, struct, ...)
        raise BagError(f"{path}: unreadable rosbag2 bag: {_reason(err)}") from err
    return reader


def read_bag(
    path: str | Path, topics: Iterable[str] | None = None, progress: Progress | None = None
) -> BagContents:
    """Open the bag at ``path`` and deserialise the messages of ``topics`` (default: all
    topics of standard message types, see :meth:`BagReader.read`).

    Raises:
        BagError: path missing, not a rosbag2 directory, unreadable metadata or storage, no
            messages at all, or a requested topic not in the bag.
    """
    with BagReader(path) as bag:
        _require_messages(bag)
        contents = bag.contents()
        contents.data = bag.read(topics, progress)
    return contents


def read_controller_bag(path: str | Path, progress: Progress | None = None) -> BagContents:
    """Read only the controller state and config topics (see :meth:`BagReader.controller_topics`).

    Raises:
        BagError: as :func:`read_bag`, and when no topic carries a controller state (the
            message lists the topics found and what was expected).
    """
    with BagReader(path) as bag:
        _require_messages(bag)
        pairs = bag.controller_topics()
        if not pairs:
            listing = ", ".join(f"{t.name} ({t.msgtype}, {t.count})" for t in bag.topics.values())
            raise BagError(
                f"{bag.path}: no controller state topic; expected a {STATE_TYPE} topic "
                "(e.g. /pd_gravity_controller/state) whose layout has 2 dims labelled "
                "'<fields>' and '<joints>' with data_offset 1 and fields including "
                f"{','.join(STATE_REQUIRED_FIELDS)}; topics in the bag: {listing or 'none'}"
            )
        contents = bag.contents()
        contents.controllers = pairs
        contents.data = bag.read([t for pair in pairs for t in pair if t is not None], progress)
    return contents


def _require_messages(bag: BagReader) -> None:
    if bag.message_count == 0:
        listing = ", ".join(bag.topics) or "no topics"
        raise BagError(f"{bag.path}: the bag is empty (no messages; {listing})")


# --------------------------------------------------------------------------- converters


def state_layout(msg) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """(fields, joints) of a controller state message, or None if it is not one.

    The layout must have exactly 2 dims, labelled with the comma-separated field names and
    joint names (sizes matching), ``data_offset`` 1, the fields of
    :data:`STATE_REQUIRED_FIELDS`, and ``1 + n_fields·n_joints`` values.
    """
    dims = msg.layout.dim
    if len(dims) != 2 or msg.layout.data_offset != 1:
        return None
    fields = tuple(s.strip() for s in dims[0].label.split(","))
    joints = tuple(s.strip() for s in dims[1].label.split(","))
    if (
        not all(fields)
        or not all(joints)
        or len(set(fields)) != len(fields)
        or len(set(joints)) != len(joints)
        or dims[0].size != len(fields)
        or dims[1].size != len(joints)
        or not set(STATE_REQUIRED_FIELDS) <= set(fields)
        or len(msg.data) != 1 + len(fields) * len(joints)
    ):
        return None
    return fields, joints


def controller_state(messages: TopicMessages) -> ControllerState:
    """The state matrix of a controller ``~/state`` topic (README, "Controller state").

    The first message's layout defines fields and joints; later messages with another
    layout or size are left out and counted in ``skipped``.

    Raises:
        BagError: the topic has no message, or its first message is not a controller state.
    """
    if not messages.messages:
        raise BagError(f"topic {messages.topic} has no message")
    layout = state_layout(messages.messages[0])
    if layout is None:
        raise BagError(f"topic {messages.topic} does not carry a controller state layout")
    fields, joints = layout
    labels = (messages.messages[0].layout.dim[0].label, messages.messages[0].layout.dim[1].label)
    size = 1 + len(fields) * len(joints)
    keep = [
        k
        for k, m in enumerate(messages.messages)
        if len(m.data) == size and (m.layout.dim[0].label, m.layout.dim[1].label) == labels
    ]
    data = np.stack([messages.messages[k].data for k in keep]).astype(float, copy=False)
    matrix = data[:, 1:].reshape(len(keep), len(fields), len(joints))
    return ControllerState(
        topic=messages.topic,
        joints=joints,
        fields=fields,
        stamp=np.ascontiguousarray(data[:, 0]),
        log_time=messages.log_time[keep],
        rows={f: np.ascontiguousarray(matrix[:, i, :]) for i, f in enumerate(fields)},
        skipped=len(messages.messages) - len(keep),
    )


def controller_configs(
    messages: TopicMessages, warnings: list[str] | None = None
) -> list[tuple[int, dict]]:
    """(log time [ns], configuration) of each message of a controller ``~/config`` topic.

    A message that is not a JSON object is left out, with a line added to ``warnings``.
    """
    out = []
    for log, msg in zip(messages.log_time.tolist(), messages.messages, strict=True):
        try:
            config = json.loads(msg.data)
        except ValueError as err:
            config, reason = None, f"invalid JSON ({err})"
        else:
            reason = "not a JSON object"
        if isinstance(config, dict):
            out.append((int(log), config))
        elif warnings is not None:
            warnings.append(
                f"{messages.topic}: ignored a configuration at log time {log}: {reason}"
            )
    return out


def joint_states(messages: TopicMessages) -> JointStates:
    """A ``sensor_msgs/JointState`` topic as arrays; absent values are NaN.

    The joints are the union of the names, in order of first appearance; a message may list
    them in any order, and leave ``position``, ``velocity`` or ``effort`` empty.
    """
    msgs = messages.messages
    names: dict[str, int] = {}
    for m in msgs:
        for name in m.name:
            names.setdefault(name, len(names))
    n, size = len(msgs), len(names)
    arrays = {key: np.full((n, size), np.nan) for key in ("position", "velocity", "effort")}
    stamp = np.empty(n)
    for k, m in enumerate(msgs):
        stamp[k] = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
        cols = [names[name] for name in m.name]
        for key, out in arrays.items():
            values = getattr(m, key)
            if len(values) == len(cols) and len(cols):
                out[k, cols] = values
    return JointStates(
        topic=messages.topic,
        names=tuple(names),
        stamp=stamp,
        log_time=messages.log_time,
        **arrays,
    )
