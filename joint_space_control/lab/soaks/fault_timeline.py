"""The bags of a fault soak → one :class:`.fault_metrics.Timeline` (I/O only: no metrics).

A fault soak leaves one bag per recorder incarnation: a killed recorder restarts into a new
bag directory, and the bag it was writing has no ``metadata.yaml`` and a cut MCAP file. Such
a bag is first rewritten by :func:`joint_space_control.recording.recover.recover` (what
``jsc recover`` does) and its recovered copy is read; the :class:`.fault_metrics.BagSpan` of
each bag says which.

The messages are converted one at a time (an hour at 1 kHz is millions of them): of the
controller's ``~/state`` only the receive time and the tracking error e = maxⱼ |q_d − q| are
kept, of ``/joint_states`` the receive time, the header stamp [ns], q and the applied effort.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from joint_space_control.analysis.bag import BagError, BagReader, state_layout
from joint_space_control.lab.soaks.fault_metrics import BagSpan, Timeline
from joint_space_control.lab.soaks.loop_digest import LoopSample, sample
from joint_space_control.recording.recover import RecoveryError, recover

#: The ``header.frame_id`` of the plant's joint states (sim_bridge leaves it empty).
PLANT_FRAME = ""
#: Suffix of the recovered copy of a bag (``recover``'s default, next to the bag).
RECOVERED_SUFFIX = "_recovered"


def read_timeline(
    bags: Sequence[str | Path],
    state_topic: str,
    joint_states_topic: str = "/joint_states",
    diagnostics_topic: str = "/diagnostics",
    recovered_dir: str | Path | None = None,
    log: Callable[[str], None] | None = None,
) -> Timeline:
    """The run recorded in ``bags`` (bag directories in recording order) as one timeline.

    ``state_topic``: the controller's state topic, e.g. ``/inverse_dynamics_controller/state``.
    A bag without ``metadata.yaml`` is recovered into ``<recovered_dir or its
    folder>/<name>_recovered`` (an existing complete copy there is read as it is). A bag that
    can be neither read nor recovered is listed with status ``unreadable`` and left out; a
    bag without one of the topics contributes no rows of it. The joints are those of the
    first joint state; later bags are matched to them by name. The nodes' ``/diagnostics``,
    where recorded, become the timeline's ``loops``.
    """
    spans: list[BagSpan] = []
    states: list[_StateRows] = []
    plants: list[_JointRows] = []
    loops: list[LoopSample] = []
    for path in map(Path, bags):
        read, status, detail = _readable(path, recovered_dir)
        state, plant = _StateRows(state_topic), _JointRows()
        if read is not None:
            try:
                with BagReader(read) as bag:
                    wanted = (state_topic, joint_states_topic, diagnostics_topic)
                    topics = [t for t in wanted if t in bag.topics]
                    for topic, log_ns, msg in bag.messages(topics):
                        if topic == diagnostics_topic:
                            loops.extend(_loop_samples(log_ns, msg))
                        else:
                            (state if topic == state_topic else plant).add(log_ns, msg)
            except BagError as err:
                read, status, detail = None, "unreadable", str(err)
                state, plant = _StateRows(state_topic), _JointRows()
        first = min((r.first for r in (state, plant) if r.count), default=math.nan)
        last = max((r.last for r in (state, plant) if r.count), default=math.nan)
        spans.append(BagSpan(path, read, status, detail, first, last, state.count, plant.count))
        states.append(state)
        plants.append(plant)
        if log is not None:
            log(f"{path}: {status}, {state.count} states, {plant.count} joint states")
    joints = next((p.names for p in plants if p.count), ())
    blocks = [p.arrays(joints) for p in plants]
    n = len(joints)
    return Timeline(
        joints=joints,
        state_wall=_cat([s.wall() for s in states], float),
        error=_cat([np.asarray(s.error, dtype=float) for s in states], float),
        js_wall=_cat([b[0] for b in blocks], float),
        js_stamp_ns=_cat([b[1] for b in blocks], np.int64),
        position=np.concatenate([b[2] for b in blocks]) if blocks else np.empty((0, n)),
        effort=np.concatenate([b[3] for b in blocks]) if blocks else np.empty((0, n)),
        js_bag=_cat([np.full(p.count, k, dtype=np.int64) for k, p in enumerate(plants)], int),
        bags=tuple(spans),
        loops=tuple(loops),
    )


def _loop_samples(log_ns: int, msg) -> list[LoopSample]:
    """The statuses of one DiagnosticArray, received at ``log_ns``."""
    return [
        sample(
            log_ns * 1e-9,
            status.name,
            int.from_bytes(status.level, "little")
            if isinstance(status.level, bytes)
            else int(status.level),
            status.message,
            {kv.key: kv.value for kv in status.values},
        )
        for status in msg.status
    ]


def _readable(path: Path, recovered_dir: str | Path | None) -> tuple[Path | None, str, str]:
    """(bag to read or None, status, detail) of the bag directory ``path``."""
    if (path / "metadata.yaml").is_file():
        return path, "complete", ""
    out = Path(recovered_dir or path.parent) / (path.name + RECOVERED_SUFFIX)
    if (out / "metadata.yaml").is_file():
        return out, "recovered", f"recovered copy {out} read"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        result = recover(path, out)
    except (RecoveryError, OSError) as err:
        return None, "unreadable", str(err)
    return out, "recovered", f"recovered into {out}: {result.stopped}"


def _cat(parts: list[np.ndarray], dtype) -> np.ndarray:
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.empty(0, dtype)


class _Rows:
    """What one bag gave of a topic: the receive times [ns] of the messages kept."""

    def __init__(self) -> None:
        self.log: list[int] = []

    @property
    def count(self) -> int:
        return len(self.log)

    @property
    def first(self) -> float:
        return self.log[0] * 1e-9

    @property
    def last(self) -> float:
        return self.log[-1] * 1e-9


class _StateRows(_Rows):
    """Receive times and tracking errors of a controller's state messages (one bag)."""

    def __init__(self, topic: str) -> None:
        super().__init__()
        self.topic = topic
        self.error: list[float] = []
        self.skipped = 0
        self._labels: tuple[str, str] | None = None

    def add(self, log_ns: int, msg) -> None:
        dims = msg.layout.dim
        if self._labels is None:
            layout = state_layout(msg)
            if layout is None:
                self.skipped += 1
                return
            fields, joints = layout
            n = len(joints)
            self._labels = (dims[0].label, dims[1].label)
            self._size = 1 + len(fields) * n
            self._qd = slice(1 + fields.index("q_d") * n, 1 + (fields.index("q_d") + 1) * n)
            self._q = slice(1 + fields.index("q") * n, 1 + (fields.index("q") + 1) * n)
        data = msg.data
        if len(data) != self._size or (dims[0].label, dims[1].label) != self._labels:
            self.skipped += 1
            return
        self.log.append(log_ns)
        self.error.append(float(np.max(np.abs(data[self._qd] - data[self._q]))))

    def wall(self) -> np.ndarray:
        return np.asarray(self.log, dtype=np.int64) * 1e-9


