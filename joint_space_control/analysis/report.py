"""Metrics + figures → ``metrics.json`` and ``report.md`` (text only: no maths, no plotting).

:func:`write_metrics` writes the document of
:func:`~joint_space_control.analysis.run_metrics.analyze_bag` as strict JSON (no NaN
tokens); :func:`write_report` renders it as Markdown with the figures embedded by relative
path, the theory's prediction next to the measured step values for inverse dynamics.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

STEP_COLUMNS = (
    ("rise_time", "rise 10–90 % [s]"),
    ("settling_time_2", "settling 2 % [s]"),
    ("settling_time_5", "settling 5 % [s]"),
    ("overshoot_percent", "overshoot [%]"),
)
PERIOD_COLUMNS = ("mean", "std", "min", "p50", "p99", "max", "max_jitter")


def write_metrics(metrics: dict, path: Path) -> Path:
    """``metrics`` as indented, strict JSON (raises ValueError on a NaN or infinity)."""
    path.write_text(json.dumps(metrics, indent=2, allow_nan=False, ensure_ascii=False) + "\n")
    return path


def fmt(value, digits: int = 4) -> str:
    """A number for a table: ``digits`` significant digits, '—' for None."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A Markdown table; a '|' in a cell (|e|, |τ|) is escaped so it stays in its cell."""

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return [line(header), "|" + "---|" * len(header), *(line(row) for row in rows), ""]


def _configuration(c: dict) -> list[str]:
    config = c.get("config")
    lines = [
        f"- state topic: `{c['state_topic']}`, configuration: "
        + (f"`{c['config_topic']}` ({c['config_count']} received)" if config else "none"),
        f"- robot: {fmt(c.get('robot'))}, law: {fmt(c.get('law'))}, joints: "
        + ", ".join(c["joints"]),
    ]
    samples = c.get("samples") or {}
    if samples:
        lines.append(
            f"- samples analysed: {samples['analysed']} of {samples['messages']} messages "
            f"({samples['duplicate_stamps']} repeated stamps, {samples['resets']} resets, "
            f"{samples['before_last_reset']} before the last reset)"
        )
    lines.append(
        f"- simulation time {fmt(c['time']['start'])} s to {fmt(c['time']['end'])} s "
        f"({fmt(c['time']['duration'])} s)"
    )
    if config:
        rate = config.get("rate")
        lines.append(f"- rate: {fmt(rate)} Hz" if rate is not None else "- rate: —")
        keys = [k for k in ("kp", "kd", "effort_limits") if config.get(k) is not None]
        if keys:
            names = config.get("joints") or c["joints"]
            lines += ["", "Gains and limits (from the configuration):", ""]

            def value(key: str, k: int) -> str:
                v = config[key]
                return fmt(v[k] if isinstance(v, list) and k < len(v) else v)

            labels = {"kp": "K_P", "kd": "K_D", "effort_limits": "effort limit [N·m]"}
            lines += _table(
                ["joint", *(labels[key] for key in keys)],
                [[j, *(value(key, k) for key in keys)] for k, j in enumerate(names)],
            )
    return lines + [""]


def _steps(c: dict) -> list[str]:
    if not c["steps"]:
        return ["No set-point step in this record.", ""]
    predicted = c.get("second_order") is not None
    header = ["joint", "step [rad]"]
    for _, label in STEP_COLUMNS:
        header += [label, "theory"] if predicted else [label]
    header += ["steady-state error [rad]", "max deviation [rad]"]
    lines = []
    for k, step in enumerate(c["steps"], 1):
        end = "end of record" if step["ends_record"] else "next step"
        lines.append(
            f"Step {k} at t = {fmt(step['t_start'])} s, held {fmt(step['duration'])} s "
            f"({step['samples']} samples, until the {end}):"
        )
        lines.append("")
        rows = []
        for joint, m in step["joints"].items():
            row = [joint, fmt(m.get("step")) if m["moving"] else "not moved"]
            theory = m.get("prediction") or {}
            for key, _ in STEP_COLUMNS:
                row.append(fmt(m.get(key)) if m["moving"] else "")
                if predicted:
                    row.append(fmt(theory.get(key)) if m["moving"] else "")
            row += [fmt(m["steady_state_error"]), fmt(m.get("max_deviation"))]
            rows.append(row)
        lines += _table(header, rows)
    if predicted:
        lines.append(
            "*theory*: the nominal inverse-dynamics loop ë + K_D ė + K_P e = 0 per joint "
            "(THEORY.md §3), ω_n = √K_P, ζ = K_D/(2√K_P), exact figures of its analytic "
            "step response. Settling times are measured from the step instant; '—' means the "
            "response had not settled within the step."
        )
        lines.append("")
    return lines


def _second_order(c: dict) -> list[str]:
    so = c.get("second_order")
    if not so:
        return []
    keys = ("kp", "kd", "omega_n", "zeta", "overshoot_percent", "rise_time", "peak_time")
    keys += ("settling_time_2", "settling_time_5")
    head = ["joint", "K_P [1/s²]", "K_D [1/s]", "ω_n [rad/s]", "ζ", "overshoot [%]"]
    head += ["rise [s]", "peak [s]", "settling 2 % [s]", "settling 5 % [s]"]
    lines = ["### Second-order prediction (inverse dynamics, THEORY.md §3)", ""]
    return lines + _table(head, [[j, *(fmt(so[j].get(k)) for k in keys)] for j in so])


