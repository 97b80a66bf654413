r"""The figure of a sweep, ``sweep.png``: the runs' metrics side by side. Pure: results in,
figure out (no ROS; matplotlib is imported when drawing).

Per run, from its controller's metrics (``jsc analyze``, analysis/run_metrics.py):

- RMS tracking error [rad]: over the moving reference if it moves, else the whole record;
  the largest over the joints;
- peak |τ| / τ_max: the largest over the joints of the peak command over its effort limit
  (1 = at the limit) when every joint has one, else peak |τ| [N·m];
- saturated fraction [%]: of the record at the effort limit, the largest over the joints;
- 2 % settling time [s] of the first step: the largest over the moving joints, undefined when
  a moving joint never settles within 2 % of its step (or the reference has no step);
- final |q_d − q| [rad]: the error at the end of the record, the largest over the joints.

A quantity no run defines gets no panel. A 1-D sweep (``key`` + ``values``, or ``runs``) is
drawn as one bar chart per quantity. A grid (``variants.grid``) is drawn as one heat map per
quantity: rows (y) the first axis, columns (x) the second, each cell annotated with its
value; a failed run's cell is hatched, an undefined value's cell grey with "n/a", a run not
made (the short form) blank. Axes are labelled with label [unit] and ticked at the grid
values, evenly spaced (a log axis too). With more axes, each combination of their values is
a row of panels. The scenario's theory boundary (workbench/experiments/judging/boundaries.py) is
drawn on
every panel, placed by
:meth:`~joint_space_control.workbench.experiments.scenarios.format.Axis.positions`.

``result`` is an :class:`~joint_space_control.workbench.experiments.experiment.ExperimentResult`,
or
anything with ``scenario`` and ``runs`` whose items have ``label``, ``error`` and, when the
run did not fail, ``controller`` (the controller's metrics dictionary).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from joint_space_control.workbench.experiments.judging import boundaries

#: Heat-map panels per row of a two-axis grid.
PANELS_PER_ROW = 3


def _finite(values: Any) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


def _largest(values: Any) -> float:
    finite = _finite(values)
    return max(finite) if finite else math.nan


def tracking_rms(c: dict) -> float:
    """RMS tracking error [rad]: moving-reference section if any, else the whole record,
    the largest over the joints."""
    te = c.get("tracking_error") or {}
    section = te.get("moving_reference") or te.get("whole_record") or {}
    return _largest((section.get("rms") or {}).values())


def peak_ratio(c: dict) -> float:
    """max_i peak |τ_i| / τ_max,i; NaN when a joint has no effort limit."""
    td = c.get("torque_demand") or {}
    peaks, limits = td.get("peak_abs") or {}, td.get("effort_limits") or {}
    ratios = []
    for joint, peak in peaks.items():
        limit = limits.get(joint)
        if peak is None or limit is None or not math.isfinite(limit) or limit <= 0:
            return math.nan
        ratios.append(peak / limit)
    return _largest(ratios)


def peak_torque(c: dict) -> float:
    """max_i peak |τ_i| [N·m]."""
    return _largest(((c.get("torque_demand") or {}).get("peak_abs") or {}).values())


def saturated_percent(c: dict) -> float:
    """100 × the largest saturated fraction over the joints [%]."""
    return 100.0 * _largest(
        ((c.get("torque_demand") or {}).get("saturated_fraction") or {}).values()
    )


def settling_2(c: dict) -> float:
    """2 % settling time of the first step [s], the largest over the moving joints; NaN if
    one of them never settles, or there is no step."""
    steps = c.get("steps") or []
    if not steps:
        return math.nan
    moving = [j for j in steps[0]["joints"].values() if j.get("moving")]
    times = [j.get("settling_time_2") for j in moving]
    if not moving or len(_finite(times)) < len(times):
        return math.nan
    return max(_finite(times))


def final_error(c: dict) -> float:
    """max_i |q_d,i − q_i| at the end of the record [rad]."""
    return _largest(abs(v) for v in (c.get("final_error") or {}).values() if v is not None)


@dataclass(frozen=True)
class Metric:
    title: str
    value: Callable[[dict], float]
    log: bool = False
    """Coloured on a log scale when its values span more than :data:`LOG_SPAN`."""


LOG_SPAN = 30.0
#: Decades a log colour scale spans at most.
LOG_DECADES = 4

RMS = Metric("RMS tracking error [rad]", tracking_rms, log=True)
PEAK_RATIO = Metric("peak |τ| / effort limit", peak_ratio)
PEAK = Metric("peak |τ| [N·m]", peak_torque)
SATURATED = Metric("saturated fraction [%]", saturated_percent)
SETTLING = Metric("2 % settling time [s]", settling_2, log=True)
FINAL = Metric("final |q_d − q| [rad]", final_error, log=True)


def _ok(runs: Sequence[Any]) -> list[Any]:
    return [r for r in runs if r.error is None]


def sweep_metrics(runs: Sequence[Any]) -> list[tuple[Metric, dict[str, float]]]:
    """(metric, value by run label) of each quantity some run defines (failed runs left
    out); peak |τ| over the effort limit when every run knows every limit, else in N·m."""
    ok = _ok(runs)
    peak = PEAK_RATIO if ok and all(math.isfinite(peak_ratio(r.controller)) for r in ok) else PEAK
    found = []
    for metric in (RMS, peak, SATURATED, SETTLING, FINAL):
        values = {r.label: metric.value(r.controller) for r in ok}
        if _finite(values.values()):  # a panel with no defined value is not drawn
            found.append((metric, values))
    return found


def draw(result: Any, path: Path) -> list[str]:
    """``sweep.png`` of a sweep at ``path``: heat maps of a grid, else bars. The titles of
    the panels drawn (none: nothing defined, no file)."""
    variants = result.scenario.variants
    if variants is None:
        return []
    if variants.axes:
        return heat_maps(result, path)
    return bars(result, path)


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _title(result: Any) -> str:
    return f"{result.scenario.title} ({result.scenario.robot})"


def bars(result: Any, path: Path) -> list[str]:
    """A 1-D sweep: one bar chart per quantity, a bar per run (that did not fail)."""
    panels = sweep_metrics(result.runs)
    if not panels:
        return []
    plt = _pyplot()
    labels = [r.label for r in _ok(result.runs)]
    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.6), squeeze=False)
    for ax, (metric, values) in zip(axes[0], panels, strict=True):
        ax.bar(range(len(labels)), [values[x] for x in labels], color="tab:blue")
        ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
        ax.set_title(metric.title, fontsize=10)
        ax.grid(True, axis="y", alpha=0.3)
    fig.suptitle(_title(result), fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return [metric.title for metric, _ in panels]


# --------------------------------------------------------------------------- heat maps
def tick(value: Any) -> str:
    """A grid value as a tick label: whole numbers as they are (1500, not 1.5e+03), others
    in 3 significant digits, lists joined by /."""
    if isinstance(value, list | tuple):
        return "/".join(tick(v) for v in value)
    if isinstance(value, float):
        if value.is_integer() and abs(value) < 1e6:
            return str(int(value))
        return f"{value:.3g}"
    return str(value)


def cell_text(value: float) -> str:
    """A cell's value in at most ~6 characters: 3 significant digits, or 2.4e-4."""
    if value == 0:
        return "0"
    if 1e-2 <= abs(value) < 1e4:
        return f"{value:.3g}"
    mantissa, exponent = f"{value:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


