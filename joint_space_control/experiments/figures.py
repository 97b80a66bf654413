"""Figures of a whole experiment (all its runs at once), named in a scenario's ``figures``.

Each figure is a function ``(result, path)`` drawing from the runs' recorded controller
states (``RunResult.state``) and the checks' numbers (``Outcome.numbers``), so that what is
drawn is what was checked. ``result`` is an :class:`~.experiment.ExperimentResult` (typed
loosely here: the experiment module imports this one). matplotlib is imported when a figure
is drawn, not when a scenario is loaded.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

#: Joints drawn at most in a per-joint figure (the ones that move most).
MAX_JOINTS = 4


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _ok_runs(result: Any) -> list[Any]:
    return [r for r in result.runs if r.error is None and r.state is not None]


def _moving_joints(runs: list[Any]) -> list[int]:
    """The joints whose position moved most over the runs (at most MAX_JOINTS), in order."""
    travel = np.zeros(len(runs[0].state.joints))
    for r in runs:
        q = r.state.rows["q"]
        q_d = r.state.rows["q_d"]
        travel = np.maximum(travel, np.ptp(q, axis=0) + np.ptp(q_d, axis=0))
    order = np.argsort(-travel)[:MAX_JOINTS]
    return sorted(int(j) for j in order if travel[j] > 0) or [0]


def overlay(result: Any, path: Path) -> None:
    """Every run's joint positions against time on one set of axes per joint, with the
    (first run's) reference dashed: the runs of a comparison side by side."""
    runs = _ok_runs(result)
    if not runs:
        return
    plt = _pyplot()
    joints = _moving_joints(runs)
    fig, axes = plt.subplots(len(joints), 1, figsize=(8, 2.6 * len(joints)), squeeze=False)
    names = runs[0].state.joints
    for ax, j in zip(axes[:, 0], joints, strict=True):
        first = runs[0].state
        ax.plot(first.stamp, first.rows["q_d"][:, j], "k--", lw=1.0, label="q_d")
        for r in runs:
            ax.plot(r.state.stamp, r.state.rows["q"][:, j], lw=1.2, label=r.label)
        ax.set_ylabel(f"{names[j]} [rad]")
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8, ncol=min(4, len(runs) + 1))
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"{result.scenario.title} ({result.scenario.robot})", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


FIGURES: dict[str, Callable[[Any, Path], None]] = {
    "overlay": overlay,
}


def draw(result: Any) -> list[Path]:
    """Draw the scenario's figures into the experiment's directory; their paths."""
    paths = []
    for name in result.scenario.figures:
        path = result.out / f"{name}.png"
        FIGURES[name](result, path)
        if path.is_file():
            paths.append(path)
    return paths
