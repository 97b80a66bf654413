"""A node never outlives the process that started it: the starting process SIGKILLed (as a
Dask worker dies mid-run), its nodes stop by themselves as on SIGTERM, within about a
second, and the recorder closes its bag on the way out."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

#: The throwaway parent: starts a recorder and a controller the way a run does
#: (processes.py, a leased domain), prints their pids, then waits to be killed.
PARENT = """
import json, sys, time
from pathlib import Path
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.processes import ProcessGroup
out = Path(sys.argv[1])
lease = lease_domain()
group = ProcessGroup(out / "logs", lease.domain_id, (lease.fileno(),))
group.start("recorder", {"output": str(out / "bag")})
group.start("pd_gravity_controller", {"robot": "planar_2dof"})
print(json.dumps({name: node.proc.pid for name, node in group.nodes.items()}), flush=True)
time.sleep(300)
"""


def running(pid: int) -> bool:
    """The process exists and is not a zombie (an exited child nobody reaped yet)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, IndexError):
        return False
    return state != "Z"


def test_nodes_stop_once_the_process_that_started_them_is_killed(tmp_path):
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    pids: dict[str, int] = {}
    try:
        pids = json.loads(parent.stdout.readline())
        assert set(pids) == {"recorder", "pd_gravity_controller"}
        logs = {name: tmp_path / "logs" / f"{name}.log" for name in pids}
        deadline = time.monotonic() + 60
        # both up: the recorder has its bag open, the controller has its control path
        while not (
            (tmp_path / "bag" / "bag.mcap").is_file()
            and "control path" in logs["pd_gravity_controller"].read_text()
        ):
            assert time.monotonic() < deadline, "the nodes did not start"
            assert all(running(pid) for pid in pids.values()), "a node exited early"
            time.sleep(0.1)
        assert all(running(pid) for pid in pids.values())

        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        killed = time.monotonic()
        while any(running(pid) for pid in pids.values()) and time.monotonic() - killed < 10:
            time.sleep(0.05)
        took = time.monotonic() - killed
        assert not any(running(pid) for pid in pids.values()), "a node outlived its parent"
        assert took < 3.0, f"the nodes took {took:.1f} s to stop"
        for name, log in logs.items():
            text = log.read_text()
            assert f"the process that started this node (pid {parent.pid}) is gone" in text, (
                name,
                text[-2000:],
            )
        # stopped as on SIGTERM: the recorder closed its bag (metadata written)
        assert (tmp_path / "bag" / "metadata.yaml").is_file()
        assert "recorder: closed" in logs["recorder"].read_text()
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        for pid in pids.values():
            with contextlib.suppress(ProcessLookupError):
                if running(pid):
                    os.kill(pid, signal.SIGKILL)
