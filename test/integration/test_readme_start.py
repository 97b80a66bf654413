"""The README's five-minute start from ROS, run as written: its node commands, from the
checkout, in a ROS domain of the test's own, bring the arm to the trajectory generator's
step."""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from joint_space_control.processes.probe import LoopProbe
from joint_space_control.processes.processes import isolated_env
from joint_space_control.ros.node_main import PARENT_PID_ENV

from .conftest import next_domain_id

pytestmark = [pytest.mark.integration, pytest.mark.realtime]

ROOT = Path(__file__).resolve().parents[2]


def readme_commands() -> list[str]:
    """The shell commands of the README's "From ROS" block, continuation lines joined and
    comments dropped."""
    text = (ROOT / "README.md").read_text()
    start = text.index("### From ROS")
    block = re.search(r"```bash\n(.*?)```", text[start:], re.S)
    assert block is not None
    joined = block.group(1).replace("\\\n", " ")
    return [line.split("  #")[0].strip() for line in joined.splitlines() if line.strip()]


def test_the_readme_ros_start_reaches_the_step(tmp_path):
    commands = readme_commands()
    nodes = [c for c in commands if not c.startswith(".venv/bin/jsc ")]
    assert [shlex.split(c)[0] for c in nodes] == [
        ".venv/bin/sim_bridge",
        ".venv/bin/pd_gravity_controller",
        ".venv/bin/trajectory_generator",
    ]
    assert ".venv/bin/jsc view" in commands  # the page: test_dashboard.py drives it
    generator = yaml.safe_load((ROOT / "config" / "trajectory_generator.yaml").read_text())
    target = np.array(generator["/**"]["ros__parameters"]["target"])
    domain = next_domain_id()
    env = {**isolated_env(domain), PARENT_PID_ENV: str(os.getpid())}  # they stop if we die
    processes = []
    probe = LoopProbe(domain, name="readme_probe")
    try:
        for k, command in enumerate(nodes):
            log = open(tmp_path / f"node{k}.log", "w")  # noqa: SIM115 - closed with the process
            processes.append(
                (
                    subprocess.Popen(
                        shlex.split(command),
                        cwd=ROOT,
                        env=env,
                        stdout=log,
                        stderr=subprocess.STDOUT,
                        start_new_session=True,
                    ),
                    log,
                )
            )

        def arrived() -> bool:
            for process, _ in processes:
                if process.poll() is not None:
                    raise RuntimeError(f"{process.args[0]} exited with {process.returncode}")
            states = probe.recording
            if not states.stamps:
                return False
            _, q, dq, _ = states.arrays()
            return bool(np.abs(q[-1] - target).max() < 1e-3 and np.abs(dq[-1]).max() < 1e-2)

        # a correctness bound, not a speed one: the step settles in about a second of
        # simulated time; a minute of wall time covers the start of three processes
        probe.spin_until(arrived, 60.0, "the arm at the step's target")
    finally:
        probe.close()
        for process, _ in processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
        for process, log in processes:
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            log.close()
    for k, _ in enumerate(nodes):
        assert "Traceback" not in (tmp_path / f"node{k}.log").read_text()