@dataclass
class Grid:
    """A grid's quantities as arrays of the grid's shape (NaN: undefined or not run)."""

    shape: tuple[int, ...]
    ran: np.ndarray
    failed: np.ndarray
    values: list[tuple[Metric, np.ndarray]]


def grid_values(result: Any) -> Grid:
    """Each run's quantities at its grid index (runs found by label)."""
    variants = result.scenario.variants
    index = {label: variants.grid_index[k] for k, (label, _) in enumerate(variants.runs)}
    shape = variants.shape
    ran, failed = np.zeros(shape, dtype=bool), np.zeros(shape, dtype=bool)
    for r in result.runs:
        if r.label in index:
            ran[index[r.label]] = True
            failed[index[r.label]] = r.error is not None
    values = []
    for metric, by_label in sweep_metrics([r for r in result.runs if r.label in index]):
        array = np.full(shape, math.nan)
        for label, value in by_label.items():
            array[index[label]] = value
        values.append((metric, array))
    return Grid(shape, ran, failed, values)


def _norm(metric: Metric, values: np.ndarray) -> Any:
    from matplotlib.colors import LogNorm, Normalize

    finite = values[np.isfinite(values)]
    lo, hi = float(finite.min()), float(finite.max())
    if metric.log and hi > 0 and hi > LOG_SPAN * lo:
        # at most LOG_DECADES decades: a numerical zero (1e-15 rad) would squeeze the rest
        # into one colour; smaller values take the lowest colour (their text says them)
        return LogNorm(max(lo, hi * 10.0**-LOG_DECADES), hi, clip=True)
    if hi == lo:
        hi = lo + (abs(lo) if lo else 1.0)
    return Normalize(lo, hi)


def _curves(result: Any, further: Sequence[tuple[Any, Any]]) -> tuple[Any, str]:
    """The boundary in the plane of the first two axes with the further axes at ``further``
    ((axis, value) pairs): (curve or None, why it is not drawn)."""
    variants = result.scenario.variants
    if variants.boundary is None:
        return None, ""
    settings = {k: v for axis, v in further for k in axis.settings(v)}
    scenario = result.scenario.with_settings("boundary", settings)
    try:
        return boundaries.curve(variants.boundary, scenario, variants.axes[:2]), ""
    except (ValueError, KeyError) as err:
        return None, f"boundary {variants.boundary} not drawn: {err}"


