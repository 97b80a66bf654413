"""``jsc analyze BAG``: a recorded bag → metrics.json, figures and report.md (wiring only)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TextIO

from joint_space_control.analysis.bag import BagError
from joint_space_control.analysis.pipeline import ResultsWriteError, analyze_bag_to
from joint_space_control.analysis.report import fmt

PROGRESS_MIN_MESSAGES = 20_000
"""Bags with fewer messages to read show no progress."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc analyze``."""
    p = subparsers.add_parser(
        "analyze",
        help="analyse a recorded rosbag2 bag: metrics.json, figures and report.md",
    )
    p.add_argument("bag", type=Path, help="rosbag2 directory (metadata.yaml + .mcap/.db3)")
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (default: <BAG>_report)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress display on stderr")
    p.set_defaults(handler=lambda args: run(args.bag, args.out, args.quiet))


def default_out(bag: Path) -> Path:
    """``<BAG>_report``, next to the bag directory."""
    return Path(str(bag).rstrip("/") + "_report")


class ProgressBar:
    """``progress(done, total)`` on a stream: one line redrawn in place on a terminal,
    otherwise a line at every quarter."""

    def __init__(self, stream: TextIO, width: int = 30) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self.width = width
        self._next_quarter = 1
        self._drawn = False

    def __call__(self, done: int, total: int) -> None:
        if total < PROGRESS_MIN_MESSAGES:
            return
        fraction = min(done / total, 1.0) if total else 1.0
        if self.tty:
            filled = round(self.width * fraction)
            bar = "#" * filled + "." * (self.width - filled)
            self.stream.write(f"\rreading [{bar}] {100 * fraction:3.0f} % {done}/{total} messages")
            self._drawn = True
        elif fraction * 4 >= self._next_quarter:
            self.stream.write(f"reading: {100 * fraction:.0f} % ({done}/{total} messages)\n")
            self._next_quarter = int(fraction * 4) + 1
        self.stream.flush()

    def finish(self) -> None:
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False


def run(bag: Path, out: Path | None = None, quiet: bool = False) -> int:
    """Analyse ``bag`` into ``out`` (default :func:`default_out`); exit code 0, or 2 when the
    bag cannot be analysed (one line on stderr), 1 when the results cannot be written."""
    out = default_out(bag) if out is None else out
    started = time.perf_counter()
    progress = None if quiet else ProgressBar(sys.stderr)
    try:
        result = analyze_bag_to(out, bag, progress)
    except (BagError, ResultsWriteError) as err:
        if progress is not None:
            progress.finish()
        print(f"jsc analyze: error: {err}", file=sys.stderr)
        return 2 if isinstance(err, BagError) else 1
    if progress is not None:
        progress.finish()
    _summary(result.metrics, result.report_path, time.perf_counter() - started)
    return 0


def _summary(metrics: dict, report: Path, elapsed: float) -> None:
    print(
        f"jsc analyze: {metrics['bag']}: {fmt(metrics['duration_s'])} s, "
        f"{metrics['message_count']} messages, analysed in {elapsed:.1f} s"
    )
    for node, c in metrics["controllers"].items():
        print(f"{node} ({c.get('robot') or 'robot ?'}, law {c.get('law') or '?'}):")
        errors = ", ".join(f"{j} {fmt(e, 3)}" for j, e in c["final_error"].items())
        print(f"  final error q_d - q [rad]: {errors}")
        for step in c["steps"]:
            moved = {j: m for j, m in step["joints"].items() if m["moving"]}
            parts = [
                f"{j} overshoot {fmt(m.get('overshoot_percent'), 3)} %, "
                f"settling 2 % {fmt(m.get('settling_time_2'), 3)} s"
                for j, m in moved.items()
            ]
            print(f"  step at {fmt(step['t_start'])} s: " + "; ".join(parts))
    for warning in metrics["warnings"]:
        print(f"warning: {warning}")
    print(f"report: {report} (with metrics.json and the figures)")
