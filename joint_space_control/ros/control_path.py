"""A dedicated wait-set loop for a node's control path, next to a standard executor.

rclpy's ``SingleThreadedExecutor`` rebuilds its wait set in Python at every wake-up: every
subscription, service, timer and QoS event handler of the node (the six parameter services
included) goes through callback-group checks and context managers, then the ready entity is
wrapped in a task. For a node that answers a joint state once per millisecond that is most
of the CPU time of a tick (profiled: ~0.6 ms per wake-up on this machine, more than the
control law, the message conversion and the publishing together). ``rclpy.experimental``'s
EventsExecutor avoids it, but in this rclpy (7.1) its ``spin()`` neither serves services nor
stops on a signal.

So the few entities of the control path (subscriptions in a fixed priority order and at most
one timer) are served by :meth:`ControlPath.spin`: one rcl wait set that holds exactly them
and the signal guard condition, built once and refilled in C at each wait, ready entities
taken and called directly. Everything else of the node (parameter services, services, other
timers, QoS events of the publishers) stays with a standard executor spun in a second
thread; it sleeps in ``rcl_wait`` (the GIL released) until one of those rare events.
``/clock`` with ``use_sim_time``, which comes at the plant's rate, is taken on the control
path too (:meth:`ControlPath.take_clock`).
The control-path entities belong to :class:`ControlPathGroup`, which the rclpy executors
never execute.

Another thread hands work to the control path with :meth:`ControlPath.post` (a function
run in the control-path thread at its next wake-up, which the post causes).

A callback receives ``(message, info)``: ``info`` is the rmw message info (``source_timestamp``,
``received_timestamp`` [ns, system clock]) for subscriptions and None for the timer.
"""

from __future__ import annotations

import gc
import sys
import threading
from collections import deque
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerGuardCondition
from rclpy.subscription import Subscription
from rclpy.timer import Timer

from joint_space_control.scheduling import name_this_thread

#: Longest wait [ns] before the loop looks at the context again (a signal wakes it at once).
_WAIT_NS = 200_000_000
#: Python's GIL switch interval [s] in a process with a control path.
SWITCH_INTERVAL = 0.0001


