"""A client node that drives and observes a running loop: waits for the graph, sends
references, calls the simulator's services, sets parameters through the standard parameter
services (what ``ros2 param set`` uses) and collects joint states: of one robot, or of each
robot of a world of several (its topics in its namespace)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.processes.client import STARTUP_TIMEOUT, RosClient
from joint_space_control.ros.control_path import ControlPath
from joint_space_control.ros.diagnostics import DIAGNOSTICS_QOS, statuses
from joint_space_control.ros.messages import (
    CONFIG_QOS,
    REFERENCE_QOS,
    reference_message,
    stamp_to_ns,
)

#: Longest wait [s] for a joint state or command before the probe serves the rest, and how
#: often [s] it serves the rest (services, parameters, diagnostics, the caller's own
#: subscriptions) while joint states keep coming.
OBSERVED_WAIT = 0.005
REST_PERIOD = 0.002
RECORD_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10000, reliability=ReliabilityPolicy.RELIABLE
)


@dataclass
class Recording:
    """Joint states received, in arrival order."""

    stamps: list[int] = field(default_factory=list)
    positions: list[list[float]] = field(default_factory=list)
    velocities: list[list[float]] = field(default_factory=list)
    efforts: list[list[float]] = field(default_factory=list)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t [s], q, q̇, τ), one row per distinct stamp (repeats dropped)."""
        stamps = np.array(self.stamps, dtype=np.int64)
        _, first = np.unique(stamps, return_index=True)
        keep = np.sort(first)
        return (
            stamps[keep] * 1e-9,
            np.array(self.positions)[keep],
            np.array(self.velocities)[keep],
            np.array(self.efforts)[keep],
        )


def in_namespace(namespace: str, topic: str) -> str:
    """``topic`` of the robot in ``namespace`` ("": the relative name, the one robot's)."""
    return f"{namespace}/{topic}" if namespace else topic


