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


@pytest.mark.parametrize(
    ("value", "thread_priority", "expected"),
    [(-1, 50, 49), (-1, 1, 1), (-1, 0, 0), (0, 50, 0), (70, 50, 70), (10, 0, 10)],
)
def test_middleware_priority_follows_thread_priority_unless_given(
    value, thread_priority, expected
):
    assert scheduling.middleware_priority(value, thread_priority) == expected


@pytest.mark.parametrize("value", [-2, 100, 1.5, True])
def test_middleware_priority_rejected_with_the_range(value):
    with pytest.raises(ValueError, match="'middleware_priority' must be an integer from -1"):
        scheduling.middleware_priority(value, 50)


def test_the_middleware_threads_are_fast_dds_reception_and_event_threads():
    names = ["dds.shm.24415", "dds.udp.7400", "dds.tcp.9", "dds.ev.0", "dds.shm.wdog", "python"]
    names += ["jsc-physics", "dds.fctrl"]
    matched = [n for n in names if scheduling.MIDDLEWARE_THREADS.fullmatch(n)]
    assert matched == ["dds.shm.24415", "dds.udp.7400", "dds.tcp.9", "dds.ev.0"]


def test_threads_matched_by_name_are_configured_and_a_refusal_said():
    calls = []

    def set_scheduler(tid, policy, param):
        if tid == 3:
            raise PermissionError(errno.EPERM, "no")
        if tid == 4:
            raise ProcessLookupError(errno.ESRCH, "gone")
        calls.append((tid, policy & ~os.SCHED_RESET_ON_FORK, param.sched_priority))

    threads = {1: "dds.shm.1", 2: "python", 3: "dds.ev.0", 4: "dds.udp.2", 5: "dds.udp.3"}
    done, refused = scheduling.configure_threads(
        scheduling.MIDDLEWARE_THREADS, 49, threads=lambda: threads, set_scheduler=set_scheduler
    )
    assert done == ["dds.shm.1", "dds.udp.3"]  # the ended thread is not an error
    assert calls == [(1, os.SCHED_FIFO, 49), (5, os.SCHED_FIFO, 49)]
    assert refused == "dds.ev.0: SCHED_FIFO priority 49 refused: not permitted"


@FIFO
def test_a_thread_of_this_process_is_configured_by_its_name():
    started, stop = threading.Event(), threading.Event()
    seen: list = []

    def body():
        scheduling.name_this_thread("dds.shm.1234")
        started.set()
        stop.wait()
        seen.append((os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))

    thread = threading.Thread(target=body)
    thread.start()
    started.wait()
    try:
        done, refused = scheduling.configure_threads(scheduling.MIDDLEWARE_THREADS, 7)
    finally:
        stop.set()
        thread.join()
    assert (done, refused) == (["dds.shm.1234"], "")
    assert seen == [(os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, 7)]
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the caller is untouched
