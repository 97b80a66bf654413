"""The default closed loop: planar_2dof, PD + g(q), a step, in lockstep, headless."""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import yaml

from joint_space_control.experiments.loop import ClosedLoop
from joint_space_control.paths import config_file

JOINTS = ["joint1", "joint2"]
SETPOINT = [0.5, -0.3]


def _params(name: str) -> dict:
    return yaml.safe_load(config_file(name).read_text())["/**"]["ros__parameters"]


def run(out: Path, duration: float, domain_id: int) -> int:
    out.mkdir(parents=True, exist_ok=True)
    print(
        f"jsc demo: planar_2dof, PD + g(q), step to {SETPOINT} rad, {duration:g} s "
        f"simulated in lockstep (ROS domain {domain_id})"
    )
    try:
        with ClosedLoop(
            out / "logs",
            domain_id,
            "planar_2dof",
            controller_params=_params("pd_gravity_controller.yaml"),
            sim_params=_params("sim_bridge.yaml"),
        ) as loop:
            loop.start(JOINTS, [SETPOINT])
            loop.run_until(duration)
            t, q, dq, tau = loop.probe.recording.arrays()
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc demo failed: {err}\nnode logs: {out / 'logs'}", file=sys.stderr)
        return 1
    csv_path = out / "run.csv"
    with open(csv_path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t"] + [f"{k}_{j}" for k in ("q", "dq", "tau") for j in JOINTS])
        for row in np.column_stack((t, q, dq, tau)):
            writer.writerow([f"{v:.9g}" for v in row])
    png_path = out / "run.png"
    _plot(t, q, tau, png_path)
    error = np.array(SETPOINT) - q[-1]
    print(
        f"final error q_d - q = {np.array2string(error, precision=6)} rad "
        f"(max |e| = {np.max(np.abs(error)):.2e} rad)"
    )
    print(f"wrote {csv_path} ({len(t)} samples), {png_path}, node logs in {out / 'logs'}")
    return 0


def _plot(t: np.ndarray, q: np.ndarray, tau: np.ndarray, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i, name in enumerate(JOINTS):
        (line,) = axes[0].plot(t, q[:, i], label=f"q {name}")
        axes[0].axhline(SETPOINT[i], ls="--", color=line.get_color(), label=f"q_d {name}")
        axes[1].plot(t, tau[:, i], label=f"τ {name}")
    axes[0].set_ylabel("position [rad]")
    axes[1].set_ylabel("torque [N·m]")
    axes[1].set_xlabel("simulation time [s]")
    axes[0].set_title("planar_2dof, PD + gravity compensation, step response")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