class LoopProbe(RosClient):
    """Owns its own rclpy context in the given domain; close() when done.

    ``namespaces``: the robots observed, each by its namespace (the default: the one robot,
    whose topics are in the probe's own namespace). Every robot has its own
    :class:`Recording` (``recordings``; ``recording`` is the first's) and reference."""

    def __init__(
        self, domain_id: int, name: str = "jsc_probe", namespaces: Sequence[str] = ("",)
    ) -> None:
        super().__init__(domain_id, name)
        self.namespaces = tuple(namespaces)
        self.recordings = {ns: Recording() for ns in self.namespaces}
        self.recording = self.recordings[self.namespaces[0]]
        self._rest_due = 0.0
        # The loop's own topics are taken by a dedicated wait-set loop: through the executor
        # (a wait-set rebuild per message) the probe falls behind a lockstep loop that runs
        # faster than real time. One message per topic and wait, as an executor takes them,
        # so that run_until() stops at the first state at or after its time.
        self._observed = ControlPath(self.node)
        self.answered = dict.fromkeys(self.namespaces, -1)  # newest stamp on effort_command
        self.commands = dict.fromkeys(self.namespaces, 0)  # commands received
        # called with (namespace, command) for each command taken: a caller keeping every
        # command reads the probe's own (one deserialization, not a second subscription)
        self.command_listeners: list[Callable[[str, JointState], None]] = []
        self.counted: dict[str, int] = {}  # messages of the topics count() was asked for
        self._ref_pubs = {}
        for ns in self.namespaces:
            self._observed.subscription(
                JointState,
                in_namespace(ns, "joint_states"),
                partial(self._on_state, self.recordings[ns]),
                RECORD_QOS,
            )
            self._observed.subscription(
                JointState,
                in_namespace(ns, "effort_command"),
                partial(self._on_command, ns),
                RECORD_QOS,
            )
            self._ref_pubs[ns] = self.node.create_publisher(
                JointTrajectory, in_namespace(ns, "reference"), REFERENCE_QOS
            )
        self._diagnostics: dict[str, dict[str, float | str]] | None = None
        self._configs: dict[str, dict] = {}  # newest ~/config per controller topic

    def observe(self, msg_type: type, topic: str, callback: Callable[[Any], None]) -> None:
        """Take every message of a high-rate topic (a controller's ``~/state``) through the
        probe's dedicated loop, as the joint states are: through ``self.node``'s executor
        the probe falls behind a loop running faster than real time."""
        self._observed.subscription(
            msg_type, topic, lambda msg, info=None: callback(msg), RECORD_QOS
        )

    def count(self, msg_type: type, topic: str) -> None:
        """Count the messages of a topic in ``counted[topic]``, taken serialized and not
        read (a controller's ``~/state``: how many the recorder must have, at least)."""
        self.counted[topic] = 0

        def on_message(raw: bytes, info: object = None) -> None:
            self.counted[topic] += 1

        self._observed.subscription(msg_type, topic, on_message, RECORD_QOS, raw=True)

    @staticmethod
    def _on_state(rec: Recording, msg: JointState, info: object = None) -> None:
        rec.stamps.append(stamp_to_ns(msg.header.stamp))
        rec.positions.append(list(msg.position))
        rec.velocities.append(list(msg.velocity))
        rec.efforts.append(list(msg.effort))

    def _on_command(self, namespace: str, msg: JointState, info: object = None) -> None:
        self.answered[namespace] = max(self.answered[namespace], stamp_to_ns(msg.header.stamp))
        self.commands[namespace] += 1
        for listener in self.command_listeners:
            listener(namespace, msg)

    # -- spinning ----------------------------------------------------------------------
    def spin_once(self) -> None:
        """The observed topics for at most OBSERVED_WAIT, and every REST_PERIOD everything
        else the executor has ready."""
        self._observed.spin_once(OBSERVED_WAIT)
        now = time.monotonic()
        if now >= self._rest_due:
            self.serve_ready()
            self._rest_due = now + REST_PERIOD

    def latest_time(self) -> float:
        """The newest joint state's time [s] (-1 before the first); with several robots,
        the robot furthest behind's."""
        return min(
            rec.stamps[-1] * 1e-9 if rec.stamps else -1.0 for rec in self.recordings.values()
        )

    def run_until(
        self, t_sim: float, timeout: float, check: Callable[[], None] | None = None
    ) -> None:
        """Spin until a joint state at simulation time ≥ t_sim has arrived."""
        self.spin_until(
            lambda: self.latest_time() >= t_sim - 1e-9,
            timeout,
            f"simulation time {t_sim} s",
            check,
        )

    def wait_for_answer(
        self, stamp_ns: int, timeout: float = 30.0, check: Callable[[], None] | None = None
    ) -> None:
        """Spin until a command answering the joint state stamped ``stamp_ns`` was seen
        (of every robot)."""
        self.spin_until(
            lambda: min(self.answered.values()) >= stamp_ns,
            timeout,
            f"the answer to {stamp_ns} ns",
            check,
        )

    def wait_for_diagnostics(
        self,
        names: Sequence[str],
        until: Callable[[dict[str, dict[str, float | str]]], bool] = lambda latest: True,
        timeout: float = 20.0,
        check: Callable[[], None] | None = None,
    ) -> dict[str, dict[str, float | str]]:
        """Subscribe to /diagnostics (on first use) and spin until a status has arrived for
        every name in ``names`` and ``until(latest)`` holds; returns the newest status of
        each name (:func:`~joint_space_control.ros.diagnostics.statuses`)."""
        if self._diagnostics is None:
            self._diagnostics = {}
            self.node.create_subscription(
                DiagnosticArray,
                "/diagnostics",
                lambda msg: self._diagnostics.update(statuses(msg)),
                DIAGNOSTICS_QOS,
            )
        latest = self._diagnostics
        self.spin_until(
            lambda: all(n in latest for n in names) and until(latest),
            timeout,
            f"diagnostics of {list(names)}",
            check,
        )
        return dict(latest)

    def controller_config(
        self, controller: str, namespace: str = "", check: Callable[[], None] | None = None
    ) -> dict:
        """The newest ``~/config`` of the robot's controller (latched: the one in force),
        subscribed on first use."""
        topic = "/" + in_namespace(namespace, f"{controller}/config")
        if topic not in self._configs:
            self.node.create_subscription(
                String,
                topic,
                lambda msg: self._configs.__setitem__(topic, json.loads(msg.data)),
                CONFIG_QOS,
            )
            self._configs[topic] = {}
        self.spin_until(lambda: bool(self._configs[topic]), STARTUP_TIMEOUT, f"{topic}", check)
        self.serve_ready()  # a newer one, if it is waiting
        return self._configs[topic]

    def wait_for_graph(
        self,
        timeout: float = STARTUP_TIMEOUT,
        check: Callable[[], None] | None = None,
        reference_subscribers: int = 1,
    ) -> None:
        """Wait until a controller and the simulator are connected through the topics, and
        ``reference_subscribers`` subscriptions (the controller's, a recorder's) are matched
        with the probe's reference publisher: a reference acknowledged by fewer would miss
        one of them. With several robots, each robot's."""
        n = self.node

        def connected(ns: str) -> bool:
            states, commands = in_namespace(ns, "joint_states"), in_namespace(ns, "effort_command")
            return (
                n.count_publishers(states) >= 1
                and n.count_subscribers(states) >= 2
                and n.count_publishers(commands) >= 1
                and n.count_subscribers(commands) >= 1
                and self._ref_pubs[ns].get_subscription_count() >= reference_subscribers
            )

        self.spin_until(
            lambda: all(connected(ns) for ns in self.namespaces),
            timeout,
            "the simulator and the controller to connect",
            check,
        )

    def wait_for_subscriber(
        self,
        node_name: str,
        topics: Sequence[str],
        timeout: float = STARTUP_TIMEOUT,
        check: Callable[[], None] | None = None,
    ) -> None:
        """Wait until the node ``node_name`` subscribes to every topic in ``topics``."""
        n = self.node

        def subscribed() -> bool:
            return all(
                any(i.node_name == node_name for i in n.get_subscriptions_info_by_topic(t))
                for t in topics
            )

        self.spin_until(subscribed, timeout, f"'{node_name}' to subscribe to {topics}", check)

    # -- acting ------------------------------------------------------------------------
    def send_reference(
        self,
        joints: Sequence[str],
        positions: Sequence[Sequence[float]],
        times: Sequence[float] = (0.0,),
        start_ns: int = 0,
        velocities: Sequence[Sequence[float]] | None = None,
        accelerations: Sequence[Sequence[float]] | None = None,
        namespace: str | None = None,
    ) -> None:
        """Publish a trajectory to the robot in ``namespace`` (default: the first) and wait
        until every subscriber has acknowledged it."""
        msg = reference_message(joints, positions, times, start_ns, velocities, accelerations)
        publisher = self._ref_pubs[self.namespaces[0] if namespace is None else namespace]
        publisher.publish(msg)
        if not publisher.wait_for_all_acked(rclpy.duration.Duration(seconds=20.0)):
            raise TimeoutError("reference not acknowledged by every subscriber")

    def close(self) -> None:
        self._observed.close()
        super().close()