class ControlPathGroup(CallbackGroup):
    """Entities served by a :class:`ControlPath`: the rclpy executors leave them alone."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


@dataclass(frozen=True)
class _Mode:
    """How :meth:`ControlPath._serve` waits and when it returns."""

    timeout_ns: int = _WAIT_NS  # longest wait
    until_ns: int | None = None  # hand out only messages received before (system clock)
    until_idle: bool = False  # return after a wait that brings nothing
    once: bool = False  # return after one wait


@dataclass(frozen=True)
class _Entry:
    sub: Subscription
    callback: Callable[[Any, Any], None]
    drain: bool


class ControlPath:
    """The control-path entities of one node and the loop that serves them.

    Subscriptions may be added and removed while the loop runs (from another thread: the
    loop rebuilds its wait set before its next wait)."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.group = ControlPathGroup()
        self._subscriptions: list[_Entry] = []
        self._timer: tuple[Timer, Callable[[], None]] | None = None
        self._version = 0  # bumped on every change of the entities
        self._posted: deque[Callable[[], None]] = deque()  # run by the serving thread
        self._stop = False
        self._wake = GuardCondition(None, None, context=node.context)
        self._sigint: SignalHandlerGuardCondition | None = None
        self._prepared: _Prepared | None = None
        # close() from another thread while this one waits on the handles (Ctrl-C closing a
        # run whose thread spins): the serving thread lets go of them on its way out
        self._guard = threading.Lock()
        self._serving = False
        self._close_pending = False
        #: Called by :meth:`spin` in the serving thread before it serves (a node gives that
        #: thread its realtime scheduling there: threads it starts later stay normal).
        self.on_serve: Callable[[], None] | None = None
        #: Called by :func:`spin_node` in the executor thread before it spins.
        self.on_executor: Callable[[], None] | None = None

    def __bool__(self) -> bool:
        return bool(self._subscriptions or self._timer)

    def subscription(
        self,
        msg_type: Any,
        topic: str,
        callback: Callable[[Any, Any], None],
        qos: QoSProfile,
        raw: bool = False,
        drain: bool = False,
    ) -> Subscription:
        """A subscription of the control path; taken in the order of creation when several
        are ready. ``callback(message, info)``; ``raw`` delivers the serialized bytes;
        ``drain`` takes every queued message at each wake-up (not just one)."""
        sub = self._create(msg_type, topic, callback, qos, raw)
        self._subscriptions = [*self._subscriptions, _Entry(sub, callback, drain)]
        self._changed()
        return sub

    def take_clock(self) -> bool:
        """With ``use_sim_time``: take ``/clock`` on the control path, not in the executor
        thread. rclpy's time source subscribes to it in the node's default callback group,
        so the standard executor woke for every message (~0.6 ms of Python each, at the
        plant's rate, in a second thread that shares the GIL and the cores with the loop);
        here the time source's own callback updates the node's clocks from this path's
        wait set, and its subscription is destroyed. Turned off and on again at runtime,
        ``use_sim_time`` makes rclpy subscribe again: both then set the same time. Returns
        whether ``/clock`` is taken here (False without ``use_sim_time``)."""
        source = getattr(self.node, "_time_source", None)
        given = getattr(source, "_clock_sub", None)
        if given is None:
            return False
        self.subscription(
            given.msg_type,
            given.topic_name,
            lambda msg, _info: source.clock_callback(msg),
            given.qos_profile,
            drain=True,
        )
        source._clock_sub = None
        self.node.destroy_subscription(given)
        return True

    def resubscribe(self, sub: Subscription, qos: QoSProfile) -> Subscription:
        """``sub`` again with another QoS, in its place in the order (control-path thread:
        the loop then rebuilds its wait set); returns the new subscription. A message may
        come on both while they overlap, none is missed."""
        entry = next(e for e in self._subscriptions if e.sub is sub)
        new = self._create(sub.msg_type, sub.topic_name, entry.callback, qos, sub.raw)
        self._subscriptions = [
            _Entry(new, e.callback, e.drain) if e.sub is sub else e for e in self._subscriptions
        ]
        self._changed()
        self.node.destroy_subscription(sub)
        return new

    def _create(
        self, msg_type: Any, topic: str, callback: Callable, qos: QoSProfile, raw: bool
    ) -> Subscription:
        # Without QoS event handlers: rmw_fastrtps wakes every wait set that holds one of a
        # subscription's events on each of its messages, so handlers served by the executor
        # would cost a full executor wake-up per message (measured: ~1 ms of CPU). A
        # publisher with an incompatible QoS still hears about it on its side.
        return self.node.create_subscription(
            msg_type,
            topic,
            callback,
            qos,
            callback_group=self.group,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            raw=raw,
        )

    def destroy_subscription(self, sub: Subscription) -> None:
        """Remove a subscription of the control path and destroy it (rclpy defers that
        until the loop has let go of it)."""
        self._subscriptions = [e for e in self._subscriptions if e.sub is not sub]
        self._changed()
        self.node.destroy_subscription(sub)

    def timer(self, period: float, callback: Callable[[], None]) -> Timer:
        """The control path's timer (the node clock: simulation time with use_sim_time)."""
        if self._timer is not None:
            raise ValueError("a control path has at most one timer")
        timer = self.node.create_timer(period, callback, callback_group=self.group)
        self._timer = (timer, callback)
        self._changed()
        return timer

    def post(self, callback: Callable[[], None]) -> None:
        """Run ``callback()`` in the thread that serves the control path, at its next wake-up
        (caused by this call); for another thread (the executor's) to hand over work that
        must not race with the control-path callbacks."""
        self._posted.append(callback)
        self._wake.trigger()

    def _changed(self) -> None:
        self._version += 1
        self._wake.trigger()

    def stop(self) -> None:
        """Make :meth:`spin` return (from another thread or a signal handler)."""
        self._stop = True
        self._wake.trigger()

    def spin(self) -> None:
        """Serve the control path until the context shuts down (Ctrl-C, SIGTERM) or
        :meth:`stop`. Exceptions of the callbacks propagate."""
        if self.on_serve is not None:
            self.on_serve()
        try:
            self._serve(_Mode())
        finally:
            self.close()

    def spin_once(self, timeout: float) -> int:
        """One wait of at most ``timeout`` seconds, then everything ready handed out (for a
        client that runs its own loop; the wait set is kept between calls: :meth:`close`
        when done); returns the number of messages."""
        return self._serve(_Mode(timeout_ns=round(timeout * 1e9), once=True))

    def drain(self, idle: float, received_before_ns: int) -> None:
        """After :meth:`stop`, before closing: hand out what the subscriptions still hold
        that was received before ``received_before_ns`` (system clock), until a wait of
        ``idle`` seconds brings no such message; later messages are dropped."""
        self._stop = False
        try:
            self._serve(_Mode(round(idle * 1e9), received_before_ns, until_idle=True))
        finally:
            self.close()

    def close(self) -> None:
        """Let go of the rcl handles and the signal guard condition (idempotent). Called
        while another thread serves, it stops that thread, which lets go when it returns
        (releasing handles a wait is using would crash the process)."""
        with self._guard:
            if self._serving:
                self._close_pending = self._stop = True
                self._wake.trigger()
                return
            self._release()

    def _release(self) -> None:
        if self._prepared is not None:
            self._prepared.close()
            self._prepared = None
        if self._sigint is not None:
            self._sigint.destroy()
            self._sigint = None

    def _serve(self, mode: _Mode) -> int:
        """Wait and hand out as ``mode`` says, with a wait set rebuilt whenever the entities
        change; returns the number of messages handed out."""
        context = self.node.context
        count = 0
        with self._guard:
            if self._stop or not context.ok():
                return 0
            self._serving = True
        try:
            while not self._stop and context.ok():
                if self._prepared is None or self._prepared.version != self._version:
                    if self._prepared is not None:
                        self._prepared.close()
                    if self._sigint is None:
                        self._sigint = SignalHandlerGuardCondition(context)
                    self._prepared = _Prepared(self, self._sigint)
                done, taken = self._loop(self._prepared, mode)
                count += taken
                if done:
                    break
        finally:
            with self._guard:
                self._serving = False
                if self._close_pending:
                    self._close_pending = False
                    self._release()
        return count

    def _loop(self, prepared: _Prepared, mode: _Mode) -> tuple[bool, int]:
        """Wait and take until the entities change ((False, n)) or ``mode`` is done
        ((True, n)); n messages were handed out."""
        context = self.node.context
        wait_set, subs, timer = prepared.wait_set, prepared.subs, prepared.timer
        add_sub, ready = wait_set.add_subscription, wait_set.is_ready
        sigint, wake = prepared.guards
        until_ns = mode.until_ns
        count = 0
        while not self._stop and context.ok() and prepared.version == self._version:
            wait_set.clear_entities()
            for handle, *_ in subs:
                add_sub(handle)
            wait_set.add_guard_condition(sigint)
            wait_set.add_guard_condition(wake)
            if timer is not None:
                wait_set.add_timer(timer[0])
            wait_set.wait(mode.timeout_ns)
            taken_any = False
            for k, (handle, msg_type, raw, callback, all_queued) in enumerate(subs):
                if ready("subscription", k):
                    taken = handle.take_message(msg_type, raw)
                    while taken is not None:
                        if until_ns is None or taken[1]["received_timestamp"] <= until_ns:
                            taken_any = True
                            count += 1
                            callback(*taken)
                        taken = handle.take_message(msg_type, raw) if all_queued else None
            if timer is not None and ready("timer", 0):
                if timer[0].is_timer_ready():
                    timer[0].call_timer()
                    timer[1]()
            posted = self._posted
            while posted:
                posted.popleft()()
            if mode.once:
                return True, count
            woken = ready("guard_condition", 0) or ready("guard_condition", 1)
            if mode.until_idle and not taken_any and not woken:
                return True, count
        return False, count


