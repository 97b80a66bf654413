"""Message ↔ array conversion and validation at the node boundary (shared STYLE.md §3).

Every function here either returns arrays in the controlled-joint order or raises
``ValueError`` with a reason that the node logs (throttled) before dropping the message.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration, Time
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.control.controller import STATE_FIELDS  # noqa: F401  (re-exported)
from joint_space_control.json_values import jsonable
from joint_space_control.trajectories.reference import Trajectory, checked_trajectory

#: Control topics: the newest sample is the only one that matters; reliable so that a
#: lockstep exchange never loses the one message it waits for.
CONTROL_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: A controller's joint states behind a plant known to run in realtime: only the newest
#: matters, and a reliable reader that fell seconds behind (a stalled or starved process) is
#: handed what it missed in order and slowly: measured, a reader stopped for 6 s then took
#: ~10 states a second, 5-10 s old, for good. Best effort, as sensor data is: the newest
#: state, at once.
REALTIME_STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
#: The plant's command subscriptions: every command received is judged (a foreign or broken
#: one is counted, docs/safety.md), so none may be overwritten in the queue by the next one
#: before the plant takes it; the newest valid command is the one held.
COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=16,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: ros2_control's forward command controller subscribes ``~/commands`` with the system
#: default QoS (reliable, keep last 10); a controller's ``forward_command`` publisher matches
#: it, and sim_bridge's ``interface: ros2_control`` subscribes as it does.
FORWARD_COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: Publishers of the control topics (joint states, /clock, commands, controller state):
#: reliable like :data:`CONTROL_QOS`, but the writer keeps its last 1000 samples. The loop
#: itself only ever wants the newest; an observer that falls behind a loop running faster
#: than real time (recorder, test probe; a starved process on a loaded machine) asks for
#: the samples it missed again, and with a writer history of one they would be gone.
CONTROL_PUBLISHER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
#: References: a few may be queued so that none is lost while a tick runs.
REFERENCE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

#: Controller configuration (``~/config``): latched, so that a recorder or a tool that starts
#: later still receives the configuration in force.
CONFIG_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def config_message(description: dict[str, Any]) -> String:
    """``~/config``: the controller's configuration as one JSON object (README, "Controller
    configuration"); non-finite numbers (absent limits) become ``null``."""
    return String(data=json.dumps(jsonable(description), allow_nan=False))


def reference_message(
    joints: Sequence[str],
    positions: Sequence[Sequence[float]],
    times: Sequence[float] = (0.0,),
    start_ns: int = 0,
    velocities: Sequence[Sequence[float]] | None = None,
    accelerations: Sequence[Sequence[float]] | None = None,
) -> JointTrajectory:
    """A reference as the experiments send it: points at ``times`` [s] after ``start_ns``
    (0: when the controller takes it), velocities and accelerations where given."""
    msg = JointTrajectory(joint_names=list(joints))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(start_ns, 1_000_000_000)
    for k, (t, pos) in enumerate(zip(times, positions, strict=True)):
        sec, nsec = divmod(round(t * 1e9), 1_000_000_000)
        point = JointTrajectoryPoint(
            positions=[float(p) for p in pos], time_from_start=Duration(sec=sec, nanosec=nsec)
        )
        if velocities is not None:
            point.velocities = [float(v) for v in velocities[k]]
        if accelerations is not None:
            point.accelerations = [float(a) for a in accelerations[k]]
        msg.points.append(point)
    return msg


def stamp_to_ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def ns_to_stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class JointOrder:
    """Maps the joint names of incoming messages to the controlled-joint order.

    The permutation is cached for the last name list seen (per ``allow_extra``), so steady
    traffic costs one tuple comparison per message.
    """

    def __init__(self, joints: Sequence[str]) -> None:
        self.joints = tuple(joints)
        self._known = set(self.joints)
        self._cache: dict[bool, tuple[tuple[str, ...], np.ndarray]] = {}

    def index(self, names: Sequence[str], allow_extra: bool) -> np.ndarray:
        """Position in ``names`` of each controlled joint. Raises for a missing or duplicated
        joint, and for a name that is not controlled unless ``allow_extra``."""
        names = tuple(names)
        cached = self._cache.get(allow_extra)
        if cached is not None and cached[0] == names:
            return cached[1]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicated joint names {list(names)}")
        missing = [j for j in self.joints if j not in names]
        if missing:
            raise ValueError(f"missing joints {missing}")
        if not allow_extra:
            unknown = [name for name in names if name not in self._known]
            if unknown:
                raise ValueError(f"unknown joints {unknown}")
        lookup = {name: i for i, name in enumerate(names)}
        index = np.array([lookup[j] for j in self.joints])
        self._cache[allow_extra] = (names, index)
        return index


