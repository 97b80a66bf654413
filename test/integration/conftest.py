"""Closed loops of real node processes for the integration tests.

Every test gets its own ROS domain and localhost-only discovery; every process it starts is
stopped when the test ends, passed or failed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from joint_space_control.processes.domains import DomainLease, lease_domain
from joint_space_control.processes.loop import ClosedLoop

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


_leases: list[DomainLease] = []

#: A failed test's report ends with the last lines of each node's log under its tmp_path
#: (a failure in CI is read from its output alone: which node said what, and when).
NODE_LOG_LINES = 25
NODE_LOGS = 12  # at most this many logs


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()
    tmp = getattr(item, "funcargs", {}).get("tmp_path")
    if report.when != "call" or not report.failed or tmp is None:
        return
    for log in sorted(Path(tmp).rglob("*.log"))[:NODE_LOGS]:
        tail = log.read_text(errors="replace").splitlines()[-NODE_LOG_LINES:]
        report.sections.append((f"node log {log.relative_to(tmp)}", "\n".join(tail)))


def next_domain_id() -> int:
    """A ROS domain no other test (worker or concurrent run) on this machine uses; held
    until the end of the current test."""
    lease = lease_domain()
    _leases.append(lease)
    return lease.domain_id


@pytest.fixture(autouse=True)
def _release_domains() -> Iterator[None]:
    yield
    while _leases:
        _leases.pop().release()


from test.loops import GAINS, JOINTS, SETPOINTS  # noqa: E402, F401  (shared)


@pytest.fixture
def make_loop(tmp_path: Path) -> Iterator[Any]:
    """Factory of lockstep loops (planar_2dof or iiwa; PD controller by default, with the
    robot's GAINS unless overridden); all closed at the end."""
    loops: list[ClosedLoop] = []

    def make(
        robot: str,
        controller_params: dict[str, Any] | None = None,
        controller: str = "pd_gravity_controller",
        sim_params: dict[str, Any] | None = None,
        record: Path | None = None,
    ) -> ClosedLoop:
        loop = ClosedLoop(
            tmp_path / f"run{len(loops)}",
            None,  # leased: no other loop on the machine shares it
            robot,
            controller,
            controller_params={**GAINS[robot], **(controller_params or {})},
            sim_params=sim_params,
            record=record,
        )
        loops.append(loop)
        return loop

    yield make
    for loop in loops:
        loop.close()


def interrupt_once_running(
    args: list[str], pattern: str, under: Path, running: float
) -> tuple[subprocess.Popen, str, list[str]]:
    """Run ``python -m joint_space_control.cli.main *args``, send it SIGINT ``running``
    seconds after a bag matching ``under/pattern`` appeared (a run is under way), and wait
    for it to end. Returns the process, its output and the pids of what it left running
    with ``under`` in its command line (none, if it works): found, then killed, also when
    the test fails."""
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "joint_space_control.cli.main", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    output = ""
    try:
        deadline = time.monotonic() + 120
        while not list(under.glob(pattern)):
            assert proc.poll() is None and time.monotonic() < deadline, "no run started"
            time.sleep(0.2)
        time.sleep(running)
        proc.send_signal(signal.SIGINT)
        output, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        leftovers = subprocess.run(
            ["pgrep", "-f", str(under)], capture_output=True, text=True
        ).stdout.split()
        for pid in leftovers:
            with contextlib.suppress(ProcessLookupError, ValueError):
                os.kill(int(pid), signal.SIGKILL)
    return proc, output, leftovers
