"""Running a scenario: node processes in an isolated ROS domain, recorded, analysed.

Each run starts ``sim_bridge`` (lockstep, paused), the scenario's controller and the
``recorder`` as separate processes with ``--ros-args --params-file`` (as a launch file
would), sends the reference, applies the scheduled changes at exact simulation times, stops
everything, and analyses the bag into ``<run>/report``. Variants run in parallel, each in
its own ROS domain.
"""

from __future__ import annotations

import json
import threading
import traceback
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from joint_space_control.analysis.bag import BagReader, ControllerState, JointStates, joint_states
from joint_space_control.analysis.pipeline import analyze_bag_to
from joint_space_control.arrays import per_joint
from joint_space_control.experiments.loop import ClosedLoop
from joint_space_control.experiments.scenario import Scenario, build_reference
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot


@dataclass
class RunResult:
    """One run of a scenario: where its files are, its metrics, what the runner saw."""

    label: str
    scenario: Scenario
    out: Path
    metrics: dict | None = None
    events: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None
    state: ControllerState | None = None
    """The controller's recorded ``~/state`` as analysed (for checks that need signals)."""
    truth: JointStates | None = None
    """The plant's true state, recorded when its measurement is imperfect (else None)."""

    @property
    def controller(self) -> dict:
        """The metrics of the scenario's controller."""
        assert self.metrics is not None
        return self.metrics["controllers"][f"/{self.scenario.controller}"]


#: The plant's true state beside an imperfect measurement (docs/plant.md).
TRUTH_TOPIC = "/sim_bridge/true_joint_states"

_active: set[ClosedLoop] = set()
_active_lock = threading.Lock()


def stop_all_runs() -> None:
    """Stop every loop still running (Ctrl-C): their node processes are terminated."""
    with _active_lock:
        loops = list(_active)
    for loop in loops:
        loop.close()


def run_scenario(
    scenario: Scenario,
    out: Path,
    short: bool = False,
    jobs: int = 2,
    log: Callable[[str], None] = print,
) -> list[RunResult]:
    """Every run of ``scenario`` (one, or one per variant, ``jobs`` at a time)."""
    runs = scenario.runs(short)
    out.mkdir(parents=True, exist_ok=True)

    def one(k: int) -> RunResult:
        label, run = runs[k]
        target = out if len(runs) == 1 else out / _safe(label)
        result = RunResult(label, run, target)
        try:
            run_once(run, target, short, result)
            log(f"  {run.name}: done")
        except Exception as err:  # noqa: BLE001 - reported, the other runs go on
            result.error = f"{type(err).__name__}: {err}"
            (target / "error.txt").write_text(traceback.format_exc())
            log(f"  {run.name}: FAILED: {result.error}")
        return result

    pool = ThreadPoolExecutor(max_workers=max(1, jobs))
    try:
        futures = [pool.submit(one, k) for k in range(len(runs))]
        return [f.result() for f in futures]
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        stop_all_runs()  # the running loops' processes; their threads then fail and end
        raise
    finally:
        pool.shutdown(wait=True)


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_.=" else "_" for c in label)


def run_once(scenario: Scenario, out: Path, short: bool, result: RunResult) -> None:
    """One closed-loop run into ``out`` (bag/, report/, logs/, events.json)."""
    out.mkdir(parents=True, exist_ok=True)
    bag = out / "bag"
    if bag.exists():
        raise RuntimeError(f"{bag} exists: use a fresh output directory")
    duration = scenario.run_duration(short)
    changes = scenario.changes_within(duration)
    with ClosedLoop(
        out / "logs",
        None,  # a leased domain: concurrent runs never meet
        scenario.robot,
        scenario.controller,
        controller_params=scenario.parameters,
        # The simulator pauses at each change and at the end: every run ends at exactly
        # `duration`, with the same samples.
        sim_params={**scenario.plant, "pause_at": changes[0].at if changes else duration},
        record=bag,
    ) as loop:
        with _active_lock:
            _active.add(loop)
        try:
            _drive(loop, scenario, duration, result)
            loop.settle_recording()
        finally:
            with _active_lock:
                _active.discard(loop)
    (out / "events.json").write_text(json.dumps(result.events, indent=1))
    analysis = analyze_bag_to(out / "report", bag)
    result.metrics = analysis.metrics
    node = f"/{scenario.controller}"
    result.state = next(
        (c.state for c in analysis.analysis.controllers if c.metrics["node"] == node), None
    )
    result.truth = true_states(bag)


def true_states(bag: Path) -> JointStates | None:
    """The plant's true state in the bag (``/sim_bridge/true_joint_states``), if recorded."""
    with BagReader(bag) as reader:
        if TRUTH_TOPIC not in reader.contents().topics:
            return None
        return joint_states(reader.read([TRUTH_TOPIC])[TRUTH_TOPIC])


def _drive(loop: ClosedLoop, scenario: Scenario, duration: float, result: RunResult) -> None:
    """Send the reference, apply the scheduled changes at their times, run to the end."""
    model = RobotModel(resolve_robot(scenario.robot))
    n = model.n
    q0 = per_joint(scenario.plant.get("initial_positions", 0.0), n, "initial_positions")
    traj = build_reference(scenario.reference, q0, duration)
    changes = scenario.changes_within(duration)
    estimate = per_joint(scenario.parameters.get("gravity_estimate", 0.0), n, "u")
    kp = scenario.parameters.get("kp", 100.0)
    loop.start(
        list(model.joint_names), traj.positions, traj.times, traj.velocities, traj.accelerations
    )
    for k, change in enumerate(changes):
        loop.hold_at(change.at)
        _, q, _, _ = loop.probe.recording.arrays()
        controller = dict(change.controller)
        kp = controller.get("kp", kp)
        if change.update == "iterative_gravity":
            # u_i = K_P (q_d − q_e,i) + u_{i−1}  (THEORY.md §2), q_d the last point
            estimate = per_joint(kp, n, "kp") * (traj.positions[-1] - q[-1]) + estimate
            controller["gravity_estimate"] = estimate.tolist()
        result.events.append(
            {"t": change.at, "q": q[-1].tolist(), "controller": controller, **change.plant}
        )
        _set(loop, scenario.controller, controller)
        nxt = changes[k + 1].at if k + 1 < len(changes) else duration
        _set(loop, "sim_bridge", {**change.plant, "pause_at": nxt})
        loop.resume()
    loop.hold_at(duration)
    _, q, _, _ = loop.probe.recording.arrays()
    result.events.append({"t": duration, "q": q[-1].tolist(), "end": True})


def _set(loop: ClosedLoop, node: str, values: dict[str, Any]) -> None:
    if not values:
        return
    results = loop.probe.set_parameters(node, values)
    failed = [f"{k}: {r.reason}" for k, r in zip(values, results, strict=True) if not r.successful]
    if failed:
        raise RuntimeError(f"{node} rejected " + "; ".join(failed))
