"""``jsc bench``: measure the control loop and print/write the results (wiring only)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc bench``."""
    p = subparsers.add_parser(
        "bench",
        help="measure the control loop: law compute, the physics step on PyBullet and MuJoCo, "
        "lockstep over ROS 2 (on both engines) vs ping-pong and in-process, realtime 1 kHz, "
        "jsc analyze, sweep throughput on 1 and 2 Dask workers, "
        "the loop without and with the dashboard's page open; prints a table, writes bench.json",
    )
    p.add_argument("--out", type=Path, default=Path("out/bench"), help="output dir")
    p.add_argument("--quick", action="store_true", help="short runs (< 1 min in all)")
    p.add_argument(
        "--sections", type=lambda s: s.split(","), default=None, help="comma-separated subset"
    )
    p.add_argument(
        "--realtime-seconds", type=float, default=None, help="realtime run length [s] (30)"
    )
    p.add_argument(
        "--browser-nice",
        type=int,
        default=0,
        metavar="N",
        help="dashboard section: open the page in a browser at this niceness (0: as a user's "
        "browser runs; 19: the lowest priority, the loop's processes first)",
    )
    p.set_defaults(
        handler=lambda args: run(
            args.out, args.quick, args.sections, args.realtime_seconds, args.browser_nice
        )
    )


def run(
    out: Path,
    quick: bool,
    sections: list[str] | None,
    realtime_seconds: float | None,
    browser_nice: int = 0,
) -> int:
    # deferred: the library (ROS, Pinocchio) loads only for this command, not for `jsc --help`
    from joint_space_control.lab.bench.run import SECTIONS, Options, format_table
    from joint_space_control.lab.bench.run import run as run_bench

    sections = sections or list(SECTIONS)
    unknown = [s for s in sections if s not in SECTIONS]
    if unknown:
        print(
            f"jsc bench: error: unknown sections {unknown}; known: {list(SECTIONS)}",
            file=sys.stderr,
        )
        return 2
    options = Options.quick() if quick else Options()
    if realtime_seconds is not None:
        options = Options(**{**options.__dict__, "realtime_seconds": realtime_seconds})
    if not 0 <= browser_nice <= 19:
        print(
            f"jsc bench: error: --browser-nice must be 0..19, got {browser_nice}", file=sys.stderr
        )
        return 2
    options = Options(**{**options.__dict__, "dashboard_browser_nice": browser_nice})
    try:
        result = run_bench(out, options, sections, lambda m: print(f"  {m}", flush=True))
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc bench failed: {err}", file=sys.stderr)
        return 1
    print()
    print(format_table(result))
    print(f"\nwritten: {out / 'bench.json'}, {out / 'bench.txt'}")
    return 0
