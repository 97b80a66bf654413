"""The realtime loop while a person opens its page, and under CPU hogs: the bench's
``watched`` section.

The loop is the README's first one (``planar_2dof``, PD + g) in realtime at 1 kHz, at the
nodes' default ``thread_priority`` 50, with the controller on ``use_sim_time`` and the
``dashboard`` node running, as users run them. Each case is measured in alternating
pairs: the middleware threads that deliver the nodes' messages left at normal scheduling
(``middleware_priority: 0``) and at the nodes' default (one below ``thread_priority``,
:func:`joint_space_control.scheduling.middleware_priority`). The cases:

- ``page``: Debian's Chromium (headless, default niceness, as a person's browser runs) is
  started on the page as the measurement starts, so the measurement holds the browser's
  start, the page's connection and its plotting from then on;
- ``hogs``: three CPU hogs (Python processes spinning at normal priority) beside the loop
  and the dashboard, no page.

Without Chromium or playwright the ``page`` case is skipped and says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from joint_space_control.lab.bench import browser, ros
from joint_space_control.lab.bench.dashboard import REALTIME_PRIORITY, SIM_TIME, Beside, _median

#: The README's first loop.
ROBOT, LAW = "planar_2dof", "pd_gravity"
#: The middleware's scheduling compared: normal, and the nodes' default.
MIDDLEWARE = {"normal": 0, "default": -1}
HOGS = 3
CASES = ("page", "hogs")


def watched(
    out: Path,
    pairs: int,
    seconds: float,
    log: Callable[[str], None],
    measured: Callable[[str, Callable[[], Any]], Any] = lambda _name, part: part(),
) -> dict[str, Any]:
    """Every run and, per case and middleware setting, the worst on-time fraction and the
    brakes over the pairs."""
    missing = browser.missing()
    runs: list[dict[str, Any]] = []
    for k in range(max(1, pairs)):
        for case in CASES:
            if case == "page" and missing:
                continue
            for label, priority in MIDDLEWARE.items():
                log(f"watched pair {k + 1}/{pairs}: {case}, middleware {label}")
                if case == "page":
                    side = Beside(True, True, log, open_at_start=True)
                else:
                    side = Beside(True, False, log, hogs=HOGS)
                params = {**SIM_TIME, "middleware_priority": priority}
                workdir = out / "runs" / f"watched_{case}_{label}_{k}"
                row = measured(
                    f"watched_{case}_{label}",
                    lambda s=side, p=params, c=case, w=workdir: ros.realtime(
                        w,
                        ROBOT,
                        LAW,
                        seconds,
                        log,
                        thread_priority=REALTIME_PRIORITY,
                        load=c,
                        controller_params=p,
                        plant_params={"middleware_priority": p["middleware_priority"]},
                        beside=s,
                    ),
                )
                runs.append(
                    {
                        "case": case,
                        "middleware": label,
                        "pair": k,
                        "page_connected": side.plotting,
                        "page_not_connected": side.not_plotting,
                        "on_time_fraction": row["on_time_fraction"],
                        "too_late_fraction": row["too_late_fraction"],
                        "brakes": row["brakes"],
                        "lateness_max_us": row["lateness"]["max_us"],
                        "cpu_seconds": side.cpu_seconds,
                    }
                )
    summary: dict[str, Any] = {}
    for case in CASES:
        for label in MIDDLEWARE:
            chosen = [r for r in runs if r["case"] == case and r["middleware"] == label]
            if not chosen:
                continue
            summary.setdefault(case, {})[label] = {
                "runs": len(chosen),
                "worst_on_time_fraction": min(r["on_time_fraction"] for r in chosen),
                "median_on_time_fraction": _median([r["on_time_fraction"] for r in chosen]),
                "brakes": sum(r["brakes"] for r in chosen),
            }
    return {
        "robot": ROBOT,
        "law": LAW,
        "seconds": seconds,
        "hogs": HOGS,
        "page_missing": missing,
        "summary": summary,
        "runs": runs,
    }


def goals(section: dict[str, Any] | None) -> list[tuple[str, float | None, Callable]]:
    """(goal, measured, met) of the loop watched and under hogs, at the nodes' defaults."""
    summary = (section or {}).get("summary", {})

    def value(case: str, key: str) -> float | None:
        row = summary.get(case, {}).get("default")
        v = None if row is None else row[key]
        return None if v is None or (isinstance(v, float) and math.isnan(v)) else v

    return [
        (
            "realtime 1 kHz, Chromium opening the page during the run: >= 99.8 % on time "
            "(worst run)",
            value("page", "worst_on_time_fraction"),
            lambda v: v >= 0.998,
        ),
        (
            "realtime 1 kHz, Chromium opening the page during the run: no brake",
            value("page", "brakes"),
            lambda v: v == 0,
        ),
        (
            f"realtime 1 kHz beside the dashboard and {HOGS} CPU hogs: >= 99.8 % on time "
            "(worst run)",
            value("hogs", "worst_on_time_fraction"),
            lambda v: v >= 0.998,
        ),
        (
            f"realtime 1 kHz beside the dashboard and {HOGS} CPU hogs: no brake",
            value("hogs", "brakes"),
            lambda v: v == 0,
        ),
    ]


def format_watched(section: dict[str, Any]) -> list[str]:
    """The section's lines of the table."""
    if "skipped" in section:
        return [f"watched: skipped ({section['skipped']})", ""]
    lines = [
        f"the loop watched: realtime 1 kHz {section['robot']} {section['law']} "
        f"(thread_priority {REALTIME_PRIORITY}, use_sim_time, the dashboard running), "
        f"{section['seconds']:g} s per run; middleware threads normal / at the default",
    ]
    if section["page_missing"]:
        lines.append(f"  page: not measured ({section['page_missing']})")
    for case, what in (
        ("page", "Chromium started on the page as the run starts"),
        ("hogs", f"{section['hogs']} CPU hogs"),
    ):
        rows = section["summary"].get(case)
        if not rows:
            continue
        text = " / ".join(
            f"worst {100 * r['worst_on_time_fraction']:.2f} % on time (median "
            f"{100 * r['median_on_time_fraction']:.2f} %), {r['brakes']} brake(s)"
            for r in (rows.get("normal"), rows.get("default"))
            if r is not None
        )
        lines.append(f"  {what}, {rows['default']['runs']} run(s) each: {text}")
    not_connected = [r for r in section["runs"] if r["page_connected"] is False]
    for r in not_connected:
        lines.append(f"  PAGE NOT CONNECTED: pair {r['pair'] + 1}: {r['page_not_connected']}")
    return [*lines, ""]
