"""A node's realtime threads: the scheduling parameters (``thread_priority``,
``cpu_affinity``, ``lock_memory``), applied by each realtime thread to itself, said once in
the log and shown on /diagnostics (:mod:`joint_space_control.scheduling`;
docs/performance.md "Thread priority")."""

from __future__ import annotations

import dataclasses
from typing import Any

from rclpy.node import Node

from joint_space_control import scheduling
from joint_space_control.ros import parameters as params

#: The executor thread's SCHED_FIFO priority beside realtime threads (configure_executor).
EXECUTOR_PRIORITY = 1

#: The scheduling parameters (declared beside the others, ROS-free).
PARAMETERS = params.REALTIME_PARAMETERS


class RealtimeThreads:
    """Validates the settings at start (ValueError: one line, exit 2), locks the memory if
    asked, and configures each realtime thread when it calls :meth:`configure`."""

    def __init__(self, node: Node, values: params.ParamValues) -> None:
        self._node = node
        self.priority = scheduling.check_priority(params.value(values, "thread_priority"))
        self.cpus = scheduling.check_cpus(params.value(values, "cpu_affinity").tolist())
        self.middleware_priority = scheduling.middleware_priority(
            params.value(values, "middleware_priority"), self.priority
        )
        self.middleware: list[str] = []
        self._middleware_done = False
        self.threads: dict[str, scheduling.Scheduling] = {}
        self._warned = False
        self.memory_locked = False
        if params.value(values, "lock_memory"):
            refused = scheduling.lock_memory()
            self.memory_locked = not refused
            if refused:
                self._warn(refused)
            else:
                node.get_logger().info("memory locked (mlockall: current and future pages)")

    def configure(self, thread: str) -> scheduling.Scheduling:
        """Apply the settings to the calling thread, which ``thread`` names; log what it
        got (INFO), or once per node what was refused and what to grant (WARN)."""
        got = scheduling.configure_this_thread(thread, self.priority, self.cpus)
        self.threads[thread] = got
        if got.refused:
            grant = f"; {scheduling.GRANT}" if "SCHED_FIFO" in got.refused else ""
            self._warn(f"realtime thread {got.text} ({got.refused}){grant}")
        else:
            self._node.get_logger().info(f"realtime thread {got.text}")
        if not self._middleware_done and "SCHED_FIFO" not in got.refused:
            # (refused for this thread, it is refused for the middleware's: said once)
            self._middleware_done = True
            self.configure_middleware()
        return got

    def configure_middleware(self) -> None:
        """The middleware's threads that deliver the node's messages, at
        ``middleware_priority`` (called by the first realtime thread, once the node has its
        publishers and subscriptions). A FIFO control path waits for its input as long as
        the thread that receives it waits for a CPU: with a browser starting beside the
        loop, the normal-priority reception threads of Fast DDS waited long enough for the
        plant to brake (docs/performance.md "Thread priority")."""
        if self.middleware_priority == 0:
            return
        done, refused = scheduling.configure_threads(
            scheduling.MIDDLEWARE_THREADS, self.middleware_priority, self.cpus
        )
        self.middleware = done
        if refused:
            self._warn(f"middleware threads: {refused}")
        elif done:
            self._node.get_logger().info(
                f"middleware threads {', '.join(done)}: SCHED_FIFO priority "
                f"{self.middleware_priority}"
            )

    def configure_executor(self) -> scheduling.Scheduling:
        """The executor thread (parameters, services, diagnostics): SCHED_FIFO at priority 1
        when the realtime threads run at FIFO, else normal. It holds the interpreter the
        realtime threads need while it works; at normal priority, other work on the machine
        preempts it in the middle and the realtime thread then waits for its time slice
        (docs/performance.md "Thread priority": under a CPU hog, 0.13 % of the plant's ticks
        more than 1 ms late instead of 0.01-0.03 %). At priority 1 it runs before any normal
        thread and after the realtime ones."""
        priority = EXECUTOR_PRIORITY if self.priority > 0 else 0
        got = scheduling.configure_this_thread("executor", priority)
        if got.refused:  # the realtime threads' refusal already said what to grant
            got = dataclasses.replace(got, refused="")
        self.threads["executor"] = got
        return got

    def diagnostics(self) -> dict[str, Any]:
        """Policy, priority and CPUs of each configured thread, and the memory lock."""
        values: dict[str, Any] = {
            "memory_locked": int(self.memory_locked),
            "scheduling.middleware.threads": len(self.middleware),
            "scheduling.middleware.priority": self.middleware_priority if self.middleware else 0,
        }
        for got in self.threads.values():
            values.update(got.diagnostics())
        return values

    def _warn(self, text: str) -> None:
        if not self._warned:
            self._warned = True
            self._node.get_logger().warning(text)
