"""Running a scenario: node processes in an isolated ROS domain, recorded, analysed.

Each run starts ``sim_bridge`` (lockstep, paused), the scenario's controller and the
``recorder`` as separate processes with ``--ros-args --params-file`` (as a launch file
would), sends the reference, applies the scheduled changes at exact simulation times, stops
everything, and analyses the bag into ``<run>/report``. Variants run in parallel, each in
its own ROS domain: each run is a task (:func:`execute_run`) of a
:class:`~joint_space_control.workbench.experiments.execution.distributed.RunPool`, in threads of
this
process or on the workers of a Dask cluster, which then write into an ``out`` they all reach.

A scenario of several robots runs them in one world (one ``sim_bridge``, a controller per
robot in its namespace, one bag) and gives one result per robot, as if each were a run of
its own: its controller's metrics, recorded state and figures, its joint states at the
events.
"""

from __future__ import annotations

import json
import os
import shutil
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from joint_space_control.analysis.bag import BagReader, ControllerState, JointStates, joint_states
from joint_space_control.analysis.pipeline import analyze_bag_to, write_analysis
from joint_space_control.analysis.run_metrics import analyze_run
from joint_space_control.arrays import per_joint
from joint_space_control.laws.pd_gravity import iterative_gravity_estimate
from joint_space_control.processes.loop import TRUTH_TOPIC, ClosedLoop
from joint_space_control.processes.probe import in_namespace
from joint_space_control.simulation.response import Response
from joint_space_control.trajectories.reference import Trajectory
from joint_space_control.workbench.experiments.execution import values
from joint_space_control.workbench.experiments.execution.distributed import RunPool, on_cancel
from joint_space_control.workbench.experiments.scenarios.format import (
    RobotSetup,
    Scenario,
    build_reference,
)


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
    response: Response | None = None
    """The robot's run as arrays (the in-process engine's; None on the ROS engine)."""
    figures: dict[str, Path] = field(default_factory=dict)
    """The controller's figures in ``report/`` (name → PNG: ``positions``, ``error``, …)."""
    timings: dict[str, float] = field(default_factory=dict)
    """Where the run's wall time went [s]: ``start`` (the node processes up and connected),
    ``run`` (the simulated run, with its changes), ``stop`` (the recorder's tail, the
    nodes stopped), ``analysis`` (bag → report and figures)."""

    @property
    def node(self) -> str:
        """The controller's node: ``/<controller>``, or ``/<namespace>/<controller>``."""
        return "/" + in_namespace(self.namespace, self.scenario.controller)

    @property
    def controller(self) -> dict:
        """The metrics of the scenario's controller."""
        assert self.metrics is not None
        return self.metrics["controllers"][self.node]


#: What a run writes into its directory (removed before a retry: a failed attempt's).
RUN_FILES = ("bag", "report", "logs", "events.json", "error.txt")
#: How long [s] a retry waits for the failed attempt's nodes to stop and its bag to close.
PREVIOUS_ATTEMPT_WAIT = 10.0


def execute_run(
    run: Scenario,
    target: Path,
    short: bool,
    engine: str = "ros",
    figures: bool = True,
    record: bool = False,
) -> list[RunResult]:
    """One run of a scenario as a pool task (top-level and picklable, for Dask workers):
    the run into ``target`` (:func:`run_once`), one result per robot of the run; its
    ``label``: the run's name after its scenario's (``Scenario.with_settings``), ``run`` for
    a scenario's only run. A failed run is a result with its ``error`` (and
    ``target/error.txt``), not an exception: lockstep runs are deterministic, and a rerun
    would fail the same way. A rerun after the worker died removes what the failed attempt
    left in ``target`` first."""
    label = run.name.partition("/")[2] or "run"
    results = [RunResult(s.name or label, run.of_robot(s), target, s.name) for s in run.setups()]
    _clear_previous_attempt(target)
    try:
        run_once(run, target, short, results, engine, figures, record)
    except Exception as err:  # noqa: BLE001 - reported, the other runs go on
        for result in results:
            result.error = f"{type(err).__name__}: {err}"
        (target / "error.txt").write_text(traceback.format_exc())
    return results


