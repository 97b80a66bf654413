"""``jsc recover BAG``: a complete bag from one whose recorder was killed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc recover``."""
    p = subparsers.add_parser(
        "recover",
        help="rewrite what is readable of a bag whose recorder was killed into a complete bag",
    )
    p.add_argument("bag", type=Path, help="rosbag2 directory (or its .mcap/.db3 file)")
    p.add_argument(
        "--out", type=Path, default=None, help="new bag directory (default: <BAG>_recovered)"
    )
    p.set_defaults(handler=lambda args: run(args.bag, args.out))


def run(bag: Path, out: Path | None) -> int:
    """Recover ``bag`` into ``out``; 0 on success, 2 (one error line) when nothing can be."""
    # deferred: the library (ROS, Pinocchio) loads only for this command, not for `jsc --help`
    from joint_space_control.recording.recover import RecoveryError, recover

    try:
        result = recover(bag, out)
    except RecoveryError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    state = "complete" if result.complete else f"incomplete, {result.stopped}"
    print(f"read {result.source} ({result.storage}, {state})")
    for topic, count in result.counts.items():
        print(f"  {topic}: {count}")
    for topic in result.skipped:
        print(f"  {topic}: skipped (no usable message definition)")
    span = (result.end_ns - result.start_ns) * 1e-9
    print(
        f"wrote {result.path}: {result.message_count} messages, "
        f"{result.start_ns * 1e-9:.3f} s to {result.end_ns * 1e-9:.3f} s ({span:.3f} s)"
    )
    return 0