def heat_maps(result: Any, path: Path) -> list[str]:
    """A grid: one heat map per quantity (per combination of the further axes, a row)."""
    variants = result.scenario.variants
    grid = grid_values(result)
    if not grid.values:
        return []
    plt = _pyplot()
    from matplotlib.patches import Patch, Rectangle

    rows_axis, cols_axis, *further_axes = variants.axes
    combos = [
        c
        for c in itertools.product(*(range(len(a.values)) for a in further_axes))
        if grid.ran[(slice(None), slice(None), *c)].any()
    ]
    n_rows, n_cols = len(rows_axis.values), len(cols_axis.values)
    panel_w, panel_h = max(3.4, 0.8 * n_cols + 1.9), max(2.8, 0.5 * n_rows + 1.6)
    if further_axes:
        layout = [[(c, m) for m in range(len(grid.values))] for c in combos]
    else:
        cells = [((), m) for m in range(len(grid.values))]
        layout = [cells[k : k + PANELS_PER_ROW] for k in range(0, len(cells), PANELS_PER_ROW)]
    width = max(len(row) for row in layout)
    fig, axes = plt.subplots(
        len(layout),
        width,
        figsize=(panel_w * width, panel_h * len(layout) + 0.8),
        squeeze=False,
    )
    notes: set[str] = set()
    boundary_label = ""
    hatched = undefined = False
    for row, panels in zip(axes, layout, strict=True):
        for ax in row[len(panels) :]:
            ax.set_visible(False)
        for ax, (combo, m) in zip(row, panels, strict=False):
            metric, values = grid.values[m]
            at = (slice(None), slice(None), *combo)
            plane, ran, failed = values[at], grid.ran[at], grid.failed[at]
            shown = np.ma.masked_invalid(plane)
            if np.isfinite(plane).any():
                norm = _norm(metric, values)  # one colour scale for every row of panels
                image = ax.imshow(shown, origin="lower", cmap="viridis", norm=norm, aspect="auto")
                fig.colorbar(image, ax=ax, fraction=0.046, pad=0.03)
            else:
                norm = None
                ax.imshow(np.zeros_like(plane), origin="lower", cmap="Greys", vmin=0, vmax=1)
            for i, j in itertools.product(range(n_rows), range(n_cols)):
                if failed[i, j]:
                    ax.add_patch(
                        Rectangle((j - 0.5, i - 0.5), 1, 1, fc="0.85", ec="0.4", hatch="xxx")
                    )
                    hatched = True
                elif ran[i, j] and not math.isfinite(plane[i, j]):
                    ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fc="0.88", ec="none"))
                    ax.text(j, i, "n/a", ha="center", va="center", fontsize=7, color="0.35")
                    undefined = True
                elif math.isfinite(plane[i, j]):
                    dark = norm is not None and norm(plane[i, j]) < 0.55
                    ax.text(
                        j,
                        i,
                        cell_text(plane[i, j]),
                        ha="center",
                        va="center",
                        fontsize=7,
                        color="white" if dark else "black",
                    )
            further = [(a, a.values[k]) for a, k in zip(further_axes, combo, strict=True)]
            curve, why = _curves(result, further)
            if why:
                notes.add(why)
            if curve is not None:
                x = cols_axis.positions(curve.coords[cols_axis.key])
                y = rows_axis.positions(curve.coords[rows_axis.key])
                ax.plot(x, y, color="tab:red", lw=2.0, ls="--")
                boundary_label = curve.label
            ax.set_xlim(-0.5, n_cols - 0.5)
            ax.set_ylim(-0.5, n_rows - 0.5)
            ax.set_xticks(range(n_cols), [tick(v) for v in cols_axis.values], fontsize=8)
            ax.set_yticks(range(n_rows), [tick(v) for v in rows_axis.values], fontsize=8)
            ax.set_xlabel(cols_axis.title, fontsize=9)
            ax.set_ylabel(rows_axis.title, fontsize=9)
            where = ", ".join(f"{a.name} = {tick(v)}" for a, v in further)
            ax.set_title(metric.title + (f"\n{where}" if where else ""), fontsize=10)
    handles = []
    if boundary_label:
        handles.append(plt.Line2D([], [], color="tab:red", lw=2.0, ls="--", label=boundary_label))
    if hatched:
        handles.append(Patch(fc="0.85", ec="0.4", hatch="xxx", label="run failed"))
    if undefined:
        handles.append(Patch(fc="0.88", label="n/a: not defined for the run"))
    if not grid.ran.all():
        handles.append(Patch(fc="white", ec="0.6", label="blank: not run (short form)"))
    height = fig.get_figheight()
    fig.suptitle(_title(result), fontsize=11, y=1 - 0.08 / height, va="top")
    top = 1 - (0.62 if handles else 0.4) / height
    if handles:
        fig.legend(
            handles=handles,
            loc="upper center",
            ncol=len(handles),
            fontsize=8,
            bbox_to_anchor=(0.5, 1 - 0.38 / height),
            frameon=False,
        )
    if notes:
        fig.text(0.5, 0.005, "; ".join(sorted(notes)), ha="center", fontsize=7, color="tab:red")
    fig.tight_layout(rect=(0, 0.25 / height if notes else 0, 1, top))
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return [metric.title for metric, _ in grid.values]
