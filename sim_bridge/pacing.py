"""Waiting for a wall-clock deadline as precisely as a Python thread can.

``time.sleep`` wakes up late by the thread's timer slack (50 µs by default on Linux) plus the
scheduler's wake-up latency. The realtime physics thread therefore (1) asks for a timer slack
of 1 ns, and (2) sleeps until :data:`SPIN_NS` before the deadline, then polls the clock with
``time.sleep(0)`` in between, which gives the GIL to the other threads of the process (the
command subscription) at every turn. What is left is the scheduler: on a shared machine
with two cores a tick can still start milliseconds late when both cores are busy.
"""

from __future__ import annotations

import ctypes
import sys
import time

#: Sleep until this long [ns] before the deadline, then poll.
SPIN_NS = 150_000
_PR_SET_TIMERSLACK = 29


def set_timer_slack(ns: int = 1) -> bool:
    """Timer slack of the calling thread (Linux ``prctl``); False where unavailable."""
    if not sys.platform.startswith("linux"):  # pragma: no cover
        return False
    try:
        return ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_TIMERSLACK, ns, 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover
        return False


def sleep_until(deadline_ns: int, spin_ns: int = SPIN_NS) -> None:
    """Return at ``deadline_ns`` (``time.perf_counter_ns`` clock) or as soon after as the
    scheduler allows."""
    remaining = deadline_ns - time.perf_counter_ns()
    if remaining > spin_ns:
        time.sleep((remaining - spin_ns) * 1e-9)
    while time.perf_counter_ns() < deadline_ns:
        time.sleep(0)
