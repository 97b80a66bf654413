"""Thread scheduling (issue 16): SCHED_FIFO for the realtime threads when permitted, one
clear refusal otherwise, CPU affinity, and what a thread runs with as the OS says it."""

from __future__ import annotations

import ast
import errno
import os
import shutil
import subprocess
import sys
import threading

import pytest

from joint_space_control import scheduling

FIFO = pytest.mark.skipif(not scheduling.fifo_permitted(), reason="SCHED_FIFO not permitted")


def run_in_thread(fn):
    """fn() in a new thread (so that the test process's own threads keep their settings)."""
    out: list = []
    thread = threading.Thread(target=lambda: out.append(fn()))
    thread.start()
    thread.join()
    return out[0]


@pytest.mark.skipif(
    not scheduling.fifo_permitted(), reason="SCHED_FIFO not permitted to this process"
)
def test_a_permitted_priority_is_in_force_in_that_thread_only():
    def configure():
        got = scheduling.configure_this_thread("control path", 50, ())
        return got, os.sched_getscheduler(0), os.sched_getparam(0).sched_priority

    got, policy, priority = run_in_thread(configure)
    assert (got.policy, got.priority, got.refused) == ("SCHED_FIFO", 50, "")
    # what the OS reports for that thread: FIFO, reset on fork (new threads start normal)
    assert policy == os.SCHED_FIFO | os.SCHED_RESET_ON_FORK and priority == 50
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the calling thread is untouched
    assert (
        got.text == f"control path: SCHED_FIFO priority 50, CPUs {scheduling.cpu_text(got.cpus)}"
    )
    assert got.diagnostics() == {
        "scheduling.control_path.policy": "SCHED_FIFO",
        "scheduling.control_path.priority": 50,
        "scheduling.control_path.cpus": scheduling.cpu_text(got.cpus),
    }


@pytest.mark.skipif(
    not scheduling.fifo_permitted(), reason="SCHED_FIFO not permitted to this process"
)
def test_a_thread_started_by_a_fifo_thread_runs_normally():
    def child_policy():
        scheduling.configure_this_thread("physics", 10, ())
        return run_in_thread(lambda: os.sched_getscheduler(0))

    assert run_in_thread(child_policy) == os.SCHED_OTHER


def test_a_refused_priority_leaves_the_thread_normal_and_says_why():
    def refuse(pid, policy, param):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    got = run_in_thread(
        lambda: scheduling.configure_this_thread("physics", 50, (), set_scheduler=refuse)
    )
    assert (got.policy, got.priority) == ("SCHED_OTHER", 0)
    assert got.refused == "SCHED_FIFO priority 50 refused: not permitted"


def test_priority_zero_asks_for_nothing():
    def never(pid, policy, param):  # pragma: no cover - must not be called
        raise AssertionError("set_scheduler called")

    got = run_in_thread(
        lambda: scheduling.configure_this_thread("physics", 0, (), set_scheduler=never)
    )
    assert (got.policy, got.refused) == ("SCHED_OTHER", "")


def test_affinity_is_applied_to_the_thread_and_a_refusal_said():
    cpu = min(os.sched_getaffinity(0))

    def pinned():
        got = scheduling.configure_this_thread("control path", 0, (cpu,))
        return got, os.sched_getaffinity(0)

    got, cpus = run_in_thread(pinned)
    assert got.cpus == (cpu,) and cpus == {cpu}
    assert os.sched_getaffinity(0) != {cpu} or len(os.sched_getaffinity(0)) == 1

    def refuse(pid, cpus):
        raise OSError(errno.EINVAL, "Invalid argument")

    got = run_in_thread(
        lambda: scheduling.configure_this_thread("physics", 0, (cpu,), set_affinity=refuse)
    )
    assert got.refused == f"cpu_affinity {cpu} refused: Invalid argument"


@pytest.mark.parametrize("value", [0, 1, 50, 99, 50.0])
def test_priorities_accepted(value):
    assert scheduling.check_priority(value) == int(value)


@pytest.mark.parametrize("value", [-1, 100, 50.5, True])
def test_priorities_rejected_with_the_range(value):
    with pytest.raises(ValueError, match=r"'thread_priority' must be an integer from 0"):
        scheduling.check_priority(value)


def test_cpus_checked_against_the_usable_ones():
    assert scheduling.check_cpus([1.0, 0, 1], available=[0, 1]) == (0, 1)
    assert scheduling.check_cpus([], available=[0, 1]) == ()
    with pytest.raises(
        ValueError, match=r"names CPU\(s\) \[7\] this process cannot use; usable: 0-1"
    ):
        scheduling.check_cpus([0, 7], available=[0, 1])
    with pytest.raises(ValueError, match="must list CPU numbers"):
        scheduling.check_cpus([0.5], available=[0, 1])


def test_cpu_text_gives_ranges():
    assert scheduling.cpu_text([0, 1, 2, 3, 6, 8, 9]) == "0-3,6,8-9"
    assert scheduling.cpu_text([5]) == "5"


def test_fifo_permitted_tells_what_a_thread_would_get():
    def try_fifo():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except OSError:
            return False
        return True

    assert scheduling.fifo_permitted() == run_in_thread(try_fifo)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the caller is untouched


LOCK = (
    "from joint_space_control.scheduling import lock_memory\n"
    "print(repr(lock_memory()))\n"
    "print([l for l in open('/proc/self/status') if l.startswith('VmLck')][0].split()[1])\n"
)


def locked(prefix: list[str]) -> tuple[str, int]:
    """lock_memory() in a fresh process (it locks that whole process): its answer and the
    kilobytes the kernel then counts as locked."""
    out = subprocess.run(
        [*prefix, sys.executable, "-c", LOCK], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    return ast.literal_eval(out[0]), int(out[1])


def test_lock_memory_locks_the_process_or_says_why_not():
    answer, kilobytes = locked([])
    if answer == "":  # permitted: the process's pages are locked (VmLck in /proc)
        assert kilobytes > 1000
    else:
        assert answer.startswith("lock_memory refused (") and kilobytes == 0
    if shutil.which("prlimit") and shutil.which("setpriv"):
        # no CAP_IPC_LOCK and a memlock limit of 0: refused, with what to raise
        answer, kilobytes = locked(
            ["setpriv", "--bounding-set=-ipc_lock", "prlimit", "--memlock=0:0", "--"]
        )
        assert answer == (
            "lock_memory refused (Operation not permitted) (raise the memlock limit: "
            "ulimit -l, or CAP_IPC_LOCK)"
        ) or answer.startswith("lock_memory refused (Cannot allocate memory)")
        assert kilobytes == 0
