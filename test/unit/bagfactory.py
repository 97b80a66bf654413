"""Synthetic rosbag2 bags with the recorder's content, written with rosbags (no ROS graph).

:class:`BagBuilder` writes the topics the recorder writes: controller ``<node>/state``
(``std_msgs/Float64MultiArray``, the self-describing layout of the README), ``<node>/config``
(``std_msgs/String``, JSON), ``sensor_msgs/JointState``, ``rosgraph_msgs/Clock``.
:func:`second_order_state` builds the state rows of an ideal inverse-dynamics loop, whose
per-joint error follows ë + K_D ė + K_P e = 0 exactly.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from joint_space_control.analysis.metrics import second_order_step

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STATE_TYPE = "std_msgs/msg/Float64MultiArray"
STRING_TYPE = "std_msgs/msg/String"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
STATE_FIELDS = (
    "q_d",
    "dq_d",
    "ddq_d",
    "q",
    "dq",
    "error",
    "derror",
    "tau_feedback",
    "tau_model",
    "tau_gravity",
    "tau_unclamped",
    "tau",
)
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}

_T = TYPESTORE.types
_F64 = _T[STATE_TYPE]
_LAYOUT = _T["std_msgs/msg/MultiArrayLayout"]
_DIM = _T["std_msgs/msg/MultiArrayDimension"]


def _time(seconds: float):
    ns = round(seconds * 1e9)
    return _T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


class BagBuilder:
    """Writes messages topic by topic; a topic's connection is created on first use.

    Use as a context manager; ``log`` times are the bag timestamps [ns].
    """

    def __init__(self, path: Path, storage: str = "mcap") -> None:
        self._writer = Writer(path, version=9, storage_plugin=STORAGES[storage])
        self._connections: dict[str, object] = {}

    def __enter__(self) -> BagBuilder:
        self._writer.open()
        return self

    def __exit__(self, *exc) -> None:
        self._writer.close()

    def connect(self, topic: str, msgtype: str):
        if topic not in self._connections:
            self._connections[topic] = self._writer.add_connection(
                topic, msgtype, typestore=TYPESTORE
            )
        return self._connections[topic]

    def write(self, topic: str, msgtype: str, log: int, msg) -> None:
        conn = self.connect(topic, msgtype)
        self._writer.write(conn, int(log), TYPESTORE.serialize_cdr(msg, msgtype))

    def state(
        self,
        topic: str,
        log: int,
        stamp: float,
        matrix: np.ndarray,
        joints: Sequence[str],
        fields: Sequence[str] = STATE_FIELDS,
        data_offset: int = 1,
    ) -> None:
        """One controller state: ``matrix`` is (n_fields, n_joints)."""
        n = len(joints)
        layout = _LAYOUT(
            dim=[
                _DIM(label=",".join(fields), size=len(fields), stride=len(fields) * n),
                _DIM(label=",".join(joints), size=n, stride=n),
            ],
            data_offset=data_offset,
        )
        data = np.concatenate(([stamp], np.asarray(matrix, dtype=float).reshape(-1)))
        self.write(topic, STATE_TYPE, log, _F64(layout=layout, data=data))

    def states(
        self,
        topic: str,
        logs: Sequence[int],
        stamps: Sequence[float],
        rows: dict[str, np.ndarray],
        joints: Sequence[str],
    ) -> None:
        """A state per stamp; ``rows`` maps field → (N, n_joints), in STATE_FIELDS order."""
        fields = [f for f in STATE_FIELDS if f in rows]
        block = np.stack([rows[f] for f in fields], axis=1)  # (N, n_fields, n_joints)
        for log, stamp, matrix in zip(logs, stamps, block, strict=True):
            self.state(topic, log, float(stamp), matrix, joints, fields)

    def config(self, topic: str, log: int, config: dict) -> None:
        self.write(topic, STRING_TYPE, log, _T[STRING_TYPE](data=json.dumps(config)))

    def joint_state(
        self,
        topic: str,
        log: int,
        stamp: float,
        names: Sequence[str],
        position: Sequence[float] = (),
        velocity: Sequence[float] = (),
        effort: Sequence[float] = (),
    ) -> None:
        header = _T["std_msgs/msg/Header"](stamp=_time(stamp), frame_id="")
        msg = _T[JOINT_STATE_TYPE](
            header=header,
            name=list(names),
            position=np.asarray(position, dtype=float),
            velocity=np.asarray(velocity, dtype=float),
            effort=np.asarray(effort, dtype=float),
        )
        self.write(topic, JOINT_STATE_TYPE, log, msg)

    def clock(self, log: int, stamp: float) -> None:
        self.write("/clock", CLOCK_TYPE, log, _T[CLOCK_TYPE](clock=_time(stamp)))


def second_order_state(
    t: np.ndarray,
    y0: Sequence[float],
    y1: Sequence[float],
    omega_n: Sequence[float],
    zeta: Sequence[float],
    t_step: float | Sequence[float] = 0.0,
) -> dict[str, np.ndarray]:
    """State rows (N, n_joints) of an ideal inverse-dynamics loop stepping from y0 to y1.

    Joint j follows the analytic second-order step response from y0[j] to y1[j] at
    ``t_step`` (one instant, or one per joint), q_d = y0[j] before it and y1[j] from it on;
    τ is a plausible stand-in (K_P e − K_D q̇ split into feedback, model and gravity parts).
    """
    t = np.asarray(t, dtype=float)
    n = len(y0)
    steps = np.broadcast_to(np.asarray(t_step, dtype=float), (n,))
    q = np.column_stack(
        [second_order_step(t - steps[j], omega_n[j], zeta[j], y0[j], y1[j]) for j in range(n)]
    )
    q_d = np.where(t[:, None] >= steps, np.asarray(y1, float), np.asarray(y0, float))
    dq = np.gradient(q, t, axis=0)
    kp = np.asarray(omega_n, float) ** 2
    kd = 2.0 * np.asarray(zeta, float) * np.asarray(omega_n, float)
    error = q_d - q
    feedback = kp * error - kd * dq
    gravity = np.full_like(q, 1.5)
    model = 0.1 * feedback
    tau = feedback + model + gravity
    zero = np.zeros_like(q)
    return {
        "q_d": q_d,
        "dq_d": zero,
        "ddq_d": zero,
        "q": q,
        "dq": dq,
        "error": error,
        "derror": -dq,
        "tau_feedback": feedback,
        "tau_model": model,
        "tau_gravity": gravity,
        "tau_unclamped": tau,
        "tau": tau,
    }


def config(
    node: str = "/inverse_dynamics_controller",
    law: str = "inverse_dynamics",
    joints: Sequence[str] = ("joint1", "joint2"),
    kp: Sequence[float] = (100.0, 400.0),
    kd: Sequence[float] = (10.0, 32.0),
    effort_limits: Sequence[float] = (50.0, 30.0),
    robot: str = "planar_2dof",
) -> dict:
    """A controller configuration as the recorder's ``<node>/config`` carries it."""
    return {
        "node": node,
        "executable": node.rsplit("/", 1)[-1],
        "law": law,
        "robot": robot,
        "joints": list(joints),
        "rate": 1000.0,
        "effort_limits": list(effort_limits),
        "position_limits": [[-3.0, 3.0] for _ in joints],
        "kp": list(kp),
        "kd": list(kd),
        "parameters": {"robot": robot, "kp": list(kp), "kd": list(kd), "use_sim_time": True},
    }