def _clear_previous_attempt(target: Path) -> None:
    """Remove a failed attempt's files from ``target``, once its nodes are gone: those on
    this machine (their command lines name ``target``) and, where that cannot be seen (the
    attempt ran on another machine), once its recorder has closed the bag (it stops by
    itself when its worker dies, processes.py)."""
    if not any((target / name).exists() for name in RUN_FILES):
        return
    deadline = time.monotonic() + PREVIOUS_ATTEMPT_WAIT
    bag = target / "bag"
    while time.monotonic() < deadline and (
        _processes_naming(target) or (bag.is_dir() and not (bag / "metadata.yaml").exists())
    ):
        time.sleep(0.2)
    for name in RUN_FILES:
        path = target / name
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        elif path.exists():
            path.unlink()


def _processes_naming(directory: Path) -> list[int]:
    """Processes on this machine whose command line names a file under ``directory`` (a
    run's nodes: their ``--params-file`` is in ``<run>/logs``)."""
    needle = os.fsencode(str(directory) + os.sep)
    found = []
    if not os.path.isdir("/proc"):  # not Linux: nothing to see, the bag is awaited alone
        return found
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/cmdline", "rb") as f:
                if needle in f.read():
                    found.append(int(entry.name))
        except OSError:  # gone meanwhile, or not ours to read
            continue
    return found


def run_scenario(
    scenario: Scenario,
    out: Path,
    short: bool = False,
    pool: RunPool | None = None,
    log: Callable[[str], None] = print,
    engine: str = "ros",
    record: bool = False,
) -> list[RunResult]:
    """Every run of ``scenario`` (one, or one per variant), each a task of ``pool`` (None:
    two threads of this process): a result per run, or per robot of each run in a world of
    several, in the scenario's order; only the last run's report draws figures. A run whose
    task failed twice (its worker died) is a result with that error. Ctrl-C cancels the runs
    of a pool made here; a caller's pool is the caller's to cancel."""
    runs = scenario.runs(short)
    out = out.absolute()  # the same path on every worker (a shared file system)
    out.mkdir(parents=True, exist_ok=True)
    own = pool is None
    if pool is None:
        pool = RunPool(2, "threads", log)
    try:
        futures = {}
        for k, (label, run) in enumerate(runs):
            target = out if len(runs) == 1 else out / _safe(label)
            # figures where they are shown: of a sweep, the last run's (the results page
            # shows the sweep's own figures and that run's positions); the other runs'
            # reports have their metrics
            shown = k == len(runs) - 1
            task = pool.submit(run.name, execute_run, run, target, short, engine, shown, record)
            futures[task] = (
                label,
                run,
                target,
            )
        for future in as_completed(futures):
            label, run, target = futures[future]
            if future.cancelled():
                continue
            err = future.exception()
            if err is None:
                failed = future.result()[0].error
                log(f"  {run.name}: FAILED: {failed}" if failed else f"  {run.name}: done")
            else:
                log(f"  {run.name}: FAILED: {type(err).__name__}: {err}")
        return [result for future, run in futures.items() for result in _results(future, *run)]
    except KeyboardInterrupt:
        if own:
            pool.cancel()  # the running loops' processes stopped, the queued runs dropped
        raise
    finally:
        if own:
            pool.close()


def _results(future, label: str, run: Scenario, target: Path) -> list[RunResult]:
    """The run's results, or, if its task failed (twice), results carrying that error."""
    err = future.exception()
    if err is None:
        return future.result()
    message = f"{type(err).__name__}: {err}"
    target.mkdir(parents=True, exist_ok=True)
    (target / "error.txt").write_text(f"the run's task failed twice: {message}\n")
    return [
        RunResult(s.name or label, run.of_robot(s), target, s.name, error=message)
        for s in run.setups()
    ]


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_.=" else "_" for c in label)


