"""``recorder``: records topics to a rosbag2 bag (MCAP by default) with the rosbags library.

The node discovers the selected topics as they appear in the graph (every
``discovery_period`` seconds of wall time, so it also works before ``/clock`` runs) and
subscribes to each with raw (serialized) delivery, so messages are written as received,
without a deserialize/serialize round trip. The subscription's QoS adapts to the publishers,
as ``ros2 bag record`` does: best effort if any publisher is best effort, transient local
(latched topics such as ``~/config``) if all publishers are; it is re-created once if a
publisher with other QoS turns up later.

``~/flush`` (std_srvs/Trigger) writes what the recorder holds to the file and answers the
messages recorded per topic (a JSON object ``{topic: count}`` in ``message``): a caller that
knows how many messages were published learns when the recorder has them all (the
experiment runner does, before it stops a lockstep loop's nodes). ``~/matched``
(std_srvs/Trigger) answers, per recorded topic, how many publishers its subscription is
matched with (``{topic: count}``): a subscription seen in the graph may not be matched yet,
and what a publisher sends before it is lost to the bag (the experiment runner waits for a
match on every topic of a run before it starts one).

Each message is stamped with its receive time in the node clock: the simulation time with
``use_sim_time:=true``, else the system time. Ctrl-C and SIGTERM close the bag cleanly (the
MCAP summary and ``metadata.yaml`` are written). What was recorded reaches the file every
``flush_period`` (of bag time, and of wall time while idle), so SIGKILL loses at most about
that much; ``jsc recover`` makes a complete bag of what is on disk. The bag is not created
on a file system with less than ``min_free_space_mb`` free; a write error while recording
(disk full) stops the recording with one error line and exit code 1.

The recorded subscriptions are served by a dedicated wait-set loop that takes every queued
message at each wake-up (:class:`~joint_space_control.ros.control_path.ControlPath`): a
standard executor rebuilds its wait set per message, which caps a recorder at a few thousand
messages per second, less than a lockstep loop produces.
"""

from __future__ import annotations

import importlib
import json
import signal
import sys
import threading
import time
from typing import Any

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
from rosbags.interfaces import QosTime as BagQosTime
from std_srvs.srv import Trigger

from joint_space_control.memory import (
    LARGE_BLOCK_BYTES,
    give_back_free_memory,
    large_blocks_from_the_system,
)
from joint_space_control.recording.bag_writer import (
    FLUSH_PERIOD,
    MIN_FREE_SPACE_MB,
    STORAGES,
    BagWriteError,
    BagWriter,
    RecordedTopic,
)
from joint_space_control.recording.selection import DEFAULT_TOPICS, TopicSelection
from joint_space_control.ros import node_main
from joint_space_control.ros import parameters as params
from joint_space_control.ros.control_path import ControlPath, spin_node
from joint_space_control.throttle import ThrottledLog

#: Messages a subscription queues while the recorder is busy writing.
QUEUE_DEPTH = 10000
#: Wall time [s] between returns of the allocator's free pages to the system (see
#: :meth:`Recorder._give_back`).
GIVE_BACK_PERIOD = 10.0
#: After a stop signal, the bag is closed once a wait of this long [s] brings no message
#: received before the signal.
DRAIN_IDLE = 0.05

PARAMETERS = (
    params.ParamSpec(
        "output",
        "",
        "Bag directory to create (must not exist); default rosbag2_<date>-<time>",
        read_only=True,
    ),
    params.ParamSpec(
        "topics",
        [],
        "Topic names or patterns (* ? []) to record; relative ones in the node's namespace; "
        f"empty: {', '.join(DEFAULT_TOPICS)}",
        read_only=True,
        kind="names",
    ),
    params.ParamSpec("storage", "mcap", "Storage format", read_only=True, choices=tuple(STORAGES)),
    params.ParamSpec(
        "discovery_period",
        0.2,
        "Wall time between looks for new topics",
        read_only=True,
        unit="s",
        minimum=0.0,
        exclusive=True,
        maximum=60.0,
    ),
    params.ParamSpec(
        "flush_period",
        FLUSH_PERIOD,
        "Recorded (bag) time, and wall time when idle, between flushes to the file [s]: the "
        "most a SIGKILL loses; 0: only at close (MCAP: 1 MiB chunks; sqlite3: nothing "
        "survives a kill)",
        read_only=True,
        unit="s",
        minimum=0.0,
        maximum=3600.0,
    ),
    params.ParamSpec(
        "min_free_space_mb",
        MIN_FREE_SPACE_MB,
        "Free space the output's file system must have at start; 0: no check",
        read_only=True,
        unit="MB",
        minimum=0.0,
    ),
)
#: What the node subscribes to and serves: (kind, relative name, type, meaning), rendered
#: into docs/reference by joint_space_control.nodes.reference.
INTERFACE = (
    (
        "subscribes",
        "<recorded topic>",
        "(any)",
        "every topic `topics` selects, taken serialized as it appears in the graph and "
        "written as received; QoS matched to its publishers (best effort if one is, "
        "transient local if all are)",
    ),
    (
        "serves",
        "~/flush",
        "std_srvs/srv/Trigger",
        "write what is held to the file; answers the messages recorded per topic, "
        "`{topic: count}` as JSON",
    ),
    (
        "serves",
        "~/matched",
        "std_srvs/srv/Trigger",
        "answers the publishers each recorded topic's subscription is matched with, "
        "`{topic: count}` as JSON",
    ),
)

