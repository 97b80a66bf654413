"""The default closed loop of ``jsc demo``: planar_2dof, PD + g(q), a step, in lockstep,
headless, recorded to a bag (analysed by the caller, as a user would with the recorder and
``jsc analyze``).

The run is library code, not CLI code, so that the command line only reports: it is the
same :class:`~joint_space_control.experiments.loop.ClosedLoop` the scenarios use, with the
nodes' installed parameter files.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from joint_space_control.experiments.loop import ClosedLoop
from joint_space_control.paths import config_file

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
