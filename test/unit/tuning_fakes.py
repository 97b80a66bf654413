"""A stand-in for the runs of ``jsc tune`` in the unit tests: the nominal inverse-dynamics
loop is the second-order system ë + 2ζω_n ė + ω_n² e = 0 exactly (THEORY.md §3), so a
trial's metrics are the theory's (analysis/metrics.second_order_prediction), computed in
process. The pool runs them in threads, as the CLI's RunPool would on its workers."""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from joint_space_control.analysis.metrics import second_order_prediction

#: planar_2dof's diagonal inertia at q0 = 0 [kg m²] and effort limits [N·m], about.
INERTIA = {"joint1": 135.0, "joint2": 22.5}
LIMITS = {"joint1": 2000.0, "joint2": 1000.0}


def controller_metrics(
    omega_n, zeta, step=(0.2, 0.2), duration=2.0, joints=("joint1", "joint2")
) -> dict:
    """The metrics dict (``RunResult.controller``) of the theory's step response."""
    p = second_order_prediction(np.asarray(omega_n, float), np.asarray(zeta, float))
    entries, peaks = {}, {}
    for k, j in enumerate(joints):
        ts2, ts5 = float(p["settling_time_2"][k]), float(p["settling_time_5"][k])
        entries[j] = {
            "moving": True,
            "initial": 0.0,
            "target": step[k],
            "final_value": step[k],
            "steady_state_error": 0.0,
            "step": step[k],
            "rise_time": float(p["rise_time"][k]),
            "settling_time_2": ts2 if ts2 <= duration else None,
            "settling_time_5": ts5 if ts5 <= duration else None,
            "overshoot_percent": float(p["overshoot_percent"][k]),
        }
        # τ ≈ B ω_n² Δq at the step (inverse dynamics: B̂ K_P e)
        peaks[j] = INERTIA.get(j, 1.0) * float(p["omega_n"][k]) ** 2 * abs(step[k])
    return {
        "joints": list(joints),
        "steps": [{"duration": duration, "joints": entries}],
        "torque_demand": {
            "peak_abs": peaks,
            "saturated_fraction": {j: 0.0 for j in joints},
            "effort_limits": {j: LIMITS.get(j) for j in joints},
        },
    }


@dataclass
class FakeResult:
    controller: dict
    error: str | None = None
    out: Path | None = None


@dataclass
class FakeRunner:
    """``submit(label, scenario, target)`` of the study: theory metrics of the scenario's
    omega_n/zeta in a thread; ``fail`` labels raise; ``after`` stops (KeyboardInterrupt in
    the caller's wait) once that many runs were submitted."""

    jobs: int = 2
    fail: set[str] = field(default_factory=set)
    submitted: list[str] = field(default_factory=list)
    points: list[tuple] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.pool = ThreadPoolExecutor(self.jobs)
        self.lock = threading.Lock()

    def run(self, label: str, scenario, target: Path) -> list[FakeResult]:
        if label in self.fail:
            raise RuntimeError(f"{label}: the simulator died")
        params = scenario.parameters
        omega, zeta = params["omega_n"], params["zeta"]
        with self.lock:
            self.points.append((tuple(omega), tuple(zeta)))
        steps = np.asarray(scenario.reference["target"]) - np.asarray(
            scenario.plant["initial_positions"]
        )
        metrics = controller_metrics(omega, zeta, tuple(steps), scenario.duration)
        return [FakeResult(metrics, None, target)]

    def submit(self, label: str, scenario, target: Path) -> Future:
        self.submitted.append(label)
        return self.pool.submit(self.run, label, scenario, target)

    def close(self) -> None:
        self.pool.shutdown(wait=True)


def finite(x) -> bool:
    return x is not None and math.isfinite(x)


class ReorderingRunner:
    """``submit`` of the study whose runs finish in an order forced on them, newest first,
    not in the order submitted nor by chance: each run's result (or failure) is the
    :class:`FakeRunner`'s, computed at once, but its future is resolved by a thread that
    holds the futures until ``jobs`` of them wait (a pool with every worker busy) and then
    resolves the newest one alone, the oldest staying held while newer ones are submitted
    and resolved; held futures the caller waits on with fewer than ``jobs`` of them (the
    last runs, or a caller waiting for all) are resolved too, newest first, one per wait.

    No timer decides: a caller slow to submit its next run (asking Optuna takes a while)
    must not see its runs finish in order. That the caller is blocked in
    ``concurrent.futures.wait`` is seen on the futures themselves: ``wait`` puts one waiter
    object on each future it waits for (CPython's ``Future._waiters``); a waiter on every held
    future that was not there when the last one was resolved is a new wait. ``guard``
    seconds without a submission resolve the held futures anyway (only if that detail
    changed: slower then, never stuck). ``finished`` is the labels in the order resolved,
    ``submitted`` in the order submitted."""

    def __init__(self, jobs: int = 2, fail: set[str] | None = None, guard: float = 2.0):
        self.jobs, self.guard = jobs, guard
        self.runner = FakeRunner(jobs=1, fail=set(fail or ()))
        self.submitted: list[str] = []
        self.finished: list[str] = []
        self._held: list[tuple[str, Future, list[FakeResult] | None, Exception | None]] = []
        self._seen: list[object] = []  # waiters present when a future was resolved
        self._last = time.monotonic()
        self._closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._resolve, name="reorder", daemon=True)
        self._thread.start()

    def submit(self, label: str, scenario, target: Path) -> Future:
        future: Future = Future()
        try:
            value, err = self.runner.run(label, scenario, target), None
        except Exception as exc:  # noqa: BLE001 - the run's failure is the future's
            value, err = None, exc
        with self._cond:
            self.submitted.append(label)
            self._held.append((label, future, value, err))
            self._last = time.monotonic()
            self._cond.notify_all()
        return future

    def _waiters(self) -> list[object]:
        return [w for _, f, _, _ in self._held for w in list(getattr(f, "_waiters", ()))]

    def _waited_on(self) -> bool:
        """The caller waits on every held future, in a wait not seen before."""
        common = None
        for _, f, _, _ in self._held:
            ids = {id(w) for w in list(getattr(f, "_waiters", ()))}
            common = ids if common is None else common & ids
        seen = {id(w) for w in self._seen}
        return bool(common and common - seen)

    def _ready(self) -> bool:
        if not self._held:
            return self._closed
        return (
            self._closed
            or len(self._held) >= self.jobs
            or self._waited_on()
            or time.monotonic() - self._last > self.guard
        )

    def _resolve(self) -> None:
        while True:
            with self._cond:
                while not self._ready():
                    self._cond.wait(0.002)
                if not self._held:  # closed, nothing left
                    return
                label, future, value, err = self._held.pop()  # the newest
                self.finished.append(label)
                self._seen = self._waiters() + [w for w in list(future._waiters)]
                self._last = time.monotonic()
            if err is None:  # outside the lock: the waiter may submit at once
                future.set_result(value)
            else:
                future.set_exception(err)

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._thread.join()
        self.runner.close()
