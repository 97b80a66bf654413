"""Waiting for a wall-clock deadline as precisely as a Python thread can.

``time.sleep`` wakes up late by the thread's timer slack (50 µs by default on Linux) plus the
scheduler's wake-up latency. The realtime physics thread therefore (1) asks for a timer slack
of 1 ns, and (2) sleeps until :data:`SPIN_NS` before the deadline, then polls the clock with
``time.sleep(0)`` in between, which gives the GIL to the other threads of the process (the
command subscription) at every turn. What is left is the scheduler: on a shared machine
with two cores a tick can still start milliseconds late when both cores are busy.

At SCHED_FIFO priority (``thread_priority``) the thread wakes within the kernel's latency
whatever else runs, and while it polls nothing of normal priority runs on its CPU: the poll
is then :data:`SPIN_FIFO_NS`, and :func:`sleep_until` returns how long it polled so that the
node can show the share of a CPU it takes (``pacing.poll_fraction`` on /diagnostics: at most
spin × rate, 5 % at 1 kHz).
"""

from __future__ import annotations

import ctypes
import sys
import time

#: Sleep until this long [ns] before the deadline, then poll.
SPIN_NS = 150_000
#: The same at SCHED_FIFO priority (the wake-up is then punctual; docs/performance.md).
SPIN_FIFO_NS = 50_000
_PR_SET_TIMERSLACK = 29


def set_timer_slack(ns: int = 1) -> bool:
    """Timer slack of the calling thread (Linux ``prctl``); False where unavailable."""
    if not sys.platform.startswith("linux"):  # pragma: no cover
        return False
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_TIMERSLACK, ns, 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover
        return False


def sleep_until(deadline_ns: int, spin_ns: int = SPIN_NS) -> int:
    """Return at ``deadline_ns`` (``time.perf_counter_ns`` clock) or as soon after as the
    scheduler allows; the result is how long [ns] the thread polled the clock."""
    remaining = deadline_ns - time.perf_counter_ns()
    if remaining > spin_ns:
        time.sleep((remaining - spin_ns) * 1e-9)
    polling = time.perf_counter_ns()
    while time.perf_counter_ns() < deadline_ns:
        time.sleep(0)
    return max(0, time.perf_counter_ns() - polling) if polling < deadline_ns else 0
