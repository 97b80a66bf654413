"""Ctrl-C during a command that runs on a pool (``jsc experiment``, ``jsc tune``)."""

from __future__ import annotations

import signal
import sys
import threading
from typing import Any


def cancel_pool(pool: Any, message: str) -> int:
    """Say ``message`` on stderr, cancel the pool's runs (their nodes stopped) and close it,
    ignoring a second Ctrl-C meanwhile (it would cut the stopping short and leave nodes and
    workers behind); exit code 130."""
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    print(message, file=sys.stderr, flush=True)
    try:
        pool.cancel()
    finally:
        pool.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    return 130