_RELIABILITY = {
    ReliabilityPolicy.RELIABLE: QosReliability.RELIABLE,
    ReliabilityPolicy.BEST_EFFORT: QosReliability.BEST_EFFORT,
}
_DURABILITY = {
    DurabilityPolicy.TRANSIENT_LOCAL: QosDurability.TRANSIENT_LOCAL,
    DurabilityPolicy.VOLATILE: QosDurability.VOLATILE,
}
_NO_TIME = BagQosTime(0, 0)


def _bag_qos(profile: QoSProfile) -> Qos:
    """A publisher's offered QoS in the form rosbag2 metadata stores it."""
    return Qos(
        history=QosHistory.UNKNOWN,
        depth=0,
        reliability=_RELIABILITY.get(profile.reliability, QosReliability.UNKNOWN),
        durability=_DURABILITY.get(profile.durability, QosDurability.UNKNOWN),
        deadline=_NO_TIME,
        lifespan=_NO_TIME,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_NO_TIME,
        avoid_ros_namespace_conventions=False,
    )


def subscription_qos(offered: list[QoSProfile]) -> QoSProfile:
    """The QoS that receives from every publisher: reliable unless one is best effort,
    transient local only if all publishers keep their last messages for late joiners."""
    best_effort = any(p.reliability == ReliabilityPolicy.BEST_EFFORT for p in offered)
    latched = bool(offered) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=QUEUE_DEPTH,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def _same_qos(a: QoSProfile, b: QoSProfile) -> bool:
    return a.reliability == b.reliability and a.durability == b.durability