def _field(values: Sequence[float], size: int, what: str) -> np.ndarray:
    if len(values) != size:
        raise ValueError(f"{len(values)} {what} values for {size} names")
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"non-finite {what}")
    return arr


def joint_state_arrays(msg: JointState, order: JointOrder) -> tuple[np.ndarray, np.ndarray]:
    """(q, q̇) of the controlled joints; other joints in the message are ignored. An empty
    velocity array is well formed (velocity not measured): q̇ is then empty."""
    idx = order.index(msg.name, allow_extra=True)
    size = len(msg.name)
    q = _field(msg.position, size, "position")[idx]
    if not len(msg.velocity):
        return q, np.empty(0)
    dq = _field(msg.velocity, size, "velocity")[idx]
    return q, dq


def effort_arrays(msg: JointState, order: JointOrder) -> np.ndarray:
    """Effort command of every controlled joint; unknown names are an error."""
    idx = order.index(msg.name, allow_extra=False)
    return _field(msg.effort, len(msg.name), "effort")[idx]


def float_array(msg: Float64MultiArray, size: int) -> np.ndarray:
    """A ros2_control-style command: exactly ``size`` finite values in joint order."""
    return _field(msg.data, size, "command")


#: The largest reference a controller takes (rejected with the reason beyond): points,
#: duration of its last point from its start [s], and its serialized size [bytes].
MAX_REFERENCE_POINTS = 200_000
MAX_REFERENCE_DURATION = 86_400.0
MAX_REFERENCE_BYTES = 64 * 1024 * 1024


#: The arrays of a trajectory point and what an error calls them.
_POINT_FIELDS = {
    "positions": "position",
    "velocities": "velocity",
    "accelerations": "acceleration",
}
_TYPESTORE = None
_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


def _typestore():
    global _TYPESTORE
    if _TYPESTORE is None:
        from rosbags.typesys import Stores, get_typestore

        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def prepare_reference_reader() -> None:
    """Build rosbags' JointTrajectory reader now (it generates and compiles code the first
    time, holding the interpreter for tens of milliseconds): at start, not while the
    control loop runs."""
    _typestore().deserialize_cdr(serialize_message(JointTrajectory()), _TRAJECTORY)


