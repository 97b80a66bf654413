"""``jsc bench``: measure the control loop and print/write the results (wiring only)."""

from __future__ import annotations

import sys
from pathlib import Path

from joint_space_control.bench.run import SECTIONS, Options, format_table
from joint_space_control.bench.run import run as run_bench


def run(out: Path, quick: bool, sections: list[str] | None, realtime_seconds: float | None) -> int:
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
    try:
        result = run_bench(out, options, sections, lambda m: print(f"  {m}", flush=True))
    except (RuntimeError, TimeoutError) as err:
        print(f"jsc bench failed: {err}", file=sys.stderr)
        return 1
    print()
    print(format_table(result))
    print(f"\nwritten: {out / 'bench.json'}, {out / 'bench.txt'}")
    return 0