def _tracking(c: dict) -> list[str]:
    te = c["tracking_error"]
    whole, moving = te["whole_record"], te.get("moving_reference")
    head = ["joint", "RMS e [rad]", "max |e| [rad]"]
    if moving:
        head += ["RMS e, reference moving [rad]", "max |e|, reference moving [rad]"]
    rows = []
    for j in c["joints"]:
        row = [j, fmt(whole["rms"][j]), fmt(whole["max_abs"][j])]
        if moving:
            row += [fmt(moving["rms"][j]), fmt(moving["max_abs"][j])]
        rows.append(row)
    lines = [
        "### Tracking error e = q_d − q",
        "",
        f"Whole record ({fmt(whole['t_start'])} s to {fmt(whole['t_end'])} s)"
        + (
            f"; reference moving during {fmt(moving['duration'])} s in "
            f"{len(moving['segments'])} segment(s)."
            if moving
            else "; the reference never moves (set-points only)."
        ),
        "",
    ]
    return lines + _table(head, rows)


SATURATION_SOURCES = {
    "effort_limits": "at limit",
    "tau_unclamped": "clamped",
    None: "—",
}


def _torque(c: dict) -> list[str]:
    td = c["torque_demand"]
    head = ["joint", "peak |τ| [N·m]", "peak |τ̇| [N·m/s]", "effort limit [N·m]"]
    head += ["saturated [% of time]", "saturated means"]
    rows = []
    for j in c["joints"]:
        sat = td["saturated_fraction"][j]
        rows.append(
            [
                j,
                fmt(td["peak_abs"][j]),
                fmt(td["peak_rate"][j]),
                fmt(td["effort_limits"][j]),
                fmt(None if sat is None else 100.0 * sat),
                SATURATION_SOURCES[td["saturation_source"][j]],
            ]
        )
    note = (
        "Saturated: *at limit* = |τ| at the configuration's effort limit; *clamped* = the "
        "controller clamped its command (τ_unclamped ≠ τ), used where no limit is known. "
        "Each sample counts until the next one."
    )
    return ["### Torque demand", "", note, ""] + _table(head, rows)


def _periods(c: dict) -> list[str]:
    ps = c["period_statistics"]
    labels = {
        "stamp_period_ms": "state stamps (simulation time)",
        "receive_period_ms": "bag log times (receive time)",
    }
    rows = [
        [label, *(fmt(ps[key][k]) for k in PERIOD_COLUMNS), fmt(ps[key]["count"])]
        for key, label in labels.items()
        if ps.get(key)
    ]
    if not rows:
        return []
    head = ["clock", *(f"{k} [ms]" for k in PERIOD_COLUMNS), "stamps"]
    return ["### Control period", ""] + _table(head, rows)


def _figures(figures: Mapping[str, Path], out_dir: Path) -> list[str]:
    lines = ["### Figures", ""]
    for name, path in figures.items():
        rel = Path(os.path.relpath(path, out_dir)).as_posix()
        lines += [f"![{name}]({rel})", ""]
    return lines


def render_report(metrics: dict, figures: Mapping[str, Mapping[str, Path]], out_dir: Path) -> str:
    """The Markdown report; ``figures`` maps node → figure name → PNG path."""
    bag = metrics["bag"]
    lines = [
        f"# Run analysis: {Path(bag).name if bag else 'a run in process'}",
        "",
        f"- bag: `{bag}` ({metrics['storage']}), {fmt(metrics['duration_s'])} s "
        f"of log time, {metrics['message_count']} messages"
        if bag
        else f"- not recorded: {fmt(metrics['duration_s'])} s of simulated time, "
        f"{metrics['message_count']} messages the nodes would have published",
        "- units: positions in rad, torques in N·m, times in s, control periods in ms",
        "",
    ]
    lines += _table(
        ["topic", "type", "messages"],
        [
            [f"`{t}`", metrics["topic_types"].get(t, "?"), str(n)]
            for t, n in metrics["message_counts"].items()
        ],
    )
    if metrics["warnings"]:
        lines += ["## Warnings", ""] + [f"- {w}" for w in metrics["warnings"]] + [""]
    for node, c in metrics["controllers"].items():
        lines += [f"## Controller `{node}`", ""]
        lines += _configuration(c)
        lines += ["### Final error q_d − q (last sample)", ""]
        lines += _table(
            ["joint", "q_d − q [rad]"], [[j, fmt(c["final_error"][j], 6)] for j in c["joints"]]
        )
        lines += ["### Set-point steps", ""] + _steps(c)
        lines += _second_order(c)
        lines += _tracking(c)
        lines += _torque(c)
        lines += _periods(c)
        if node in figures:
            lines += _figures(figures[node], out_dir)
    return "\n".join(lines).rstrip() + "\n"


def write_report(metrics: dict, figures: Mapping[str, Mapping[str, Path]], out_dir: Path) -> Path:
    """Write ``out_dir/report.md`` (see :func:`render_report`); returns its path."""
    path = out_dir / "report.md"
    path.write_text(render_report(metrics, figures, out_dir))
    return path