#: The engines a lockstep run can run on: node processes over ROS, or this process.
ENGINES = ("ros", "inprocess")


def run_once(
    scenario: Scenario,
    out: Path,
    short: bool,
    results: list[RunResult],
    engine: str = "ros",
    figures: bool = True,
    record: bool = False,
) -> None:
    """One closed-loop run into ``out`` (bag/, report/, logs/, events.json) on ``engine``
    (its report without figures unless ``figures``); ``results``: one per robot of
    ``scenario.setups()``, in that order. A run on the ROS engine is always recorded (its
    nodes' messages are what it is measured from); one in process is measured from memory
    and written to ``bag/`` only with ``record``."""
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; known: {', '.join(ENGINES)}")
    out.mkdir(parents=True, exist_ok=True)
    bag = out / "bag"
    if bag.exists():
        raise RuntimeError(f"{bag} exists: use a fresh output directory")
    duration = scenario.run_duration(short)
    changes = scenario.changes_within(duration)
    # The simulator pauses at each change and at the end: every run ends at exactly
    # `duration`, with the same samples.
    sim_params = {**scenario.plant, "pause_at": changes[0].at if changes else duration}
    clock = [time.monotonic()]
    timings: dict[str, float] = {}

    def lap(name: str) -> None:
        now = time.monotonic()
        timings[name] = now - clock[0]
        clock[0] = now

    if engine == "ros":
        with _closed_loop(scenario, out / "logs", sim_params, bag) as loop, on_cancel(loop.close):
            lap("start")
            _drive(RosRun(loop), scenario, duration, results)
            lap("run")
            loop.settle_recording()
        lap("stop")
        (out / "events.json").write_text(json.dumps(_events(results), indent=1))
        analysis = analyze_bag_to(out / "report", bag, figures=figures)
        truths = [true_states(bag, r.namespace) for r in results]
    else:
        # pybullet (its banner on stdout) only where a run is
        from joint_space_control.workbench.experiments.execution.inprocess import (
            InProcessLoop,
            recording,
        )

        loop = InProcessLoop(scenario.setups(), sim_params, bag if record else None)
        try:
            lap("start")
            _drive(loop, scenario, duration, results)
            lap("run")
        finally:
            loop.close()
        lap("stop")
        (out / "events.json").write_text(json.dumps(_events(results), indent=1))
        responses = [loop.response(r.namespace) for r in results]
        measured = analyze_run(
            [(r.steps, r.configs) for r in responses],
            recording(loop.world, bag if record else None),
        )
        analysis = write_analysis(measured, out / "report", figures=figures)
        truths = []
        for result, response in zip(results, responses, strict=True):
            result.response = response
            truths.append(_truth(response, result.namespace))
    lap("analysis")
    for result, truth in zip(results, truths, strict=True):
        result.timings = dict(timings)
        result.metrics = analysis.metrics
        result.state = next(
            (c.state for c in analysis.analysis.controllers if c.metrics["node"] == result.node),
            None,
        )
        result.figures = analysis.figures.get(result.node, {})
        result.truth = truth


def _truth(response: Response, namespace: str) -> JointStates | None:
    """The plant's true state of an in-process run, as a recording of it reads it (logged
    just before the measured state of the same instant)."""
    if response.q_true is None:
        return None
    return JointStates(
        "/" + in_namespace(namespace, TRUTH_TOPIC),
        response.joints,
        response.t,
        response.log_times["states"] - 1,
        response.q_true,
        response.dq_true,
        response.tau_applied,
    )


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


