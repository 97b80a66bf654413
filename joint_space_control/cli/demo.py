"""``jsc demo``: run the default closed loop (planar_2dof, PD + g(q), a step) headless and
analyse its bag into a report, as a user would with the recorder and ``jsc analyze``
(wiring and printing only; the run is :mod:`joint_space_control.processes.demo`)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

import numpy as np

from joint_space_control.cli import analyze
from joint_space_control.processes.demo import run_demo, run_view_demo


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc demo``."""
    p = subparsers.add_parser(
        "demo",
        help="run the default closed loop (planar_2dof, PD + g(q), "
        "a step) headless and write its results",
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    p.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    p.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS domain for the run (default: one no other run on this machine uses)",
    )
    p.add_argument(
        "--view",
        action="store_true",
        help="instead: the robot in realtime with the dashboard, until Ctrl-C (prints its URL)",
    )
    p.add_argument("--port", type=int, default=8080, help="--view: the dashboard's port")
    p.set_defaults(
        handler=lambda args: (
            view(args.out, args.port)
            if args.view
            else run(args.out, args.duration, args.domain_id)
        )
    )


def view(out: Path, port: int) -> int:
    """``jsc demo --view``: the live demo until Ctrl-C or SIGTERM (exit 0)."""
    from joint_space_control.nodes.dashboard import port_free

    if not port_free("127.0.0.1", port):
        print(
            f"jsc demo --view: error: port {port} is in use (give another: --port N)",
            file=sys.stderr,
        )
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        return run_view_demo(out, port, lambda m: print(f"jsc demo: {m}", flush=True), stop=stop)
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc demo --view failed: {err}\nnode logs: {out / 'logs'}", file=sys.stderr)
        return 1


def run(out: Path, duration: float, domain_id: int | None) -> int:
    """Run the demo into ``out``; the exit code of its analysis, or 1 when the run failed."""
    try:
        demo = run_demo(out, duration, domain_id, lambda m: print(f"jsc demo: {m}"))
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc demo failed: {err}\nnode logs: {out / 'logs'}", file=sys.stderr)
        return 1
    error = demo.final_error
    print(
        f"live run: final error q_d - q = {np.array2string(error, precision=6)} rad "
        f"(max |e| = {np.max(np.abs(error)):.2e} rad)"
    )
    return analyze.run(demo.bag, demo.report)
