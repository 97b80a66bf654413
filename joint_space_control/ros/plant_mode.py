"""Which mode the plant behind a topic runs in, learnt without blocking (``trigger: auto``).

A controller with ``trigger: auto`` answers every joint state of a lockstep plant and runs
its timer against anything else. It learns the plant's mode from the ROS graph: the nodes
that publish its ``joint_states`` topic, whose ``mode`` parameter it reads through the
standard parameter service (``rcl_interfaces/srv/GetParameters``), the way ``ros2 param get``
does. ``sim_bridge`` declares ``mode`` (``realtime`` | ``lockstep``).

- a publisher answers ``lockstep``                      → ``state``
- every publisher answered something else, or has no
  ``mode``, or no answer came within ANSWER_TIMEOUT     → ``timer``
- no publisher seen yet, or answers outstanding         → no decision yet

Besides the trigger, the watcher says whether every publisher declared itself ``realtime``
(:attr:`PlantModeWatcher.realtime`): a controller that answers each state keeps a reliable
reader behind a publisher that is not a plant (a test's own states), and takes the newest
state only behind a plant that says it runs in realtime.

Everything here runs in the node's executor thread (a steady-clock timer, so it also runs
with ``use_sim_time`` before any /clock; asynchronous service calls and their
done-callbacks): the control path is never blocked. The publishers are looked at again
every WATCH_PERIOD once decided, so a plant restarted in another mode is followed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import GetParameters
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

#: How often the publishers are looked at while no decision is made [s].
POLL_PERIOD = 0.05
#: How often once decided [s].
WATCH_PERIOD = 1.0
#: A publisher whose parameter service does not answer within this [s] is not lockstep.
ANSWER_TIMEOUT = 2.0
#: What a publisher without an answer counts as.
NO_ANSWER = ""

#: The decision as /diagnostics names the plant (``plant``).
PLANT_SEEN = {None: "unknown", "state": "lockstep", "timer": "not_lockstep"}

Key = tuple[str, str, bytes]  # node namespace, node name, endpoint gid


def _service_name(key: Key) -> str:
    namespace, name, _ = key
    return f"{namespace.rstrip('/')}/{name}/get_parameters"


def _label(key: Key) -> str:
    namespace, name, _ = key
    return f"{namespace.rstrip('/')}/{name}"


def trigger_for(answers: dict[Key, str], publishers: frozenset[Key]) -> str | None:
    """The trigger the modes of the publishers ask for (None: not known yet)."""
    if any(answers.get(k) == "lockstep" for k in publishers):
        return "state"
    if publishers and all(k in answers for k in publishers):
        return "timer"
    return None


def declared_realtime(answers: dict[Key, str], publishers: frozenset[Key]) -> bool:
    """True when there are publishers and every one answered ``mode`` = ``realtime``."""
    return bool(publishers) and all(answers.get(k) == "realtime" for k in publishers)


class PlantModeWatcher:
    """Calls ``on_decision(trigger, reason)`` (in the executor thread) whenever the trigger
    the publishers of ``topic`` ask for is decided or changes, or :attr:`realtime` does."""

    def __init__(self, node: Node, topic: str, on_decision: Callable[[str, str], None]) -> None:
        self._node = node
        self._topic = node.resolve_topic_name(topic)
        self._on_decision = on_decision
        self._publishers: frozenset[Key] = frozenset()
        self._answers: dict[Key, str] = {}
        # outstanding questions: key -> (client, future or None before the call, since)
        self._asked: dict[Key, tuple[Any, Any, float]] = {}
        self._decision: str | None = None
        self._realtime = False
        self._next_look = 0.0
        self._timer = node.create_timer(
            POLL_PERIOD, self._poll, clock=Clock(clock_type=ClockType.STEADY_TIME)
        )

    @property
    def decision(self) -> str | None:
        return self._decision

    @property
    def realtime(self) -> bool:
        """Every publisher of the topic declared ``mode: realtime`` (as of the decision)."""
        return self._realtime

    def _poll(self) -> None:
        now = time.monotonic()
        if self._decision is not None and not self._asked and now < self._next_look:
            return
        self._next_look = now + WATCH_PERIOD
        infos = self._node.get_publishers_info_by_topic(self._topic)
        keys = frozenset((i.node_namespace, i.node_name, bytes(i.endpoint_gid)) for i in infos)
        if keys != self._publishers:
            for key in set(self._asked) - keys:
                self._node.destroy_client(self._asked.pop(key)[0])
            self._answers = {k: v for k, v in self._answers.items() if k in keys}
            self._publishers = keys
        for key in keys:
            if key not in self._answers:
                self._ask(key, now)
        self._decide()

    def _ask(self, key: Key, now: float) -> None:
        client, future, since = self._asked.get(key, (None, None, now))
        if client is None:
            client = self._node.create_client(GetParameters, _service_name(key))
        if future is None and client.service_is_ready():
            future = client.call_async(GetParameters.Request(names=["mode"]))
            future.add_done_callback(lambda f, key=key: self._answered(key, f))
        self._asked[key] = (client, future, since)
        if now - since > ANSWER_TIMEOUT:
            self._finish(key, NO_ANSWER)

    def _answered(self, key: Key, future: Any) -> None:
        if key not in self._asked:  # gone meanwhile
            return
        mode = NO_ANSWER
        try:
            values = future.result().values
        except Exception:  # noqa: BLE001 - a failed call is "no answer"
            values = []
        if values and values[0].type == ParameterType.PARAMETER_STRING:
            mode = values[0].string_value
        self._finish(key, mode)
        self._decide()

    def _finish(self, key: Key, mode: str) -> None:
        client, future, _ = self._asked.pop(key)
        if future is not None and not future.done():
            future.cancel()
        self._node.destroy_client(client)
        self._answers[key] = mode

    def _decide(self) -> None:
        trigger = trigger_for(self._answers, self._publishers)
        realtime = declared_realtime(self._answers, self._publishers)
        if trigger is None or (trigger, realtime) == (self._decision, self._realtime):
            return
        self._decision, self._realtime = trigger, realtime
        modes = ", ".join(
            f"{_label(k)} mode={self._answers[k] or '(none)'}"
            for k in sorted(self._publishers)
            if k in self._answers
        )
        self._on_decision(trigger, f"{self._topic} published by {modes}")

    def close(self) -> None:
        self._timer.cancel()
        for client, future, _ in self._asked.values():
            if future is not None and not future.done():
                future.cancel()
            self._node.destroy_client(client)
        self._asked.clear()