class Recorder(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        params.declare(self, PARAMETERS)
        values = params.current_values(self, PARAMETERS)
        storage = params.value(values, "storage")
        self.selection = TopicSelection(params.value(values, "topics"), self.get_namespace())
        period = params.value(values, "discovery_period")
        flush_period = params.value(values, "flush_period")
        min_free = params.value(values, "min_free_space_mb")
        output = values["output"] or time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")
        # fails here, before anything runs
        self.bag = BagWriter(output, storage, flush_period, min_free)
        self._recording: dict[str, tuple[Subscription, QoSProfile]] = {}
        self._skipped: set[str] = set()
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._log = ThrottledLog(self.get_logger())  # one line a second per kind
        self.control_path = ControlPath(self)
        self.control_path.take_clock()  # the receive stamps' time, at the plant's rate
        try:
            self._discover()
            self.create_timer(period, self._discover, clock=self._wall)
            if flush_period > 0:  # an idle recorder still flushes what it holds
                self.create_timer(flush_period, self._flush, clock=self._wall)
            self.create_timer(GIVE_BACK_PERIOD, self._give_back, clock=self._wall)
            self.create_service(Trigger, "~/flush", self._on_flush)
            self.create_service(Trigger, "~/matched", self._on_matched)
        except BaseException:
            self.bag.close()
            raise
        self.get_logger().info(
            f"recording {', '.join(self.selection.patterns)} to {output} ({storage})"
        )

    def _flush(self) -> None:
        try:
            self.bag.flush()
        except BagWriteError as err:
            self.write_failed(err)

    def _give_back(self) -> None:
        """The allocator's free pages back to the system, every ``GIVE_BACK_PERIOD``.

        A recorder frees most of what it allocates within a flush period (messages, the
        chunk being written), but blocks it keeps (the MCAP summary's chunk index, the
        middleware's bookkeeping) can land between them, and glibc returns only the top of
        its heap on free: the freed pages below stay resident. One call returned 1.0 MB of
        a recorder's 53 MB after 6 minutes at 250 Hz. It took 0.1-5 ms a call there, in
        the executor's thread, not the one that takes the messages."""
        give_back_free_memory()

    def _on_flush(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """``~/flush``: what is held goes to the file; the answer counts what was recorded."""
        self._flush()
        response.success = self.bag.error is None
        response.message = (
            json.dumps({t.name: t.count for t in self.bag.topics.values()})
            if response.success
            else str(self.bag.error)
        )
        return response

    def _on_matched(
        self, _request: Trigger.Request, response: Trigger.Response
    ) -> Trigger.Response:
        """``~/matched``: the publishers each recorded topic's subscription is matched with."""
        response.success = True
        response.message = json.dumps(
            {
                name: sub.get_publisher_count()
                for name, (sub, _qos) in list(self._recording.items())
            }
        )
        return response

    def write_failed(self, err: BagWriteError) -> None:
        """A write error of the storage (disk full): one error line, recording stops (the
        bag is already closed as far as it can be)."""
        self.get_logger().error(str(err))
        self.control_path.stop()

    def _discover(self) -> None:
        if self.bag.error is not None:
            return
        for name, types in self.get_topic_names_and_types():
            if not self.selection.matches(name) or name in self._skipped:
                continue
            offered = [i.qos_profile for i in self.get_publishers_info_by_topic(name)]
            qos = subscription_qos(offered)
            current = self._recording.get(name)
            if current is not None:
                if not offered or _same_qos(current[1], qos):
                    continue
                self.control_path.destroy_subscription(current[0])  # a publisher needs other QoS
                topic = self.bag.topics[name]
            else:
                msgtype = types[0]
                if len(types) > 1 or not self.bag.knows(msgtype) or not _importable(msgtype):
                    self._skipped.add(name)
                    self.get_logger().warning(
                        f"not recording {name}: "
                        + (
                            f"several types {types}"
                            if len(types) > 1
                            else f"no message definition for {msgtype}"
                        )
                    )
                    continue
                try:
                    topic = self.bag.add_topic(name, msgtype, [_bag_qos(p) for p in offered])
                except BagWriteError as err:
                    self.write_failed(err)
                    return
                self.get_logger().info(f"recording {name} [{msgtype}]")
            self._subscribe(topic, qos)

    def _subscribe(self, topic: RecordedTopic, qos: QoSProfile) -> None:
        msg_class = _message_class(topic.msgtype)
        clock = self.get_clock()
        bag = self.bag
        log = self._log
        malformed = ("malformed", topic.name)  # a kind per topic

        def on_message(raw: bytes, info: Any) -> None:
            try:
                written = bag.write(topic, clock.now().nanoseconds, raw)
            except BagWriteError as err:
                self.write_failed(err)
                return
            if not written and bag.error is None:
                log.warning(malformed, "dropped a malformed {} on {}", topic.msgtype, topic.name)
            if len(raw) >= LARGE_BLOCK_BYTES:  # a huge reference: its framing's pages back
                give_back_free_memory()

        sub = self.control_path.subscription(
            msg_class, topic.name, on_message, qos, raw=True, drain=True
        )
        self._recording[topic.name] = (sub, qos)

    def close(self) -> None:
        """Close the bag (summary and metadata written); called on Ctrl-C and SIGTERM."""
        try:
            self.bag.close()
        except BagWriteError as err:
            self.get_logger().error(str(err))
        if self.bag.error is not None:
            print(
                f"recorder: stopped on a write error; {self.bag.path} is incomplete with "
                f"{self.bag.message_count} messages written",
                flush=True,
            )
            return
        counts = ", ".join(f"{t.name}: {t.count}" for t in self.bag.topics.values())
        print(
            f"recorder: closed {self.bag.path} with {self.bag.message_count} messages"
            + (f" ({counts})" if counts else ""),
            flush=True,
        )


def _message_class(msgtype: str) -> type:
    """The Python class of 'pkg/msg/Name' from its installed interface package."""
    package, _, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _importable(msgtype: str) -> bool:
    try:
        _message_class(msgtype)
    except (ImportError, AttributeError, ValueError):
        return False
    return True


def main(args: list[str] | None = None) -> None:
    """Record until Ctrl-C or SIGTERM (or until the process that started it is gone,
    node_main.watch_parent), then take what the subscriptions still hold (messages
    delivered before the signal are not lost) and close the bag."""
    node_main.init(args, signal_handler_options=SignalHandlerOptions.NO)
    large_blocks_from_the_system()  # as node_main.run_node does for the other nodes
    stop = threading.Event()
    recorder: list[Recorder] = []
    stopped_at = [0]  # system clock [ns]: what was received until then is written

    def on_signal(*_: Any) -> None:
        if not stop.is_set():
            stopped_at[0] = time.time_ns()
        stop.set()
        if recorder:
            recorder[0].control_path.stop()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)

    def log(message: str) -> None:
        if recorder:
            recorder[0].get_logger().warning(message)
        else:
            print(f"warning: {message}", file=sys.stderr, flush=True)

    node_main.watch_parent(log)  # its starting process killed: the bag is closed as on SIGTERM
    try:
        node = Recorder()
    except (ValueError, ParameterException) as err:
        print(f"error: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        sys.exit(2)
    recorder.append(node)
    try:
        if not stop.is_set():
            spin_node(node, node.control_path)  # until a signal or a write error stops it
        if node.bag.error is None:
            node.control_path.drain(DRAIN_IDLE, stopped_at[0] or time.time_ns())
    finally:
        node.close()
        node.destroy_node()
        rclpy.try_shutdown()
    if node.bag.error is not None:
        sys.exit(1)


if __name__ == "__main__":
    main()
