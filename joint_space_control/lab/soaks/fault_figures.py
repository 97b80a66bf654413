"""A fault soak's timeline + outcomes → one PNG figure (matplotlib, Agg backend).

:func:`fault_figure` draws the tracking error e = maxⱼ |q_d,ⱼ − qⱼ| [rad] over the whole run
(log scale, wall time in minutes from the start) with the tracking bound dashed, and every
fault: a line at its start and a band until tracking was back (its end plus the recovery
time, or the next fault when it never was), coloured by kind (legend), numbered at the top
from 1 as the soak prints them; a fault after which tracking did not come back is marked ✗.
Stretches without controller rows (a dead controller, a recorder down) are left blank.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from joint_space_control.analysis.figures import DPI, minmax_decimate
from joint_space_control.lab.soaks.fault_metrics import (
    KINDS,
    FaultOutcome,
    FaultRecord,
    FaultThresholds,
    Timeline,
)

#: Smallest error drawn [rad] (an exact zero has no place on a log axis).
FLOOR = 1e-7


#: Colours of the kinds: tab10 without its grey (the grid's), then navy and gold.
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#bcbd22",
    "#17becf",
    "#000080",
    "#ffd700",
)


def kind_colours(kinds: Sequence[str]) -> dict[str, tuple[float, float, float]]:
    """An RGB colour (0–1) per kind: :data:`KINDS` always get the same, in order, from
    :data:`PALETTE`; other kinds the next ones (cycling)."""
    from matplotlib.colors import to_rgb

    order = [*KINDS, *sorted(set(kinds) - set(KINDS))]
    return {kind: to_rgb(PALETTE[k % len(PALETTE)]) for k, kind in enumerate(order)}


def plotted_error(
    t: np.ndarray, error: np.ndarray, max_gap: float
) -> tuple[np.ndarray, np.ndarray]:
    """(t, e) to draw: min/max decimated (:func:`.figures.minmax_decimate`), floored at
    :data:`FLOOR`, with a NaN between two rows more than ``max_gap`` [s] apart so that the
    line breaks where there was no controller row."""
    e = np.where(np.isnan(error), np.nan, np.maximum(error, FLOOR))
    gap = np.flatnonzero(np.diff(t) > max_gap)
    keep = np.unique(np.concatenate((minmax_decimate(np.nan_to_num(e, nan=FLOOR)), gap, gap + 1)))
    tk, ek = t[keep], e[keep]
    breaks = np.flatnonzero((np.diff(keep) == 1) & (np.diff(tk) > max_gap)) + 1
    return np.insert(tk, breaks, np.nan), np.insert(ek, breaks, np.nan)


def fault_figure(
    timeline: Timeline,
    faults: Sequence[FaultRecord],
    path: str | Path,
    outcomes: Sequence[FaultOutcome] = (),
    thresholds: FaultThresholds | None = None,
    title: str = "Fault soak",
) -> Path:
    """Write the figure of the run to ``path`` (PNG) and return it (see the module); the
    bound and the row gaps from ``thresholds`` (default :class:`.FaultThresholds`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    path = Path(path)
    thresholds = thresholds or FaultThresholds()
    starts = [f.start for f in faults]
    origins = [x for x in (timeline.start, *starts) if math.isfinite(x)]
    t0 = min(origins) if origins else 0.0
    back = {o.index: o for o in outcomes}
    colours = kind_colours([f.kind for f in faults])

    width, height = 15.0, 5.5  # [in]
    fig, ax = plt.subplots(figsize=(width, height))
    fig.subplots_adjust(
        left=0.7 / width, right=1 - 2.2 / width, top=1 - 0.9 / height, bottom=0.6 / height
    )
    t, e = plotted_error(timeline.state_wall, timeline.error, thresholds.max_gap_s)
    ax.plot((t - t0) / 60.0, e, color="0.15", lw=0.6, label="tracking error e", zorder=3)
    ax.set_yscale("log")
    ax.axhline(
        thresholds.tracking_bound,
        color="crimson",
        ls="--",
        lw=1.0,
        label=f"bound {thresholds.tracking_bound:g} rad",
    )
    finite = e[np.isfinite(e)]
    low = max(np.percentile(finite, 0.5) / 3 if finite.size else FLOOR, FLOOR)
    high = max(finite.max() * 3 if finite.size else 1.0, thresholds.tracking_bound * 10)
    ax.set_ylim(low, high)

    for fault in faults:
        colour = colours[fault.kind]
        outcome = back.get(fault.index)
        x0 = (fault.start - t0) / 60.0
        if outcome is not None and not math.isnan(outcome.recovery_s):
            x1 = (fault.end + outcome.recovery_s - t0) / 60.0
        elif outcome is not None:
            x1 = (outcome.until - t0) / 60.0
        else:
            x1 = (fault.end - t0) / 60.0
        ax.axvspan(x0, x1, color=colour, alpha=0.3, lw=0, zorder=1)
        ax.axvline(x0, color=colour, lw=1.2, zorder=2)
        ax.text(
            x0,
            1.005,
            str(fault.index + 1),
            transform=ax.get_xaxis_transform(),
            rotation=90,
            ha="center",
            va="bottom",
            fontsize=6,
            color=colour,
        )
        if outcome is not None and math.isnan(outcome.recovery_s):
            ax.text(
                x0,
                0.97,
                "✗",
                transform=ax.get_xaxis_transform(),
                ha="left",
                va="top",
                color="crimson",
                fontsize=9,
                fontweight="bold",
            )

    handles, _ = ax.get_legend_handles_labels()
    kinds = sorted(
        {f.kind for f in faults}, key=lambda k: (KINDS.index(k) if k in KINDS else 99, k)
    )
    handles += [Patch(color=colours[k], label=k) for k in kinds]
    ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
        borderaxespad=0,
        title="faults (band: until back)",
        title_fontsize=8,
    )
    ax.set_xlabel("wall time from the start [min]")
    ax.set_ylabel("e = maxⱼ |q_d − q| [rad]")
    ax.grid(True, which="major", alpha=0.3)
    ends = [timeline.end, *[f.end for f in faults], *[o.until for o in outcomes]]
    span = max([(x - t0) / 60.0 for x in ends if math.isfinite(x)], default=1.0)
    ax.set_xlim(0.0, max(span, 1e-3))
    not_back = sum(math.isnan(o.recovery_s) for o in outcomes)
    verdict = ""
    if outcomes:
        verdict = f" ({not_back} not back, marked ✗)" if not_back else " (every one back)"
    fig.suptitle(
        f"{title}: {len(faults)} faults, tracking error over {span:.1f} min{verdict}",
        fontsize=11,
    )
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path
