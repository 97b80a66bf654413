"""``jsc recover BAG``: a complete bag from one whose recorder was killed."""

from __future__ import annotations

import sys
from pathlib import Path

from joint_space_control.recording.recover import RecoveryError, recover


def run(bag: Path, out: Path | None) -> int:
    """Recover ``bag`` into ``out``; 0 on success, 2 (one error line) when nothing can be."""
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