class _JointRows(_Rows):
    """Receive times, stamps, positions and efforts of the plant's joint state messages (one
    bag): those with the plant's ``header.frame_id`` (sim_bridge's: ""), not what another
    node published on the topic (the soak's malformed ones, say)."""

    def __init__(self, frame_id: str = PLANT_FRAME) -> None:
        super().__init__()
        self.frame_id = frame_id
        self.others = 0  # messages of other publishers, left out
        self.names: tuple[str, ...] = ()
        self.stamp: list[int] = []
        self.position: list[np.ndarray] = []
        self.effort: list[np.ndarray] = []

    def add(self, log_ns: int, msg) -> None:
        if msg.header.frame_id != self.frame_id:
            self.others += 1
            return
        if not self.names:
            self.names = tuple(msg.name)
            self._col = {j: k for k, j in enumerate(self.names)}
        n = len(self.names)
        names = tuple(msg.name)
        # columns of this message's values; a joint not in the first message goes to slot n
        order = slice(0, n) if names == self.names else [self._col.get(j, n) for j in names]
        self.log.append(log_ns)
        self.stamp.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        for values, out in ((msg.position, self.position), (msg.effort, self.effort)):
            row = np.full(n + 1, np.nan)
            if len(values) == len(names):
                row[order] = values
            out.append(row[:n])

    def arrays(
        self, joints: tuple[str, ...]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(wall [s], stamp [ns], position, effort), columns in ``joints`` order."""
        n = len(joints)
        if not self.count:
            return np.empty(0), np.empty(0, np.int64), np.empty((0, n)), np.empty((0, n))
        position, effort = np.array(self.position), np.array(self.effort)
        if self.names != joints:
            cols = [self.names.index(j) if j in self.names else -1 for j in joints]
            pad = np.full((self.count, 1), np.nan)
            position = np.hstack((position, pad))[:, cols]
            effort = np.hstack((effort, pad))[:, cols]
        return (
            np.asarray(self.log, dtype=np.int64) * 1e-9,
            np.asarray(self.stamp, dtype=np.int64),
            position,
            effort,
        )