def trajectory_from_bytes(
    raw: bytes,
    order: JointOrder,
    now: float,
    origin_ns: int,
    position_limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> Trajectory:
    """:func:`trajectory_from_msg` of a serialized JointTrajectory, read by rosbags'
    deserializer (Python: it lets other threads run while it reads 100,000 points, which
    rclpy's C++ one does not for tens of milliseconds). ``ValueError`` for bytes that are
    no JointTrajectory, or larger than MAX_REFERENCE_BYTES."""
    if len(raw) > MAX_REFERENCE_BYTES:
        raise ValueError(f"message of {len(raw)} bytes; at most {MAX_REFERENCE_BYTES} (split it)")
    if len(raw) < 4 or bytes(raw[:2]) not in (b"\x00\x00", b"\x00\x01"):
        raise ValueError(f"not a serialized JointTrajectory ({len(raw)} bytes): no CDR header")
    # rosbags' reader without its exact-length check (deserialize_cdr), which refuses the
    # trailing bytes that rmw_serialize leaves (rclpy's serialize_message) and rclpy accepts
    store = _typestore()
    msgdef = store.get_msgdef(_TRAJECTORY)
    read = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    try:
        msg, _ = read(memoryview(raw)[4:], 0, msgdef.cls, store)
    except Exception as err:  # noqa: BLE001 - struct.error, ValueError, UnicodeDecodeError...
        raise ValueError(f"not a serialized JointTrajectory ({len(raw)} bytes): {err}") from None
    return trajectory_from_msg(msg, order, now, origin_ns, position_limits)


def trajectory_from_msg(
    msg: JointTrajectory,
    order: JointOrder,
    now: float,
    origin_ns: int,
    position_limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> Trajectory:
    """Validate a JointTrajectory for the controlled joints.

    ``header.stamp`` is the start time in the controller's clock (zero means ``now``);
    times are returned in seconds after ``origin_ns``, the controller's time origin. Every
    controlled joint must be present, no unknown or duplicated names; positions are required
    on every point, velocities and accelerations are optional but, when given, complete.
    Rejected as well: more than MAX_REFERENCE_POINTS points or a last point later than
    MAX_REFERENCE_DURATION, a trajectory whose last point lies before ``now`` (it ended already),
    and points outside ``position_limits`` (lower, upper; set-points are rejected, not
    clamped: a clamped set-point is a different motion than the one asked for).
    """
    if not msg.points:
        raise ValueError("trajectory has no points")
    if len(msg.points) > MAX_REFERENCE_POINTS:
        raise ValueError(
            f"trajectory has {len(msg.points)} points; at most {MAX_REFERENCE_POINTS} (split it)"
        )
    last = msg.points[-1].time_from_start
    if last.sec + 1e-9 * last.nanosec > MAX_REFERENCE_DURATION:
        raise ValueError(
            f"trajectory lasts {last.sec + 1e-9 * last.nanosec:g} s; at most "
            f"{MAX_REFERENCE_DURATION:g} s"
        )
    idx = order.index(msg.joint_names, allow_extra=False)
    size = len(msg.joint_names)
    # one pass over the points filling preallocated arrays, the checks vectorized after it:
    # no per-point arrays, no conversion of 100,000 rows in one call (the reference worker
    # then lets the control loop run between its steps)
    count = len(msg.points)
    times_ns = np.empty(count, dtype=np.int64)
    times = np.empty(count)
    arrays = {name: np.empty((count, size)) for name in _POINT_FIELDS}
    given = {name: np.zeros(count, dtype=bool) for name in _POINT_FIELDS}
    for k, point in enumerate(msg.points):
        d = point.time_from_start
        times_ns[k] = d.sec * 1_000_000_000 + d.nanosec
        times[k] = d.sec + 1e-9 * d.nanosec
        for name, what in _POINT_FIELDS.items():
            values = getattr(point, name)
            if len(values) or name == "positions":
                if len(values) != size:
                    raise ValueError(f"{len(values)} point {k} {what} values for {size} names")
                arrays[name][k] = values
                given[name][k] = True
    for name, what in _POINT_FIELDS.items():
        rows = given[name]
        if not rows.any():
            continue
        if not rows.all():
            raise ValueError(f"{name} given on some points only")
        finite = np.isfinite(arrays[name]).all(axis=1)
        if not finite.all():
            raise ValueError(f"non-finite point {int(np.argmin(finite))} {what}")
    positions = arrays["positions"][:, idx]
    velocities = arrays["velocities"][:, idx] if given["velocities"].any() else None
    accelerations = arrays["accelerations"][:, idx] if given["accelerations"].any() else None
    stamp = stamp_to_ns(msg.header.stamp)
    start = now if stamp == 0 else (stamp - origin_ns) * 1e-9
    return checked_trajectory(
        start,
        times_ns,
        times,
        positions,
        velocities,
        accelerations,
        now,
        position_limits,
        order.joints,
    )


def state_message(joints: Sequence[str]) -> Float64MultiArray:
    """A reusable ``~/state`` message: data[0] is the stamp [s] of the joint state answered,
    then a (field × joint) row-major matrix, rows named by ``layout.dim[0].label``."""
    msg = Float64MultiArray()
    n = len(joints)
    msg.layout.dim = [
        MultiArrayDimension(
            label=",".join(STATE_FIELDS), size=len(STATE_FIELDS), stride=len(STATE_FIELDS) * n
        ),
        MultiArrayDimension(label=",".join(joints), size=n, stride=n),
    ]
    msg.layout.data_offset = 1
    return msg


#: ``~/pause``'s answer names the stamp of the last joint state the plant sent (an observer
#: then waits for that state, not for a quiet spell that a loaded machine can fake).
PAUSED_PREFIX = "paused; last state stamped "


def paused_message(stamp_ns: int | None) -> str:
    """The plant's answer to ``~/pause``: ``paused; last state stamped <ns> ns``."""
    return "paused" if stamp_ns is None else f"{PAUSED_PREFIX}{stamp_ns} ns"


def paused_stamp(message: str) -> int | None:
    """The last state's stamp [ns] in a ``~/pause`` answer (None: none sent, or a plant
    that does not say)."""
    if not message.startswith(PAUSED_PREFIX):
        return None
    try:
        return int(message[len(PAUSED_PREFIX) :].split()[0])
    except (IndexError, ValueError):
        return None
