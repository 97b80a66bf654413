"""Realtime threads at SCHED_FIFO (issue 16): where the system permits it, the plant's
physics thread and command path and the controller's control path run at
``thread_priority`` (50 by default), as the OS reports for those very threads, and say so in
the log and on /diagnostics; the executor thread runs at FIFO priority 1 (it holds the
interpreter the realtime threads need: docs/performance.md), the middleware's reception and
event threads at ``middleware_priority`` (one below by default), the other threads normal.
Where it is refused (here: the node started without CAP_SYS_NICE and with an rtprio limit of
0), the node runs at normal scheduling and says once what to grant. No timing is judged
here (jsc bench measures it)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from joint_space_control.scheduling import MIDDLEWARE_THREADS, fifo_permitted

from .conftest import GAINS
from .test_faults import ROBOT, Rig, rig  # noqa: F401  (the fixture)

# realtime (one at a time): its two FIFO loops beside another test's can leave the probe, at
# normal priority, without the plant's /diagnostics for longer than the test waits
pytestmark = [pytest.mark.integration, pytest.mark.realtime]

SIM, CONTROLLER = "sim_bridge", "pd_gravity_controller"


def threads(pid: int) -> dict[str, tuple[int, int]]:
    """{OS thread name: (policy without the reset-on-fork flag, priority)} of a process."""
    out = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        tid = int(task.name)
        try:
            name = (task / "comm").read_text().strip()
            policy = os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK
            out[name] = (policy, os.sched_getparam(tid).sched_priority)
        except (OSError, ProcessLookupError):  # a thread that just ended
            continue
    return out


@pytest.mark.skipif(not fifo_permitted(), reason="SCHED_FIFO not permitted to the tests")
def test_realtime_threads_run_at_fifo_priority_when_permitted(rig: Rig):  # noqa: F811
    sim = rig.group.start(
        SIM, {"robot": ROBOT, "mode": "realtime", "thread_priority": 40, "lock_memory": True}
    )
    ctrl = rig.group.start(CONTROLLER, {"robot": ROBOT, **GAINS[ROBOT]})
    status = rig.diagnostics(SIM, lambda s: "scheduling.command_path.policy" in s)
    assert status["scheduling.physics.policy"] == "SCHED_FIFO"
    assert status["scheduling.physics.priority"] == 40
    assert status["scheduling.command_path.policy"] == "SCHED_FIFO"
    assert status["scheduling.executor.priority"] == 1
    assert status["memory_locked"] == 1
    locked_kb = [line for line in Path(f"/proc/{sim.proc.pid}/status").read_text().splitlines()]
    assert int(next(line for line in locked_kb if line.startswith("VmLck")).split()[1]) > 1000
    status = rig.diagnostics(CONTROLLER, lambda s: "scheduling.control_path.policy" in s)
    assert status["scheduling.control_path.policy"] == "SCHED_FIFO"
    assert status["scheduling.control_path.priority"] == 50

    # the OS's word, thread by thread: the named realtime threads at FIFO, the middleware's
    # reception and event threads one below them, the rest normal
    plant = threads(sim.proc.pid)
    assert plant.pop("jsc-physics") == (os.SCHED_FIFO, 40)
    assert plant.pop("jsc-command-pat") == (os.SCHED_FIFO, 40)  # 15 characters
    assert plant.pop("jsc-executor") == (os.SCHED_FIFO, 1)  # the interpreter's other holder
    assert pop_middleware(plant) == {(os.SCHED_FIFO, 39)}
    assert plant and all(policy == os.SCHED_OTHER for policy, _ in plant.values())
    control = threads(ctrl.proc.pid)
    assert control.pop("jsc-control-pat") == (os.SCHED_FIFO, 50)
    assert control.pop("jsc-executor") == (os.SCHED_FIFO, 1)
    assert pop_middleware(control) == {(os.SCHED_FIFO, 49)}
    assert control and all(policy == os.SCHED_OTHER for policy, _ in control.values())

    assert "realtime thread physics: SCHED_FIFO priority 40" in sim.log()
    assert "realtime thread control path: SCHED_FIFO priority 50" in ctrl.log()
    assert "SCHED_FIFO priority 39" in next(
        line for line in sim.log().splitlines() if "middleware threads dds." in line
    )
    status = rig.diagnostics(SIM, lambda s: True)
    assert status["scheduling.middleware.priority"] == 39
    assert status["scheduling.middleware.threads"] >= 2  # a reception thread, the events


def pop_middleware(threads_: dict[str, tuple[int, int]]) -> set[tuple[int, int]]:
    """Take Fast DDS's reception and event threads out of ``threads_``: their (policy,
    priority) settings; each kind must be there."""
    names = [n for n in threads_ if MIDDLEWARE_THREADS.fullmatch(n)]
    assert any(n.startswith("dds.ev.") for n in names), threads_
    assert any(n.startswith(("dds.shm.", "dds.udp.")) for n in names), threads_
    return {threads_.pop(n) for n in names}


def test_middleware_priority_zero_leaves_the_middleware_threads_normal(rig: Rig):  # noqa: F811
    sim = rig.group.start(SIM, {"robot": ROBOT, "mode": "realtime", "middleware_priority": 0})
    rig.wait_for_publisher("joint_states")
    status = rig.diagnostics(SIM, lambda s: "scheduling.physics.policy" in s)
    assert status["scheduling.middleware.threads"] == 0
    plant = threads(sim.proc.pid)
    assert {plant[n] for n in plant if MIDDLEWARE_THREADS.fullmatch(n)} == {(os.SCHED_OTHER, 0)}
    assert "middleware threads" not in sim.log()


@pytest.mark.skipif(shutil.which("setpriv") is None, reason="setpriv (util-linux) not found")
def test_a_refused_priority_is_said_once_and_the_loop_runs_normally(rig: Rig):  # noqa: F811
    # no CAP_SYS_NICE (dropped from the bounding set, so also for root) and no rtprio limit
    refused = ["setpriv", "--bounding-set=-sys_nice", "prlimit", "--rtprio=0:0", "--"]
    if shutil.which("prlimit") is None:
        refused = refused[:2]
    sim = rig.group.start(SIM, {"robot": ROBOT, "mode": "realtime"}, prefix=refused)
    ctrl = rig.group.start(CONTROLLER, {"robot": ROBOT, **GAINS[ROBOT]}, prefix=refused)
    rig.wait_for_publisher("joint_states")
    # the loop closes: commands answer the states at normal scheduling
    rig.probe.spin_until(lambda: len(rig.commands) > 100, 20.0, "commands", rig.group.check_alive)
    status = rig.diagnostics(SIM, lambda s: "scheduling.command_path.policy" in s)
    assert status["scheduling.executor.policy"] == "SCHED_OTHER"
    assert status["scheduling.physics.policy"] == "SCHED_OTHER"
    assert status["scheduling.command_path.policy"] == "SCHED_OTHER"
    status = rig.diagnostics(CONTROLLER, lambda s: "scheduling.control_path.policy" in s)
    assert status["scheduling.control_path.policy"] == "SCHED_OTHER"
    for node, threads_ in ((sim, ("physics", "command path")), (ctrl, ("control path",))):
        log = node.log()
        warnings = [line for line in log.splitlines() if "refused" in line]
        assert len(warnings) == 1, log  # once per node, whatever the number of threads
        assert "SCHED_FIFO priority 50 refused: not permitted" in warnings[0]
        assert "CAP_SYS_NICE" in warnings[0] and "rtprio" in warnings[0]
        assert "Traceback" not in log
        assert all(f"realtime thread {t}: SCHED_FIFO" not in log for t in threads_)