class _Prepared:
    """The wait set for one version of a control path's entities, their rcl handles held
    (kept alive, destruction deferred) until :meth:`close`."""

    def __init__(self, path: ControlPath, sigint: SignalHandlerGuardCondition) -> None:
        self.version = path._version
        entries, timer = path._subscriptions, path._timer
        self._handles = ExitStack()
        handles = [sigint.handle, path._wake.handle] + [e.sub.handle for e in entries]
        if timer is not None:
            handles.append(timer[0].handle)
        for handle in handles:
            self._handles.enter_context(handle)
        self.guards = (sigint.handle, path._wake.handle)
        self.subs = [
            (e.sub.handle, e.sub.msg_type, e.sub.raw, e.callback, e.drain) for e in entries
        ]
        self.timer = None if timer is None else (timer[0].handle, timer[1])
        self.wait_set = _rclpy.WaitSet(
            len(self.subs), 2, 0 if timer is None else 1, 0, 0, 0, path.node.context.handle
        )

    def close(self) -> None:
        self._handles.close()


def spin_node(
    node: Node,
    control_path: ControlPath | None,
    executor: SingleThreadedExecutor | None = None,
    stopping: threading.Event | None = None,
) -> None:
    """Spin ``node``: its control path (if any, even one still empty) in this thread and the
    rest in a standard executor (``executor``, made before the node so that a signal during
    start-up finds it whole; else one made here) in a second thread; only the executor
    without one. Returns when the context shuts down, the control path is stopped or
    ``stopping`` is set (a signal, :func:`~joint_space_control.ros.node_main.run_node`)."""
    executor = executor if executor is not None else SingleThreadedExecutor()
    executor.add_node(node)
    if control_path is None:
        if stopping is None:
            executor.spin()
            return
        while not stopping.is_set():
            executor.spin_once(timeout_sec=0.2)
        return
    # A thread that wants the GIL asks its holder to let go after this long (default 5 ms):
    # the control path must not wait milliseconds behind the executor thread's work. 0.1 ms
    # rather than 0.5: each executor wake-up (~0.6 ms of Python) then delays a realtime tick
    # by ~0.1 ms, within the 200 µs a tick may be late (docs/performance.md, Thread priority).
    sys.setswitchinterval(SWITCH_INTERVAL)
    # Everything built so far (modules, the model, the node) lives as long as the process:
    # out of the garbage collector's sight, a full collection takes microseconds instead of
    # the ~15 ms that stalled a tick now and then.
    gc.collect()
    gc.freeze()
    failure: list[BaseException] = []
    done = threading.Event()

    def spin_rest() -> None:
        name_this_thread("jsc-executor")
        if control_path.on_executor is not None:
            control_path.on_executor()
        try:
            while not done.is_set():
                executor.spin_once(timeout_sec=0.2)
        except ExternalShutdownException:
            pass
        except BaseException as err:  # pragma: no cover - reported by the main thread
            failure.append(err)
            control_path.stop()

    thread = threading.Thread(target=spin_rest, name="executor", daemon=True)
    thread.start()
    try:
        control_path.spin()
    finally:
        # The executor thread leaves its wait before the executor's guard conditions are
        # destroyed: shut down under it, a wait on destroyed handles crashes (SIGSEGV); at
        # FIFO priority this thread would win that race every time.
        done.set()
        executor.wake()
        thread.join(timeout=2.0)
        executor.shutdown(timeout_sec=1.0)
    if failure:
        raise failure[0]
