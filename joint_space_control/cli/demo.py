"""The default closed loop: planar_2dof, PD + g(q), a step, in lockstep, headless; the run
is recorded to a bag and analysed into a report, as a user would with the recorder and
``jsc analyze``."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

from joint_space_control.cli import analyze
from joint_space_control.experiments.loop import ClosedLoop
from joint_space_control.paths import config_file

JOINTS = ["joint1", "joint2"]
SETPOINT = [0.5, -0.3]


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc demo``."""
    p = subparsers.add_parser(
        "demo",
        help="run the default closed loop (planar_2dof, PD + g(q), "
        "a step) headless and write its results",
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    p.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    p.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS domain for the run (default: one no other run on this machine uses)",
    )
    p.set_defaults(handler=lambda args: run(args.out, args.duration, args.domain_id))


def _params(name: str) -> dict:
    return yaml.safe_load(config_file(name).read_text())["/**"]["ros__parameters"]


def run(out: Path, duration: float, domain_id: int | None) -> int:
    out.mkdir(parents=True, exist_ok=True)
    bag, report = out / "bag", out / "report"
    for previous in (bag, report):  # the demo's own outputs from an earlier run
        if previous.exists():
            shutil.rmtree(previous)
    print(
        f"jsc demo: planar_2dof, PD + g(q), step to {SETPOINT} rad, {duration:g} s "
        f"simulated in lockstep, recorded to {bag}"
    )
    try:
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
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc demo failed: {err}\nnode logs: {out / 'logs'}", file=sys.stderr)
        return 1
    error = np.array(SETPOINT) - q[-1]
    print(
        f"live run: final error q_d - q = {np.array2string(error, precision=6)} rad "
        f"(max |e| = {np.max(np.abs(error)):.2e} rad)"
    )
    return analyze.run(bag, report)
