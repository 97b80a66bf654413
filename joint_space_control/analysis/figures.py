"""A controller's recorded state + its metrics → PNG figures (matplotlib, Agg backend).

:func:`controller_figures` draws, one subplot per joint against simulation time:

- ``positions.png``: q and q_d [rad];
- ``error.png``: tracking error e = q_d − q [rad];
- ``torques.png``: τ sent [N·m], with the ± effort limits dashed when known;
- ``torque_split.png``: τ_feedback, τ_model, τ_gravity and τ [N·m] (the rows present).

Long records are min/max decimated (:func:`minmax_decimate`) to at most
:data:`MAX_POINTS` points per line, so that peaks survive; the figure says so.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from joint_space_control.analysis.bag import ControllerState

MAX_POINTS = 5000
"""Points per plotted line at most."""
DPI = 110
FIGURE_NAMES = ("positions", "error", "torques", "torque_split")
"""The figures of a controller, file names without ``.png``."""
SPLIT_ROWS = (
    ("tau_feedback", "feedback"),
    ("tau_model", "model"),
    ("tau_gravity", "gravity"),
    ("tau", "total τ (sent)"),
)


def minmax_decimate(y: np.ndarray, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` samples of ``y`` that keep its envelope.

    The record is cut into ``max_points // 2`` buckets and each contributes its minimum and
    maximum sample, in time order (plus the first and last samples); a record that is short
    enough is returned whole.
    """
    n = y.size
    if n <= max_points:
        return np.arange(n)
    buckets = max(max_points // 2 - 1, 1)
    size = -(-n // buckets)  # ceil
    blocks = np.pad(y, (0, buckets * size - n), mode="edge").reshape(buckets, size)
    base = np.arange(buckets) * size
    lo = np.minimum(base + np.argmin(blocks, axis=1), n - 1)
    hi = np.minimum(base + np.argmax(blocks, axis=1), n - 1)
    return np.unique(np.concatenate(([0, n - 1], lo, hi)))


def file_prefix(node: str) -> str:
    """A file-name prefix from a node name: ``/robot1/pd_gravity_controller`` →
    ``robot1_pd_gravity_controller_``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", node).strip("_.") + "_"


def _title(metrics: dict, what: str) -> str:
    parts = [metrics["node"]]
    if metrics.get("robot"):
        parts.append(str(metrics["robot"]))
    parts.append(f"law: {metrics['law']}" if metrics.get("law") else "law: unknown (no config)")
    return f"{what} — " + ", ".join(parts)


class _JointFigure:
    """One subplot per joint against time, drawn and saved several times.

    The figure, its axes and their ticks are built once and only the curves change between
    two saves: building a 7-axes figure costs as much as drawing it. Margins are fixed [in]
    and the legends sit right of the axes: no layout engine and no "best" legend search,
    each of which redraws every point.
    """

    def __init__(self, joints: tuple[str, ...]) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        self._plt = plt
        self.decimated = False
        n = len(joints)
        width, height = 10.0, 1.0 + 1.9 * n  # [in]
        self.fig, axes = plt.subplots(n, 1, figsize=(width, height), sharex=True, squeeze=False)
        self.axes = list(axes[:, 0])
        self.fig.subplots_adjust(
            left=0.8 / width,
            right=1.0 - 1.9 / width,
            top=1.0 - 0.75 / height,
            bottom=0.5 / height,
            hspace=0.45,
        )
        for ax, joint in zip(self.axes, joints, strict=True):
            # an explicit y skips the automatic title placement (a tight bbox per draw)
            ax.set_title(joint, fontsize=9, loc="left", y=1.0, pad=3)
            ax.grid(True, alpha=0.3)
        self.axes[-1].set_xlabel("simulation time [s]")

    def plot(self, ax, t: np.ndarray, y: np.ndarray, **kwargs) -> None:
        """``ax.plot`` of (t, y), min/max decimated to at most :data:`MAX_POINTS` points."""
        index = minmax_decimate(y)
        self.decimated |= index.size < y.size
        ax.plot(t[index], y[index], **kwargs)

    def save(self, draw, title: str, samples: int, path: Path) -> Path:
        """``draw(ax, j)`` on the axes of every joint j, then write ``path``."""
        self.decimated = False
        for j, ax in enumerate(self.axes):
            for artist in [*ax.lines, *ax.collections]:
                artist.remove()
            ax.relim()
            ax.set_prop_cycle(None)
            draw(ax, j)
            ax.autoscale_view()
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0)
        if self.decimated:
            title += f"\n({samples} samples, min/max decimated to ≤ {MAX_POINTS} points per line)"
        self.fig.suptitle(title, fontsize=11)
        self.fig.savefig(path, dpi=DPI)
        return path

    def close(self) -> None:
        self._plt.close(self.fig)


def controller_figures(
    state: ControllerState, metrics: dict, out_dir: Path, prefix: str = ""
) -> dict[str, Path]:
    """Write the four figures of one controller into ``out_dir``; name → path.

    ``metrics`` is the controller's entry of the metrics document (for the title and the
    effort limits); ``prefix`` goes in front of every file name (several controllers).
    """
    t, rows, joints = state.stamp, state.rows, state.joints
    limits = (metrics.get("torque_demand") or {}).get("effort_limits") or {}
    out_dir.mkdir(parents=True, exist_ok=True)
    figure = _JointFigure(joints)
    plot = figure.plot

    def positions(ax, j):
        plot(ax, t, rows["q"][:, j], label="q", color="C0")
        plot(ax, t, rows["q_d"][:, j], label="q_d", color="C1", ls="--")
        ax.set_ylabel("position [rad]")

    def error(ax, j):
        plot(ax, t, rows["q_d"][:, j] - rows["q"][:, j], label="e = q_d − q", color="C3")
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel("error [rad]")

    def torques(ax, j):
        plot(ax, t, rows["tau"][:, j], label="τ", color="C0")
        if (lim := limits.get(joints[j])) is not None:
            ax.axhline(lim, color="C3", ls="--", lw=1.0, label=f"± effort limit {lim:g} N·m")
            ax.axhline(-lim, color="C3", ls="--", lw=1.0)
        ax.set_ylabel("torque [N·m]")

    def split(ax, j):
        for k, (row, label) in enumerate(SPLIT_ROWS):
            if row in rows:
                width = 1.6 if row == "tau" else 1.0
                plot(ax, t, rows[row][:, j], label=label, color=f"C{k}", lw=width)
        ax.set_ylabel("torque [N·m]")

    draws = {
        "positions": (positions, "positions q, q_d"),
        "error": (error, "tracking error e = q_d − q"),
        "torques": (torques, "torques sent τ"),
        "torque_split": (split, "torque split"),
    }
    try:
        return {
            name: figure.save(
                draw, _title(metrics, what), len(state), out_dir / f"{prefix}{name}.png"
            )
            for name, (draw, what) in draws.items()
        }
    finally:
        figure.close()
