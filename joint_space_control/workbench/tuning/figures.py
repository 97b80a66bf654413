"""The figures of ``jsc tune``'s report (matplotlib, Agg): arrays and numbers in, PNG out.

- :func:`history_figure`: each trial's objective against its number, the ones meeting the
  specification apart from the others, failed runs marked, the best so far as a line;
- :func:`step_figure`: the best run's step response per joint against the specification:
  the overshoot bound, the ±2 % (±5 %) band and the settling-time bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from joint_space_control.analysis.spec import Spec

DPI = 110


@dataclass(frozen=True)
class HistoryPoint:
    number: int
    objective: float | None  # None: the run failed
    feasible: bool


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def history_figure(points: Sequence[HistoryPoint], path: Path, title: str) -> Path:
    """Objective per trial (minimised; ≤ 0 where the specification is met), best so far."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.2))
    ok = [p for p in points if p.objective is not None and p.feasible]
    bad = [p for p in points if p.objective is not None and not p.feasible]
    failed = [p for p in points if p.objective is None]
    values = [p.objective for p in ok + bad]
    top = max(values, default=1.0)
    ax.axhspan(min(min(values, default=-1.0), -1.0) * 1.1, 0.0, color="tab:green", alpha=0.07)
    ax.axhline(0.0, color="tab:green", lw=0.8)
    if bad:
        ax.scatter(
            [p.number for p in bad],
            [p.objective for p in bad],
            marker="x",
            color="tab:red",
            label="misses the spec (Σ violations)",
        )
    if ok:
        ax.scatter(
            [p.number for p in ok],
            [p.objective for p in ok],
            marker="o",
            color="tab:green",
            label="meets the spec (−smallest margin)",
        )
    if failed:
        ax.scatter(
            [p.number for p in failed],
            [top] * len(failed),
            marker="v",
            color="0.5",
            label="run failed",
        )
    # feasible objectives are ≤ 0 < every infeasible one: the running minimum is the best
    # feasible trial once there is one, the least violating before
    best, xs, ys = math.inf, [], []
    for p in sorted(points, key=lambda p: p.number):
        if p.objective is not None:
            best = min(best, p.objective)
            xs.append(p.number)
            ys.append(best)
    if xs:
        ax.step(xs, ys, where="post", color="tab:blue", lw=1.5, label="best so far")
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xlabel("trial")
    ax.set_ylabel("objective (minimised; ≤ 0: spec met)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def step_figure(
    t: np.ndarray,
    q: np.ndarray,
    q_d: np.ndarray,
    joints: Sequence[str],
    spec: Spec,
    path: Path,
    title: str,
    notes: Sequence[str] = (),
) -> Path:
    """q(t) and q_d of every joint (one row each) after the step at t[0], with the
    specification drawn where it speaks of the response: the overshoot bound (dotted), the
    ±2 % band (shaded; ±5 % too with a 5 % clause) and the settling bound (dashed)."""
    plt = _pyplot()
    n = len(joints)
    fig, axes = plt.subplots(n, 1, figsize=(8.0, 1.9 + 1.8 * n), sharex=True, squeeze=False)
    t = np.asarray(t, dtype=float) - float(t[0])
    bounds = {c.metric: c.bound for c in spec.clauses if c.op == "<="}
    for k, (ax, joint) in enumerate(zip(axes[:, 0], joints, strict=True)):
        y0, target = float(q[0, k]), float(q_d[0, k])
        step = target - y0
        ax.plot(t, q_d[:, k], color="0.3", ls="--", lw=1.0, label="q_d")
        ax.plot(t, q[:, k], color="tab:blue", lw=1.4, label="q")
        if step != 0.0:
            for band, alpha, name in ((0.05, 0.08, "5 %"), (0.02, 0.18, "2 %")):
                if band == 0.05 and "settling_5pct" not in bounds:
                    continue
                ax.axhspan(
                    target - band * abs(step),
                    target + band * abs(step),
                    color="tab:green",
                    alpha=alpha,
                    label=f"±{name} band",
                )
            if "overshoot" in bounds:
                limit = target + math.copysign(bounds["overshoot"] / 100.0 * abs(step), step)
                ax.axhline(limit, color="tab:red", ls=":", lw=1.2, label="overshoot bound")
        for metric, style in (("settling_2pct", "--"), ("settling_5pct", "-.")):
            if metric in bounds:
                ax.axvline(bounds[metric], color="tab:red", ls=style, lw=1.0, label=metric)
        note = f": {notes[k]}" if k < len(notes) else ""
        ax.set_title(f"{joint}{note}", fontsize=9)
        ax.set_ylabel("q [rad]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    axes[-1, 0].set_xlabel("time after the step [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.35 / fig.get_figheight()))
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
