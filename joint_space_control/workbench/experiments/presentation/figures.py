"""Figures of a whole experiment (all its runs at once), named in a scenario's ``figures``.

Each figure is a function ``(result, path)`` drawing from the runs' recorded controller
states (``RunResult.state``) and the checks' numbers (``Outcome.numbers``), so that what is
drawn is what was checked. ``result`` is an
:class:`~joint_space_control.workbench.experiments.experiment.ExperimentResult` (typed loosely
here:
the experiment module imports this one). matplotlib is imported when a figure is drawn, not
when a scenario is loaded.
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


def _numbers(result: Any, check: str) -> list[dict]:
    return [o.numbers for o in result.outcomes if o.check == check and o.numbers]


def targets(result: Any, path: Path) -> None:
    """Accuracy and repeatability as targets (the ``repeatability`` check's numbers): per
    group, at its own scale, the true final positions of the runs relative to the target
    (first two joints, mrad), their mean (accuracy: its distance from the centre), the
    repeatability circle around the mean, and the dead band of PD + g (dotted) where the
    plant has friction."""
    groups = _numbers(result, "repeatability")
    if not groups:
        return
    plt = _pyplot()
    from matplotlib.patches import Circle, Rectangle

    fig, axes = plt.subplots(1, len(groups), figsize=(4.2 * len(groups), 4.2), squeeze=False)
    for ax, g in zip(axes[0], groups, strict=True):
        err = 1e3 * (np.array(g["finals"])[:, :2] - np.array(g["target"][:2]))
        mean = 1e3 * np.array(g["offset"][:2])
        band = 1e3 * np.array(g["band"][:2])
        if np.any(band > 0):
            ax.add_patch(
                Rectangle(-band, 2 * band[0], 2 * band[1], fill=False, ls=":", color="grey")
            )
        ax.add_patch(Circle(mean, 1e3 * g["repeatability"], fill=False, color="tab:blue"))
        ax.axhline(0, color="k", lw=0.8)
        ax.axvline(0, color="k", lw=0.8)
        ax.plot(err[:, 0], err[:, 1], "o", color="tab:blue", ms=5, label="final positions")
        ax.plot(*mean, "x", color="tab:red", ms=10, mew=2, label="mean (accuracy)")
        # each target at its own scale: the runs, their mean and the centre in view
        lim = 1.3 * max(np.max(np.abs(err)), np.max(np.abs(mean)) + 1e3 * g["repeatability"])
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{g['joints'][0]} − target [mrad]")
        ax.set_ylabel(f"{g['joints'][1]} − target [mrad]")
        ax.set_title(
            f"{g['group']}: accuracy {1e3 * g['accuracy']:.2g} mrad, "
            f"repeatability {1e3 * g['repeatability']:.2g} mrad",
            fontsize=9,
        )
        ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    fig.suptitle(f"{result.scenario.title} ({result.scenario.robot})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def sampling(result: Any, path: Path) -> None:
    """Overshoot against the control period T_s (the ``sampled_loop`` check's numbers): the
    points measured at the samples, the sampled loop's prediction at the samples and its
    peak between them as curves, the continuous theory, and the
    predicted stability limit; runs that diverged are marked at the top."""
    runs = [n for n in _numbers(result, "sampled_loop") if "period" in n]
    if not runs:
        return
    from joint_space_control.laws.sampled import sampled_step_prediction

    plt = _pyplot()
    kp, kd, h = runs[0]["kp"], runs[0]["kd"], runs[0]["physics_dt"]
    limit = runs[0]["stability_limit"]
    grid = np.arange(1, int(limit / h) + 1) * h
    predictions = [sampled_step_prediction(kp, kd, T, h) for T in grid]
    curve = [p["overshoot_percent_sampled"] for p in predictions]
    peak = [p["overshoot_percent"] for p in predictions]
    omega_n, zeta = np.sqrt(kp), kd / (2 * np.sqrt(kp))
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    ax.plot(1e3 * grid, curve, "-", color="tab:blue", label="prediction at the samples")
    ax.plot(
        1e3 * grid, peak, "-", color="tab:cyan", lw=0.8, label="prediction, peak between samples"
    )
    if zeta < 1:
        m_p = 100 * np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2))
        ax.axhline(m_p, color="grey", ls=":", label=f"continuous theory {m_p:.2g} %")
    ax.axvline(
        1e3 * limit, color="tab:red", ls="--", label=f"predicted limit {1e3 * limit:.3g} ms"
    )
    top = max(max(peak), *(n["overshoot"] or 0 for n in runs if not n["diverged"])) * 1.15
    for n in runs:
        if n["diverged"]:
            ax.plot(1e3 * n["period"], top, "x", color="tab:red", ms=9, mew=2)
        else:
            ax.plot(1e3 * n["period"], n["overshoot"], "o", color="k", ms=5)
    ax.plot([], [], "o", color="k", label="measured")
    ax.plot([], [], "x", color="tab:red", label="measured: diverges")
    ax.set_ylim(0, top * 1.08)
    ax.set_xlabel("control period T_s [ms]")
    ax.set_ylabel("overshoot [%]")
    ax.set_title(
        f"{result.scenario.title}\n(ω_n = {omega_n:.3g} rad/s, ζ = {zeta:.3g}, physics "
        f"{1e3 * h:g} ms)",
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def bode(result: Any, path: Path) -> None:
    """Gain and phase of q against q_d (the ``frequency_response`` check's numbers): the
    measured points beside G(jω) of the theory, and the predicted and measured −3 dB
    bandwidths; full-feedforward runs (exact tracking predicted) drawn apart."""
    points = [n for n in _numbers(result, "frequency_response") if "omega" in n]
    if not points:
        return
    from joint_space_control.laws.second_order import second_order_frequency_response

    plt = _pyplot()
    omega_n, zeta = points[0]["omega_n"], points[0]["zeta"]
    omegas = [n["omega"] for n in points]
    w = np.logspace(np.log10(min(omegas) / 2), np.log10(max(omegas) * 2), 400)
    g = second_order_frequency_response(w, omega_n, zeta)
    fig, (ax_g, ax_p) = plt.subplots(2, 1, figsize=(7.5, 6), sharex=True)
    ax_g.semilogx(w, 20 * np.log10(np.abs(g)), color="tab:blue", label="G(jω), theory")
    ax_p.semilogx(w, np.degrees(np.angle(g)), color="tab:blue")
    for n, marker, label in (
        ([p for p in points if p["regulation"]], "o", "measured, regulation form"),
        ([p for p in points if not p["regulation"]], "s", "measured, full feedforward (→ 1)"),
    ):
        if n:
            x = [p["omega"] for p in n]
            ax_g.semilogx(x, [20 * np.log10(p["gain"]) for p in n], marker, color="k", label=label)
            ax_p.semilogx(x, [np.degrees(p["phase"]) for p in n], marker, color="k")
    summary = [n for n in _numbers(result, "frequency_response") if "bandwidth" in n]
    if summary:
        b = summary[0]
        ax_g.axvline(b["bandwidth_predicted"], color="tab:red", ls="--", label="ω_b predicted")
        if b["bandwidth"] is not None and np.isfinite(b["bandwidth"]):
            ax_g.axvline(b["bandwidth"], color="k", ls=":", label="ω_b measured")
    ax_g.axhline(-3.0103, color="grey", lw=0.8)
    ax_g.set_ylabel("gain [dB]")
    ax_p.set_ylabel("phase [°]")
    ax_p.set_xlabel("ω [rad/s]")
    for ax in (ax_g, ax_p):
        ax.grid(True, which="both", alpha=0.3)
    ax_g.legend(fontsize=8, loc="lower left")
    ax_g.set_title(
        f"{result.scenario.title}\n(ω_n = {omega_n:.3g} rad/s, ζ = {zeta:.3g})", fontsize=10
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def chatter(result: Any, path: Path) -> None:
    """Per run (the ``measurement_noise`` check's numbers): the torque chatter measured and
    predicted, and the true RMS error, per joint, on two panels."""
    rows = _numbers(result, "measurement_noise")
    if not rows:
        return
    plt = _pyplot()
    labels = [o.text.split(" ", 1)[0] for o in result.outcomes if o.check == "measurement_noise"]
    n = len(rows[0]["chatter"])
    x = np.arange(len(rows))
    width = 0.8 / (2 * n)
    fig, (ax_c, ax_e) = plt.subplots(2, 1, figsize=(9, 6.4), sharex=True)
    for j in range(n):
        measured = [r["chatter"][j] for r in rows]
        predicted = [r["chatter_predicted"][j] for r in rows]
        ax_c.bar(x + (2 * j - n + 0.5) * width, measured, width, label=f"joint {j + 1} measured")
        ax_c.bar(
            x + (2 * j - n + 1.5) * width,
            predicted,
            width,
            alpha=0.45,
            label=f"joint {j + 1} predicted",
        )
        errors = [1e3 * (r["true_rms_error"][j] or np.nan) for r in rows]
        ax_e.bar(x + (j - (n - 1) / 2) * 0.8 / n, errors, 0.8 / n, label=f"joint {j + 1}")
    ax_c.set_yscale("log")
    ax_c.set_ylabel("torque chatter RMS [N·m]")
    ax_c.legend(fontsize=7, ncol=2)
    ax_e.set_yscale("log")
    ax_e.set_ylabel("true RMS error [mrad]")
    ax_e.legend(fontsize=7)
    ax_e.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
    for ax in (ax_c, ax_e):
        ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(f"{result.scenario.title} ({result.scenario.robot})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


FIGURES: dict[str, Callable[[Any, Path], None]] = {
    "overlay": overlay,
    "targets": targets,
    "sampling": sampling,
    "bode": bode,
    "chatter": chatter,
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
