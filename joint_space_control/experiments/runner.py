"""Running a scenario: node processes in an isolated ROS domain, recorded, analysed.

Each run starts ``sim_bridge`` (lockstep, paused), the scenario's controller and the
``recorder`` as separate processes with ``--ros-args --params-file`` (as a launch file
would), sends the reference, applies the scheduled changes at exact simulation times, stops
everything, and analyses the bag into ``<run>/report``. Variants run in parallel, each in
its own ROS domain.

A scenario of several robots runs them in one world (one ``sim_bridge``, a controller per
robot in its namespace, one bag) and gives one result per robot, as if each were a run of
its own: its controller's metrics, recorded state and figures, its joint states at the
events.
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
from joint_space_control.experiments.probe import in_namespace
from joint_space_control.experiments.scenario import RobotSetup, Scenario, build_reference
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.ros import parameters as params
from joint_space_control.trajectories.reference import Trajectory


@dataclass
class RunResult:
    """One run of a scenario: where its files are, its metrics, what the runner saw."""

    label: str
    scenario: Scenario
    """The run's scenario; of a world of several robots, this robot's (Scenario.of_robot)."""
    out: Path
    namespace: str = ""
    """The robot's name in a world of several ("": the one robot, in the root namespace)."""
    metrics: dict | None = None
    events: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None
    state: ControllerState | None = None
    """The controller's recorded ``~/state`` as analysed (for checks that need signals)."""
    truth: JointStates | None = None
    """The plant's true state, recorded when its measurement is imperfect (else None)."""
    figures: dict[str, Path] = field(default_factory=dict)
    """The controller's figures in ``report/`` (name → PNG: ``positions``, ``error``, …)."""

    @property
    def node(self) -> str:
        """The controller's node: ``/<controller>``, or ``/<namespace>/<controller>``."""
        return "/" + in_namespace(self.namespace, self.scenario.controller)

    @property
    def controller(self) -> dict:
        """The metrics of the scenario's controller."""
        assert self.metrics is not None
        return self.metrics["controllers"][self.node]


#: The plant's true state beside an imperfect measurement (docs/plant.md), in the robot's
#: namespace.
TRUTH_TOPIC = "sim_bridge/true_joint_states"

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
    """Every run of ``scenario`` (one, or one per variant, ``jobs`` at a time): a result
    per run, or per robot of each run in a world of several."""
    runs = scenario.runs(short)
    out.mkdir(parents=True, exist_ok=True)

    def one(k: int) -> list[RunResult]:
        label, run = runs[k]
        target = out if len(runs) == 1 else out / _safe(label)
        results = [
            RunResult(s.name or label, run.of_robot(s), target, s.name) for s in run.setups()
        ]
        try:
            run_once(run, target, short, results)
            log(f"  {run.name}: done")
        except Exception as err:  # noqa: BLE001 - reported, the other runs go on
            for result in results:
                result.error = f"{type(err).__name__}: {err}"
            (target / "error.txt").write_text(traceback.format_exc())
            log(f"  {run.name}: FAILED: {results[0].error}")
        return results

    pool = ThreadPoolExecutor(max_workers=max(1, jobs))
    try:
        futures = [pool.submit(one, k) for k in range(len(runs))]
        return [result for f in futures for result in f.result()]
    except KeyboardInterrupt:
        pool.shutdown(wait=False, cancel_futures=True)
        stop_all_runs()  # the running loops' processes; their threads then fail and end
        raise
    finally:
        pool.shutdown(wait=True)


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_.=" else "_" for c in label)


def run_once(scenario: Scenario, out: Path, short: bool, results: list[RunResult]) -> None:
    """One closed-loop run into ``out`` (bag/, report/, logs/, events.json); ``results``:
    one per robot of ``scenario.setups()``, in that order."""
    out.mkdir(parents=True, exist_ok=True)
    bag = out / "bag"
    if bag.exists():
        raise RuntimeError(f"{bag} exists: use a fresh output directory")
    duration = scenario.run_duration(short)
    changes = scenario.changes_within(duration)
    # The simulator pauses at each change and at the end: every run ends at exactly
    # `duration`, with the same samples.
    sim_params = {**scenario.plant, "pause_at": changes[0].at if changes else duration}
    with _closed_loop(scenario, out / "logs", sim_params, bag) as loop:
        with _active_lock:
            _active.add(loop)
        try:
            _drive(loop, scenario, duration, results)
            loop.settle_recording()
        finally:
            with _active_lock:
                _active.discard(loop)
    (out / "events.json").write_text(json.dumps(_events(results), indent=1))
    analysis = analyze_bag_to(out / "report", bag)
    for result in results:
        result.metrics = analysis.metrics
        result.state = next(
            (c.state for c in analysis.analysis.controllers if c.metrics["node"] == result.node),
            None,
        )
        result.figures = analysis.figures.get(result.node, {})
        result.truth = true_states(bag, result.namespace)


