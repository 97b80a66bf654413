"""Other work on the machine, on purpose: a CPU hog on every core, for the realtime runs
of ``jsc bench`` under load (docs/performance.md "Thread priority").

Each hog is a Python process spinning at normal priority. The bench stops them when the
measurement ends, on error or Ctrl-C (:func:`cpu_hog` is a context manager), and a hog
whose parent is gone (the bench killed) stops by itself within milliseconds.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager

#: The hog: spin until its parent is no longer the process that started it.
_HOG = (
    "import os, sys\n"
    "parent = int(sys.argv[1])\n"
    "while os.getppid() == parent:\n"
    "    for _ in range(100_000):\n"
    "        pass\n"
)


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


@contextmanager
def cpu_hog(processes: int | None = None) -> Iterator[list[int]]:
    """``processes`` busy processes (default: one per usable core) while the block runs;
    yields their pids."""
    count = usable_cores() if processes is None else processes
    hogs = [
        subprocess.Popen(
            [sys.executable, "-c", _HOG, str(os.getpid())],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        for _ in range(count)
    ]
    try:
        yield [h.pid for h in hogs]
    finally:
        for hog in hogs:
            if hog.poll() is None:
                hog.send_signal(signal.SIGKILL)
        for hog in hogs:
            hog.wait()
