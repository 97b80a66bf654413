"""Stand-ins for ``experiments.distributed.RunPool`` and ``runner.execute_run`` (issue 18,
part 2) until they are on main: the same interface, runs in threads on this machine.

To be deleted once main has ``experiments/distributed.py``.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

from joint_space_control.experiments.runner import RunResult, run_once, stop_all_runs
from joint_space_control.experiments.scenario import Scenario


def execute_run(run: Scenario, target: Path, short: bool) -> list[RunResult]:
    """One run of ``run`` into ``target``: a result per robot; raises when it fails."""
    results = [RunResult(s.name or "run", run.of_robot(s), target, s.name) for s in run.setups()]
    run_once(run, target, short, results)
    return results


class RunPool:
    """``jobs`` threads on this machine (``scheduler`` must be None or "threads")."""

    def __init__(
        self, jobs: int = 2, scheduler: str | None = None, log: Callable[[str], None] = print
    ) -> None:
        if scheduler not in (None, "threads"):
            raise ValueError(f"scheduler {scheduler!r}: only threads here until Dask lands")
        self.workers = max(1, jobs)
        self.description = f"{self.workers} threads on this machine"
        self._pool: ThreadPoolExecutor | None = None

    def __enter__(self) -> RunPool:
        self._pool = ThreadPoolExecutor(self.workers)
        return self

    def submit(self, label: str, fn: Callable[..., Any], *args: Any) -> Future:
        assert self._pool is not None
        return self._pool.submit(fn, *args)

    def cancel(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        stop_all_runs()

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