def _closed_loop(
    scenario: Scenario, workdir: Path, sim_params: dict[str, Any], bag: Path
) -> ClosedLoop:
    """The loop of the scenario's robot, or of its world of robots, in a leased domain
    (concurrent runs never meet)."""
    if not scenario.robots:
        return ClosedLoop(
            workdir,
            None,
            scenario.robot,
            scenario.controller,
            controller_params=scenario.parameters,
            sim_params=sim_params,
            record=bag,
        )
    return ClosedLoop(workdir, None, scenario.robots, sim_params=sim_params, record=bag)


def _events(results: list[RunResult]) -> list[dict[str, Any]] | dict[str, list[dict[str, Any]]]:
    """What ``events.json`` holds: the one robot's events, or each robot's by name."""
    if len(results) == 1 and not results[0].namespace:
        return results[0].events
    return {r.namespace: r.events for r in results}


def true_states(bag: Path, namespace: str = "") -> JointStates | None:
    """The plant's true state in the bag (``/sim_bridge/true_joint_states``, or
    ``/<namespace>/sim_bridge/true_joint_states``), if recorded."""
    topic = "/" + in_namespace(namespace, TRUTH_TOPIC)
    with BagReader(bag) as reader:
        if topic not in reader.contents().topics:
            return None
        return joint_states(reader.read([topic])[topic])


def _drive(
    loop: ClosedLoop, scenario: Scenario, duration: float, results: list[RunResult]
) -> None:
    """Send each robot's reference, apply the scheduled changes at their times (one robot
    only), run to the end."""
    setups = scenario.setups()
    models = [setup_model(s) for s in setups]
    trajectories = [_reference(s, m.n, duration) for s, m in zip(setups, models, strict=True)]
    for s, model, traj in zip(setups, models, trajectories, strict=True):
        loop.probe.send_reference(
            list(model.joint_names),
            traj.positions,
            traj.times,
            velocities=traj.velocities,
            accelerations=traj.accelerations,
            namespace=s.name,
        )
    loop.resume()  # every reference acknowledged: only now does the world run
    result, traj, n = results[0], trajectories[0], models[0].n
    changes = scenario.changes_within(duration)
    estimate = per_joint(scenario.parameters.get("gravity_estimate", 0.0), n, "u")
    kp = scenario.parameters.get("kp", 100.0)
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
    for s, r in zip(setups, results, strict=True):
        _, q, _, _ = loop.probe.recordings[s.name].arrays()
        r.events.append({"t": duration, "q": q[-1].tolist(), "end": True})


def setup_model(setup: RobotSetup) -> RobotModel:
    """The robot's model as its controller builds it: from the robot parameters among its
    ``parameters`` (``urdf_path`` with ``package_paths`` and ``xacro_args``, ``joints``,
    ``effort_limits``) over the built-in ``robot``."""
    defaults = {p.name: p.default for p in params.ROBOT_PARAMETERS}
    given = {k: v for k, v in setup.parameters.items() if k in defaults}
    return params.robot_model(
        params.ParamValues(params.ROBOT_PARAMETERS, {**defaults, "robot": setup.robot, **given})
    )


def _reference(setup: RobotSetup, n: int, duration: float) -> Trajectory:
    """The robot's reference trajectory, from its initial configuration."""
    q0 = per_joint(setup.plant.get("initial_positions", 0.0), n, "initial_positions")
    return build_reference(setup.reference, q0, duration)


def _set(loop: ClosedLoop, node: str, values: dict[str, Any]) -> None:
    if not values:
        return
    results = loop.probe.set_parameters(node, values)
    failed = [f"{k}: {r.reason}" for k, r in zip(values, results, strict=True) if not r.successful]
    if failed:
        raise RuntimeError(f"{node} rejected " + "; ".join(failed))