class RunLoop(Protocol):
    """What driving a run needs of its engine (:class:`RosRun`, or the in-process
    :class:`~joint_space_control.workbench.experiments.execution.inprocess.InProcessLoop`);
    ``namespace``
    names the robot ("": the one robot)."""

    def send_reference(
        self,
        namespace: str,
        joints: Sequence[str],
        positions: Sequence[Sequence[float]],
        times: Sequence[float],
        velocities: Sequence[Sequence[float]] | None = None,
        accelerations: Sequence[Sequence[float]] | None = None,
    ) -> None: ...

    def run_until(self, t: float) -> None: ...

    def positions(self, namespace: str = "") -> np.ndarray: ...

    def gains(self, namespace: str = "") -> np.ndarray: ...

    def set_controller(self, namespace: str, changes: Mapping[str, Any]) -> None: ...

    def set_plant(self, changes: Mapping[str, Any]) -> None: ...


class RosRun:
    """:class:`RunLoop` on the node processes of a :class:`ClosedLoop`: the simulator
    holds at each ``pause_at`` (the first given at its start, the next with each change)
    and is resumed to run to it."""

    def __init__(self, loop: ClosedLoop) -> None:
        self.loop = loop
        self._controllers = {r.name: r.controller for r in loop.robots}

    def send_reference(
        self, namespace, joints, positions, times, velocities=None, accelerations=None
    ) -> None:
        self.loop.probe.send_reference(
            list(joints),
            positions,
            times,
            velocities=velocities,
            accelerations=accelerations,
            namespace=namespace,
        )

    def run_until(self, t: float) -> None:
        self.loop.resume()
        self.loop.hold_at(t)

    def positions(self, namespace: str = "") -> np.ndarray:
        _, q, _, _ = self.loop.probe.recordings[namespace].arrays()
        return q[-1]

    def gains(self, namespace: str = "") -> np.ndarray:
        config = self.loop.probe.controller_config(
            self._controllers[namespace], namespace, self.loop.group.check_alive
        )
        if config.get("kp") is None:
            raise RuntimeError("the gains are not designed yet (no state answered)")
        return np.array(config["kp"], dtype=float)

    def set_controller(self, namespace: str, changes: Mapping[str, Any]) -> None:
        _set(self.loop, in_namespace(namespace, self._controllers[namespace]), dict(changes))

    def set_plant(self, changes: Mapping[str, Any]) -> None:
        _set(self.loop, "sim_bridge", dict(changes))


def _drive(loop: RunLoop, scenario: Scenario, duration: float, results: list[RunResult]) -> None:
    """Send each robot's reference, run to each scheduled change (one robot only) and
    apply it there, run to the end."""
    setups = scenario.setups()
    models = [values.controller_model(s.controller, s.robot, s.parameters) for s in setups]
    trajectories = [_reference(s, m.n, duration) for s, m in zip(setups, models, strict=True)]
    for s, model, traj in zip(setups, models, trajectories, strict=True):
        loop.send_reference(
            s.name,
            model.joint_names,
            traj.positions,
            traj.times,
            velocities=traj.velocities,
            accelerations=traj.accelerations,
        )
    changes = scenario.changes_within(duration)
    result, traj, first = results[0], trajectories[0], setups[0]
    ns = first.name
    estimate = None
    loop.run_until(changes[0].at if changes else duration)
    for k, change in enumerate(changes):
        q = loop.positions(ns)
        controller = dict(change.controller)
        if change.update == "iterative_gravity":
            if estimate is None:  # the controller's u at the start
                given = values.controller_values(first.controller, first.robot, first.parameters)
                estimate = per_joint(given["gravity_estimate"], len(q), "gravity_estimate")
            # q_d the reference's last point, K_P the gains in force
            estimate = iterative_gravity_estimate(loop.gains(ns), traj.positions[-1], q, estimate)
            controller["gravity_estimate"] = estimate.tolist()
        result.events.append(
            {"t": change.at, "q": q.tolist(), "controller": controller, **change.plant}
        )
        nxt = changes[k + 1].at if k + 1 < len(changes) else duration
        loop.set_controller(ns, controller)
        loop.set_plant({**change.plant, "pause_at": nxt})
        loop.run_until(nxt)
    for s, r in zip(setups, results, strict=True):
        r.events.append({"t": duration, "q": loop.positions(s.name).tolist(), "end": True})


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
