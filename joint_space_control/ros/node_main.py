"""The ``main`` shared by every node executable: init, spin, clean shutdown."""

from __future__ import annotations

import os
import re
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from joint_space_control.memory import large_blocks_from_the_system
from joint_space_control.ros.control_path import spin_node

#: The environment variable that names the process that started a node
#: (processes/processes.py sets it): once that process is gone, the node stops.
PARENT_PID_ENV = "JSC_PARENT_PID"
#: How often [s] a node looks whether its starting process is still there.
PARENT_POLL = 0.25


def init_error(err: BaseException) -> str:
    """rcl's initialisation error in one line, without its C source locations:
    ``failed to initialize rcl: Couldn't parse params file: '--params-file x.yaml'. Error:
    Error parsing a event near line 3, at /project/src/parse.c:782, at ...``."""
    text = " ".join(str(err).split())
    return re.sub(r",? at /\S+:\d+", "", text).removeprefix("failed to initialize rcl: ")


def init(args: list[str] | None, **kwargs: Any) -> None:
    """``rclpy.init``; a malformed or missing ``--params-file`` or bad ``--ros-args`` is one
    line on stderr and exit code 2 (rclpy raises RCLError with C source locations)."""
    try:
        rclpy.init(args=args, **kwargs)
    except _rclpy.RCLError as err:
        print(f"error: {init_error(err)}", file=sys.stderr)
        sys.exit(2)


def watch_parent(log: Callable[[str], None]) -> threading.Thread | None:
    """Stop this process exactly as SIGTERM does once the process named by
    ``JSC_PARENT_PID`` is gone (``os.getppid()`` no longer that pid: the node was
    re-parented), so that a node never outlives the run that started it, even when that
    process is killed (a Dask worker SIGKILLed mid-run) and cannot stop its nodes. Node
    processes run in sessions of their own (processes.py), so nothing else would reach them.

    A daemon thread polls every :data:`PARENT_POLL` seconds; ``log`` is called once, with
    the reason. Without the variable (a node started by hand or by ``ros2 run``) nothing is
    watched and None is returned."""
    raw = os.environ.get(PARENT_PID_ENV, "")
    try:
        parent = int(raw)
    except ValueError:
        return None

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL)
        log(f"the process that started this node (pid {parent}) is gone: stopping")
        os.kill(os.getpid(), signal.SIGTERM)  # the handler of run_node, in the main thread

    thread = threading.Thread(target=watch, name="jsc-parent-watch", daemon=True)
    thread.start()
    return thread


def run_node(
    factory: Callable[[], Node],
    args: list[str] | None = None,
    executor: Callable[[], Executor] = SingleThreadedExecutor,
) -> None:
    """Create the node and spin it until Ctrl-C or SIGTERM (both shut rclpy down cleanly).

    A node with a ``control_path`` (:class:`~joint_space_control.ros.control_path.ControlPath`)
    has it served in this thread and everything else by an executor in a second thread.

    A configuration error (unknown robot, invalid parameter at start-up, a malformed or
    missing ``--params-file``) is reported on one line and ends the process with exit code 2
    instead of a traceback; so is one the node finds just after its start and stops for
    (its ``exit_error``: a second simulator's /clock discovered late). ``executor`` makes
    the executor that spins it (made before the node, so that a signal during start-up finds
    it whole).

    A node started by :mod:`~joint_space_control.processes.processes` also stops, as on
    SIGTERM, once the process that started it is gone (:func:`watch_parent`).
    """
    # Ctrl-C and SIGTERM are handled here, not by rclpy: rclpy's handlers shut the context
    # down at once, under threads still waiting on it (a SIGSEGV now and then in the stress
    # test). Here a signal stops the loops; the threads leave their waits; then the node is
    # closed and the context shut down (stop latency: one wait, at most 0.2 s).
    init(args, signal_handler_options=SignalHandlerOptions.NO)
    large_blocks_from_the_system()  # a large message's memory goes back when freed
    stopping = threading.Event()
    node = None

    def on_signal(signum: int, frame: Any) -> None:
        stopping.set()
        path = getattr(node, "control_path", None)
        if path is not None:
            path.stop()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)

    def log(message: str) -> None:
        if node is not None:
            node.get_logger().warning(message)
        else:
            print(f"warning: {message}", file=sys.stderr, flush=True)

    watch_parent(log)
    stopped_because = None
    try:
        spinner = executor()
        try:
            node = factory()
        except (ValueError, ParameterException) as err:
            print(f"error: {err}", file=sys.stderr)
            sys.exit(2)
        if not stopping.is_set():
            spin_node(node, getattr(node, "control_path", None), spinner, stopping)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy.RCLError:
        # A signal can shut the context down while the executor builds its wait set; that
        # is the same clean shutdown, not an error.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            stopped_because = getattr(node, "exit_error", None)
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()
    if stopped_because:  # the node stopped itself on bad input found after its start
        print(f"error: {stopped_because}", file=sys.stderr)
        sys.exit(2)
