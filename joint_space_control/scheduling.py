"""Scheduling of the threads that must be on time, the way ros2_control does it.

ros2_control's controller manager runs its loop thread at SCHED_FIFO (``thread_priority``,
default 50) when the system permits it and warns when it does not (realtime_tools
``configure_sched_fifo``), with optional CPU affinity and memory locking. The nodes here do
the same for their realtime threads (the plant's physics thread and command path, each
controller's control path): :func:`configure_this_thread` is called by the thread itself.

- ``priority`` 1-99: SCHED_FIFO at that priority, with SCHED_RESET_ON_FORK so that threads
  and processes the thread starts later (a controller's reference thread and process) are
  normal ones; 0: normal scheduling (SCHED_OTHER). A FIFO thread runs before every normal
  one on its CPU whenever it is ready, so a busy machine delays it by the kernel's wake-up
  latency instead of by other processes' time slices. It is refused without CAP_SYS_NICE or
  an rtprio limit of at least the priority (:data:`GRANT`); the thread then stays normal.
- ``cpus``: the CPUs the thread may run on (empty: all the process may use). Pinning a
  realtime thread to a core that nothing else is pinned to keeps its cache warm and its
  neighbours predictable; on two cores it mostly takes choices away from the scheduler.
- ``lock_memory`` (:func:`lock_memory`, whole process): mlockall(MCL_CURRENT | MCL_FUTURE),
  so that no page of the process is swapped out or faulted in lazily in the middle of a
  tick. It helps a machine short of memory; it costs the process's whole size in RAM.

Linux only (elsewhere the settings are refused with the reason); no ROS here.
"""

from __future__ import annotations

import ctypes
import errno
import os
import re
import sys
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

#: What to grant when SCHED_FIFO is refused (one line, as the nodes log it).
GRANT = (
    "grant CAP_SYS_NICE (container: --cap-add=SYS_NICE --ulimit rtprio=99) or an rtprio "
    "limit (/etc/security/limits.conf: '<user> - rtprio 99', then log in again); "
    "docs/performance.md 'Thread priority'"
)
MAX_PRIORITY = 99
_MCL_CURRENT, _MCL_FUTURE = 1, 2
_PR_SET_NAME = 15


@dataclass(frozen=True)
class Scheduling:
    """What a thread runs with, and why not what was asked for (``refused``, else "")."""

    thread: str
    policy: str  # "SCHED_FIFO" or "SCHED_OTHER"
    priority: int  # 0 with SCHED_OTHER
    cpus: tuple[int, ...]
    refused: str = ""

    @property
    def text(self) -> str:
        """``control path: SCHED_FIFO priority 50, CPUs 0-1`` (the start-up log line)."""
        how = self.policy + (f" priority {self.priority}" if self.policy == "SCHED_FIFO" else "")
        return f"{self.thread}: {how}, CPUs {cpu_text(self.cpus)}"

    def diagnostics(self) -> dict[str, str | int]:
        """The /diagnostics values, under ``scheduling.<thread>.``."""
        key = "scheduling." + self.thread.replace(" ", "_")
        return {
            f"{key}.policy": self.policy,
            f"{key}.priority": self.priority,
            f"{key}.cpus": cpu_text(self.cpus),
        }


def cpu_text(cpus: Sequence[int]) -> str:
    """``0-3,6`` (ranges of consecutive CPUs)."""
    cpus = sorted(cpus)
    parts: list[str] = []
    i = 0
    while i < len(cpus):
        j = i
        while j + 1 < len(cpus) and cpus[j + 1] == cpus[j] + 1:
            j += 1
        parts.append(str(cpus[i]) if i == j else f"{cpus[i]}-{cpus[j]}")
        i = j + 1
    return ",".join(parts)


def check_priority(value: float) -> int:
    """``thread_priority`` as an int in 0..99, else ValueError with the reason."""
    if isinstance(value, bool) or not float(value).is_integer() or not 0 <= value <= MAX_PRIORITY:
        raise ValueError(
            f"'thread_priority' must be an integer from 0 (normal scheduling) to "
            f"{MAX_PRIORITY}, got {value:g}"
        )
    return int(value)


def middleware_priority(value: float, thread_priority: int) -> int:
    """``middleware_priority`` (-1: one below ``thread_priority``, at least 1, and 0 when
    that is 0) as an int in 0..99, else ValueError with the reason."""
    if isinstance(value, bool) or not float(value).is_integer() or not -1 <= value <= MAX_PRIORITY:
        raise ValueError(
            f"'middleware_priority' must be an integer from -1 (one below thread_priority) "
            f"to {MAX_PRIORITY}, got {value:g}"
        )
    if value == -1:
        return max(thread_priority - 1, 1) if thread_priority > 0 else 0
    return int(value)


def check_cpus(values: Sequence[float], available: Sequence[int] | None = None) -> tuple[int, ...]:
    """``cpu_affinity`` as CPU numbers this process may use (empty: all), else ValueError."""
    usable = sorted(os.sched_getaffinity(0) if available is None else available)
    cpus = []
    for value in values:
        if isinstance(value, bool) or not float(value).is_integer():
            raise ValueError(f"'cpu_affinity' must list CPU numbers, got {list(values)!r}")
        cpus.append(int(value))
    outside = sorted(set(cpus) - set(usable))
    if outside:
        raise ValueError(
            f"'cpu_affinity' names CPU(s) {outside} this process cannot use; usable: "
            f"{cpu_text(usable)}"
        )
    return tuple(sorted(set(cpus)))


