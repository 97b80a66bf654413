"""The default closed loop of ``jsc demo``: planar_2dof, PD + g(q), a step, in lockstep,
headless, recorded to a bag (analysed by the caller, as a user would with the recorder and
``jsc analyze``); and ``jsc demo --view``: the same robot in realtime with the dashboard.

The run is library code, not CLI code, so that the command line only reports: it is the
same :class:`~joint_space_control.processes.loop.ClosedLoop` the scenarios use, with the
nodes' installed parameter files.
"""

from __future__ import annotations

import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from joint_space_control.paths import config_file
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.loop import ClosedLoop
from joint_space_control.processes.processes import ProcessGroup

JOINTS = ["joint1", "joint2"]
SETPOINT = [0.5, -0.3]
"""The step's target [rad], from the robot's zero configuration."""


@dataclass(frozen=True)
class DemoRun:
    """Where the demo wrote its run, and the live run's final error q_d − q [rad]."""

    bag: Path
    report: Path
    logs: Path
    final_error: np.ndarray


def _params(name: str) -> dict:
    return yaml.safe_load(config_file(name).read_text())["/**"]["ros__parameters"]


def run_demo(
    out: Path, duration: float, domain_id: int | None, log: Callable[[str], None] = print
) -> DemoRun:
    """Run the demo loop for ``duration`` s of simulated time into ``out`` (bag/, logs/;
    report/ is left to the caller). An earlier demo's bag and report there are removed.

    Raises:
        RuntimeError, TimeoutError: a node failed or did not answer (logs in ``out/logs``).
    """
    out.mkdir(parents=True, exist_ok=True)
    bag, report = out / "bag", out / "report"
    for previous in (bag, report):  # the demo's own outputs from an earlier run
        if previous.exists():
            shutil.rmtree(previous)
    log(
        f"planar_2dof, PD + g(q), step to {SETPOINT} rad, {duration:g} s "
        f"simulated in lockstep, recorded to {bag}"
    )
    with ClosedLoop(
        out / "logs",
        domain_id,
        "planar_2dof",
        controller_params=_params("pd_gravity_controller.yaml"),
        sim_params={**_params("sim_bridge.yaml"), "pause_at": duration},  # exact end
        record=bag,
    ) as loop:
        loop.start(JOINTS, [SETPOINT])
        loop.hold_at(duration)
        _, q, _, _ = loop.probe.recording.arrays()
    return DemoRun(bag, report, out / "logs", np.array(SETPOINT) - q[-1])


def run_view_demo(
    out: Path,
    port: int,
    log: Callable[[str], None] = print,
    host: str = "127.0.0.1",
    stop: threading.Event | None = None,
) -> int:
    """The demo's robot in realtime with the dashboard, until ``stop`` is set (Ctrl-C or
    SIGTERM when run from ``jsc demo --view``): sim_bridge and the controller from their
    installed parameter files (the controller on simulation time), the trajectory generator's
    step, the dashboard on ``host``:``port``. Node logs in ``out/logs``. Returns 0; a node that
    exits on its own raises ``RuntimeError`` with its log, a page that never answers
    ``TimeoutError``."""
    import urllib.request

    stop = stop or threading.Event()
    logs = out / "logs"
    with lease_domain() as lease, ProcessGroup(logs, lease.domain_id, (lease.fileno(),)) as group:
        group.start("sim_bridge", _params("sim_bridge.yaml"))
        group.start(
            "pd_gravity_controller",
            {**_params("pd_gravity_controller.yaml"), "use_sim_time": True},
        )
        group.start(
            "trajectory_generator", {**_params("trajectory_generator.yaml"), "use_sim_time": True}
        )
        group.start("dashboard", {"host": host, "port": port})
        url = f"http://{'localhost' if host == '127.0.0.1' else host}:{port}"
        deadline = time.monotonic() + 60.0
        while not stop.is_set():
            group.check_alive()
            try:
                urllib.request.urlopen(url, timeout=1.0).close()
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise TimeoutError(
                        f"the dashboard did not answer on {url} within 60 s"
                    ) from None
                stop.wait(0.2)
        log(
            f"planar_2dof, PD + g(q), realtime, a step to {SETPOINT} rad; dashboard at {url} "
            f"(ROS_DOMAIN_ID={lease.domain_id}; logs in {logs}); Ctrl-C stops it"
        )
        while not stop.wait(0.5):
            group.check_alive()
    return 0
