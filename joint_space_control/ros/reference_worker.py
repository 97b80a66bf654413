"""References built in a process of their own, so that the control loop never waits for one.

A controller's reference arrives as the serialized bytes of a JointTrajectory. Reading,
validating and splining it is about a second of Python for 100,000 points; in a thread of
the controller's own process it would share the interpreter with the control loop, which
then waits up to the interpreter's switch interval (5 ms) and longer for the C calls between
(stretched periods of 30-70 ms were measured). :class:`ReferenceBuilder` therefore builds
a large reference (more than :data:`IN_THREAD_BYTES`) in a child process — started at the
first such reference and kept, about half a second to start — and a small one, which takes
a few milliseconds, in the calling thread.

The child gets the bytes over a pipe and sends back the prepared
:class:`~joint_space_control.trajectories.reference.Trajectory` pickled with protocol 5: its
arrays travel as out-of-band buffers and become the arrays of the parent's trajectory
without a copy, so the parent does O(arrays) work, not O(points). The child ignores SIGINT
(the node handles Ctrl-C and stops it) and ends when the pipe closes, including when the
node is killed.

The child runs at the lowest priority (nice 19, in a session and so an autogroup of its own,
whose nice it raises too: with autogroups, nice alone only ranks the tasks of one session),
so on a busy machine its second of work waits for the control loops, the plant's included.
What stays in the node is rclpy's copy of the message when it is taken: about 10 ms for a
100,000-point, two-joint reference (4 MB), one stretched period (docs/performance.md).
"""

from __future__ import annotations

import gc
import os
import pickle
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Sequence
from multiprocessing.connection import Connection

import numpy as np

from joint_space_control.memory import give_back_free_memory
from joint_space_control.ros.messages import JointOrder, trajectory_from_bytes
from joint_space_control.trajectories.reference import Trajectory

#: A reference of at most this many serialized bytes (about 4,000 points of two joints or
#: 1,500 of seven) is built in the calling thread; a larger one in the child process.
IN_THREAD_BYTES = 256 * 1024


def build_reference(
    raw: bytes,
    joints: Sequence[str],
    now: float,
    position_limits: tuple[np.ndarray, np.ndarray] | None,
) -> Trajectory | str:
    """The validated trajectory with its spline prepared, or why it is rejected. The cyclic
    garbage collector is off meanwhile: a full collection among the 100,000 objects of a
    large reference would hold the interpreter for ~100 ms (reference counting frees them;
    nothing they make is cyclic)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        trajectory = trajectory_from_bytes(raw, JointOrder(joints), now, 0, position_limits)
        return trajectory.prepared()
    except ValueError as err:
        return str(err)
    finally:
        if enabled:
            gc.enable()


class ReferenceBuilder:
    """Builds references off the control path (module docstring); one call at a time, from
    the node's reference thread."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._process: subprocess.Popen | None = None
        self._conn: Connection | None = None
        self._closed = False

    def build(
        self,
        raw: bytes,
        joints: Sequence[str],
        now: float,
        position_limits: tuple[np.ndarray, np.ndarray] | None,
    ) -> Trajectory | str:
        """:func:`build_reference`, in the child process for a large reference."""
        if len(raw) <= IN_THREAD_BYTES:
            return build_reference(raw, joints, now, position_limits)
        with self._lock:
            if self._closed:
                return "the controller is shutting down"
            try:
                conn = self._connection()
                conn.send((tuple(joints), now, position_limits))
                conn.send_bytes(raw)
                kind, value = conn.recv()
                if kind == "rejected":
                    return value
                header = conn.recv_bytes()
                buffers = [conn.recv_bytes() for _ in range(value)]
                return pickle.loads(header, buffers=buffers)
            except (OSError, EOFError, pickle.UnpicklingError) as err:
                self._stop()  # a new child for the next reference
                return f"the reference worker process failed ({err or type(err).__name__})"

    @property
    def process_id(self) -> int | None:
        """The child's pid while it runs (started by the first large reference)."""
        return None if self._process is None else self._process.pid

    def close(self) -> None:
        """Stop the child (a reference being built is dropped); idempotent, any thread."""
        self._closed = True
        self._stop()

    def _connection(self) -> Connection:
        if self._conn is None:
            parent, child = socket.socketpair()
            self._process = subprocess.Popen(
                [sys.executable, "-m", __name__, str(child.fileno())],
                pass_fds=(child.fileno(),),
                stdin=subprocess.DEVNULL,
                start_new_session=True,  # an autogroup of its own: see main()
            )
            child.close()
            self._conn = Connection(parent.detach())
        return self._conn

    def _stop(self) -> None:
        conn, process = self._conn, self._process
        self._conn = self._process = None
        if conn is not None:
            conn.close()  # an idle child reads the end of the pipe and exits
        if process is not None:
            try:
                process.wait(timeout=0.5)
            except subprocess.TimeoutExpired:  # busy with a reference nobody will take
                process.kill()
                process.wait()


def serve(conn: Connection) -> None:
    """The child's loop: a request (joints, now, limits) and the bytes, then the answer:
    ("rejected", reason), or ("trajectory", number of buffers), the pickle and its buffers."""
    while True:
        try:
            joints, now, limits = conn.recv()
            raw = conn.recv_bytes()
        except (EOFError, OSError):
            return  # the node closed the pipe or is gone
        result = build_reference(raw, joints, now, limits)
        del raw
        give_back_free_memory()  # the message's objects, freed: this process stays small
        try:
            if isinstance(result, str):
                conn.send(("rejected", result))
                continue
            buffers: list[pickle.PickleBuffer] = []
            header = pickle.dumps(result, protocol=5, buffer_callback=buffers.append)
            conn.send(("trajectory", len(buffers)))
            conn.send_bytes(header)
            for buffer in buffers:
                conn.send_bytes(buffer.raw())
        except (BrokenPipeError, ConnectionResetError):
            return
        del result, buffers


def main(argv: list[str]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the node's; it stops us
    os.nice(19)  # background work: on a busy machine the control loop goes first
    try:  # with autogroups, nice only ranks the tasks of one session: rank the session too
        with open("/proc/self/autogroup", "w") as autogroup:
            autogroup.write("19")
    except OSError:
        pass
    serve(Connection(int(argv[1])))


if __name__ == "__main__":
    main(sys.argv)