def configure_this_thread(
    thread: str,
    priority: int,
    cpus: Sequence[int] = (),
    *,
    set_scheduler: Callable[[int, int, os.sched_param], None] | None = None,
    set_affinity: Callable[[int, Sequence[int]], None] | None = None,
) -> Scheduling:
    """Give the calling thread SCHED_FIFO at ``priority`` (0: leave it normal) and the
    ``cpus`` (empty: leave them), and name it ``jsc-<thread>`` for ``ps -L``/``top -H``.
    What the OS refuses is said in ``refused``; the thread then runs as before. The
    ``set_*`` functions stand in for the os module's (tests)."""
    set_scheduler = set_scheduler or _set_scheduler
    set_affinity = set_affinity or os.sched_setaffinity
    name_this_thread("jsc-" + thread.replace(" ", "-"))
    refused = []
    if cpus:
        try:
            set_affinity(0, cpus)
        except OSError as err:
            refused.append(f"cpu_affinity {cpu_text(cpus)} refused: {_reason(err)}")
    if priority > 0:
        try:
            set_scheduler(0, _fifo(), os.sched_param(priority))
        except (OSError, AttributeError) as err:
            refused.append(f"SCHED_FIFO priority {priority} refused: {_reason(err)}")
    return current(thread, "; ".join(refused))


#: The middleware's threads that deliver a node's messages, by the names Fast DDS gives them:
#: reception of each transport port (``dds.shm.<port>``, ``dds.udp.<port>``,
#: ``dds.tcp.<port>``) and the participant's timed events (``dds.ev.<n>``: heartbeats and
#: acknowledgements of reliable topics, under the locks a publish takes too).
MIDDLEWARE_THREADS = re.compile(r"dds\.(shm|udp|tcp|ev)\.\d+")


def threads_of_this_process() -> dict[int, str]:
    """Every thread of this process: its id → its OS name (empty off Linux)."""
    out = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:  # pragma: no cover - not Linux
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/comm") as f:
                out[int(tid)] = f.read().strip()
        except OSError:  # ended meanwhile
            continue
    return out


def configure_threads(
    names: re.Pattern[str],
    priority: int,
    cpus: Sequence[int] = (),
    *,
    threads: Callable[[], dict[int, str]] = threads_of_this_process,
    set_scheduler: Callable[[int, int, os.sched_param], None] | None = None,
    set_affinity: Callable[[int, Sequence[int]], None] | None = None,
) -> tuple[list[str], str]:
    """Give the threads of this process whose OS names match ``names`` SCHED_FIFO at
    ``priority`` and the ``cpus`` (empty: leave them), as :func:`configure_this_thread`
    does for the calling thread: the threads a library started (the middleware's), which the
    process cannot configure from inside. Returns the names configured and what was refused
    ("" when nothing was)."""
    set_scheduler = set_scheduler or _set_scheduler
    set_affinity = set_affinity or os.sched_setaffinity
    done: list[str] = []
    refused: list[str] = []
    for tid, name in sorted(threads().items()):
        if not names.fullmatch(name):
            continue
        try:
            if cpus:
                set_affinity(tid, cpus)
            set_scheduler(tid, _fifo(), os.sched_param(priority))
        except ProcessLookupError:  # ended meanwhile
            continue
        except (OSError, AttributeError) as err:
            refused.append(f"{name}: SCHED_FIFO priority {priority} refused: {_reason(err)}")
            continue
        done.append(name)
    return done, "; ".join(refused[:1])


def fifo_permitted(priority: int = 1) -> bool:
    """Whether this process may run a thread at SCHED_FIFO ``priority`` (tried in a
    short-lived thread of its own)."""
    result: list[bool] = []

    def probe() -> None:
        try:
            os.sched_setscheduler(0, _fifo(), os.sched_param(priority))
        except (OSError, AttributeError):
            result.append(False)
        else:
            result.append(True)

    thread = threading.Thread(target=probe)
    thread.start()
    thread.join()
    return result[0]


def current(thread: str, refused: str = "") -> Scheduling:
    """The calling thread's policy, priority and CPUs as the OS has them."""
    try:
        policy = os.sched_getscheduler(0) & ~getattr(os, "SCHED_RESET_ON_FORK", 0)
        priority = os.sched_getparam(0).sched_priority
        cpus = tuple(sorted(os.sched_getaffinity(0)))
    except (OSError, AttributeError):  # pragma: no cover - not Linux
        return Scheduling(thread, "SCHED_OTHER", 0, (), refused)
    fifo = policy == getattr(os, "SCHED_FIFO", -1)
    return Scheduling(thread, "SCHED_FIFO" if fifo else "SCHED_OTHER", priority, cpus, refused)


def lock_memory() -> str:
    """mlockall(MCL_CURRENT | MCL_FUTURE) for the whole process: "" when done, else why not."""
    if not sys.platform.startswith("linux"):  # pragma: no cover
        return "lock_memory refused (not Linux)"
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) == 0:
        return ""
    err = ctypes.get_errno()
    hint = " (raise the memlock limit: ulimit -l, or CAP_IPC_LOCK)" if err in (1, 12) else ""
    return f"lock_memory refused ({os.strerror(err)}){hint}"


def _set_scheduler(pid: int, policy: int, param: os.sched_param) -> None:
    os.sched_setscheduler(pid, policy, param)


def _fifo() -> int:
    return os.SCHED_FIFO | getattr(os, "SCHED_RESET_ON_FORK", 0)


def _reason(err: BaseException) -> str:
    if isinstance(err, OSError) and err.errno is not None:
        return os.strerror(err.errno) if err.errno != errno.EPERM else "not permitted"
    return str(err) or type(err).__name__


def name_this_thread(name: str) -> None:
    """The OS name of the calling thread (15 characters), best effort."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None).prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)
        except (OSError, AttributeError):  # pragma: no cover
            pass
