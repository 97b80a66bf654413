"""Benchmarks without ROS: the control laws per tick, the Pinocchio calls they make, the
closed loop of plant + law in one process (the ceiling for the loop over ROS), and one
physics step of the plant on each engine."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from joint_space_control.control import parameters as params
from joint_space_control.control.configure import controller_kind
from joint_space_control.control.controller import Controller
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import example_robot_data_share, resolve_robot

#: The laws benchmarked, by the controller that runs them.
LAWS = {
    "pd_gravity": "pd_gravity_controller",
    "inverse_dynamics": "inverse_dynamics_controller",
}


#: The gains benchmarked, by law: PD + g(q) with K_P = 100, K_D = 20 on every joint;
#: inverse dynamics (eq. 15) with ω_n = 20 rad/s, ζ = 1.
BENCH_PARAMETERS = {
    "pd_gravity": {"kp": 100.0, "kd": 20.0},
    "inverse_dynamics": {"omega_n": 20.0, "zeta": 1.0},
}


#: The robots of the physics-step rows: the built-in ones, and the arms of example-robot-data
#: (PyPI) in :data:`EXAMPLE_ROBOT_DATA` when it is installed.
PHYSICS_ROBOTS = ("planar_2dof", "iiwa", "panda", "ur5")
#: Arms of example-robot-data, by their file under its ``robots/`` folder.
EXAMPLE_ROBOT_DATA = {"ur5": "ur_description/urdf/ur5_robot.urdf"}


def make_controller(model: RobotModel, law: str) -> Controller:
    """The controller object its node runs for ``law`` with :data:`BENCH_PARAMETERS`,
    built from parameter values as the node builds it."""
    if law not in LAWS:
        raise ValueError(f"unknown law {law!r}; known: {list(LAWS)}")
    kind = controller_kind(LAWS[law])
    values = kind.values(robot=model.spec.name, **BENCH_PARAMETERS[law])
    return kind.controller(values, model)


def percentiles_us(samples_ns: Sequence[int] | np.ndarray) -> dict[str, float]:
    x = np.asarray(samples_ns, dtype=float) * 1e-3
    return {
        "p50_us": float(np.percentile(x, 50)),
        "p99_us": float(np.percentile(x, 99)),
        "max_us": float(x.max()),
        "samples": int(x.size),
    }


def time_each(call: Callable[[int], Any], n: int) -> list[int]:
    """Wall time [ns] of ``call(k)`` for k = 0..n−1, each timed on its own."""
    clock = time.perf_counter_ns
    out = [0] * n
    for k in range(n):
        t0 = clock()
        call(k)
        out[k] = clock() - t0
    return out


def _states(model: RobotModel, n: int, seed: int) -> list[tuple[np.ndarray, ...]]:
    """n random (q, q̇, q_d, q̇_d, q̈_d) inside the joint limits (±1 rad, ±1 rad/s...)."""
    rng = np.random.default_rng(seed)
    lo, hi = model.position_limits
    lo, hi = np.maximum(lo, -1.0), np.minimum(hi, 1.0)
    return [
        (
            rng.uniform(lo, hi),
            rng.uniform(-1, 1, model.n),
            rng.uniform(lo, hi),
            rng.uniform(-1, 1, model.n),
            rng.uniform(-1, 1, model.n),
        )
        for _ in range(n)
    ]


def law_timings(robot: str, law: str, ticks: int, seed: int = 0) -> dict[str, Any]:
    """Per-tick time of the controller object's ``step`` for ``law`` on ``robot`` (what its
    node calls every tick: reference sample, law with its model calls, gate and clamp), and
    of the Pinocchio calls alone, over ``ticks`` random states holding a set-point."""
    model = RobotModel(resolve_robot(robot, ""))
    states = _states(model, ticks, seed)
    controller = make_controller(model, law)
    m, d = model.model, model.data
    if law == "pd_gravity":
        configs = [model.configuration(s[0]) for s in states]

        def run_pinocchio(k: int) -> Any:
            return pin.computeGeneralizedGravity(m, d, configs[k])

        calls = "computeGeneralizedGravity"
    else:
        configs = [(model.configuration(s[0]), np.array(s[1])) for s in states]

        def run_pinocchio(k: int) -> Any:
            qc, v = configs[k]
            pin.crba(m, d, qc)
            pin.nonLinearEffects(m, d, qc, v)
            return pin.computeGeneralizedGravity(m, d, qc)

        calls = "crba + nonLinearEffects + computeGeneralizedGravity"

    def run_step(k: int) -> Any:
        return controller.step(k * 1e-3, states[k][0], states[k][1])

    run_step(0), run_pinocchio(0)  # imports, first-call set-up
    return {
        "robot": robot,
        "law": law,
        "joints": model.n,
        "law_per_tick": percentiles_us(time_each(run_step, ticks)),
        "pinocchio_calls": calls,
        "pinocchio_per_tick": percentiles_us(time_each(run_pinocchio, ticks)),
    }


def in_process_loop(robot: str, law: str, steps: int) -> dict[str, Any]:
    """The lockstep loop in one process (:class:`~joint_space_control.simulation.World`:
    sim_bridge's plant and sub-step loop, the controller's policy, no ROS, no bag): steps per
    second of measure → controller step → physics step (1 kHz), a 0.3 rad step on every
    joint."""
    from joint_space_control.simulation import Arm, World  # pybullet

    with World([Arm("", robot, LAWS[law], BENCH_PARAMETERS[law])]) as world:
        joints = world.controllers[0].joints
        world.send_reference("", joints, [[0.3] * len(joints)], [0.0])
        world.run_until(0.0)  # the first state answered: imports, first-call set-up
        period = world.period_ns * 1e-9
        per_step = time_each(lambda k: world.run_until((k + 1) * period), steps)
        elapsed = sum(per_step) * 1e-9
    return {
        "robot": robot,
        "law": law,
        "steps": steps,
        "steps_per_s": steps / elapsed,
        "per_step": percentiles_us(per_step),
    }


def simulate_call(
    robot: str, law: str, engine: str, seconds: float, repeats: int
) -> dict[str, Any]:
    """``simulate()`` as a user calls it: ``seconds`` of simulated time of ``robot`` under
    ``law`` (a 0.2 rad step on every joint, 1 kHz) on the plant ``engine``, with its
    ``Response`` and the step's metrics (``step_info``); the median of ``repeats`` calls,
    split into building the world, the loop and the response with its metrics. A sweep of
    such runs in one process gets ``runs_per_minute`` through."""
    from joint_space_control.simulation import Arm, World  # pybullet

    def once() -> tuple[float, float, float]:
        t0 = time.perf_counter()
        with World([Arm("", robot, LAWS[law], BENCH_PARAMETERS[law])], {"engine": engine}) as w:
            joints = w.controllers[0].joints
            w.send_reference("", joints, [[0.2] * len(joints)], [0.0])
            t1 = time.perf_counter()
            w.run_until(seconds)
            t2 = time.perf_counter()
            w.response().step_info()
            t3 = time.perf_counter()
        return t1 - t0, t2 - t1, t3 - t2

    once()  # imports, the description parsed once
    rows = np.array([once() for _ in range(repeats)])
    build, loop, response = (float(np.median(rows[:, k])) for k in range(3))
    total = float(np.median(rows.sum(axis=1)))
    return {
        "robot": robot,
        "law": law,
        "engine": engine,
        "seconds": seconds,
        "repeats": repeats,
        "total_ms": total * 1e3,
        "build_ms": build * 1e3,
        "loop_ms": loop * 1e3,
        "response_ms": response * 1e3,
        "runs_per_minute": 60.0 / total,
    }


def pacing_floor(
    seconds: float, priority: int = 0, late_us: float = 200.0, too_late_us: float = 1000.0
) -> dict:
    """A Python thread paced at 1 kHz exactly as sim_bridge's realtime physics thread
    (:func:`sim_bridge.pacing.sleep_until`, at SCHED_FIFO ``priority`` when given and
    permitted, with the same poll), doing nothing else and without ROS: how well this
    machine can hold 1 kHz at all."""
    import threading

    from joint_space_control import scheduling
    from sim_bridge import pacing

    n = max(1, round(seconds * 1000))
    lateness = np.zeros(n, dtype=np.int64)
    got: list[scheduling.Scheduling] = []

    def run() -> None:
        pacing.set_timer_slack(1)
        got.append(scheduling.configure_this_thread("floor", priority))
        spin = pacing.SPIN_FIFO_NS if got[0].policy == "SCHED_FIFO" else pacing.SPIN_NS
        deadline = time.perf_counter_ns() + 1_000_000
        for k in range(n):
            pacing.sleep_until(deadline, spin)
            lateness[k] = time.perf_counter_ns() - deadline
            deadline += 1_000_000

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    late = lateness * 1e-3
    return {
        "seconds": seconds,
        "ticks": n,
        "thread_priority": priority,
        "policy": got[0].policy,
        "lateness": percentiles_us(lateness),
        "on_time_fraction": float(np.mean(late <= late_us)),
        "too_late_fraction": float(np.mean(late > too_late_us)),
    }


def robot_parameters(robot: str) -> dict[str, Any] | None:
    """The node parameters that load ``robot``: a built-in name, or an arm of
    :data:`EXAMPLE_ROBOT_DATA` (None when example-robot-data is not installed)."""
    if robot not in EXAMPLE_ROBOT_DATA:
        return {"robot": robot}
    share = example_robot_data_share()
    if share is None:
        return None
    urdf = share / "example-robot-data" / "robots" / EXAMPLE_ROBOT_DATA[robot]
    return {"urdf_path": str(urdf), "package_paths": [str(share)]}


def engine_missing(engine: str) -> str | None:
    """Why a world of ``engine`` cannot open here (MuJoCo not installed, say); None when it
    can."""
    from sim_bridge.engines import open_world

    try:
        open_world(engine, 1000.0).close()
    except ValueError as err:
        return str(err)
    return None


def physics_steps(
    robots: Sequence[str], engines: Sequence[str], steps: int, repeats: int
) -> dict[str, Any]:
    """Wall time of one physics step of each robot's plant on each engine, in process:
    sim_bridge's plant built from its default parameter values as sim_bridge builds it
    (:class:`~sim_bridge.robot_plant.RobotPlant`; 1 kHz, no friction), each step
    ``plant.step(g(q))``, one sub-step under gravity compensation (Pinocchio's g at the
    state read before it, outside the timing), so the arm stays where it starts.

    ``repeats`` rounds, each running ``steps`` steps of every (robot, engine) in turn from
    its initial configuration at rest: ``us_per_step`` is the median over the rounds of the
    mean step [µs], so the engines of a robot are measured seconds apart on a drifting
    machine. A robot or engine that is not installed, or a description an engine refuses,
    is left out with the reason under ``skipped``."""
    from sim_bridge.engines import open_world
    from sim_bridge.parameters import PARAMETERS, robot_values
    from sim_bridge.robot_plant import RobotPlant

    skipped: list[str] = []
    runnable = []
    for engine in engines:
        why = engine_missing(engine)
        if why is None:
            runnable.append(engine)
        else:
            skipped.append(f"{engine}: {why}")
    plants: dict[tuple[str, str], RobotPlant] = {}
    worlds = []
    try:
        for robot in robots:
            given = robot_parameters(robot)
            if given is None:
                skipped.append(f"{robot}: example-robot-data is not installed")
                continue
            for engine in runnable:
                values = params.defaults(PARAMETERS, **given, engine=engine)
                world = open_world(engine, params.value(values, "physics_rate"))
                worlds.append(world)
                try:
                    plants[robot, engine] = RobotPlant(robot_values(values, ""), world)
                except ValueError as err:  # a description this engine cannot simulate
                    skipped.append(f"{robot} on {engine}: {err}")
        for plant in plants.values():
            _gravity_steps(plant, 10)  # first-call set-up
        times: dict[tuple[str, str], list[np.ndarray]] = {key: [] for key in plants}
        for _ in range(max(1, repeats)):
            for key, plant in plants.items():
                plant.reset()
                times[key].append(_gravity_steps(plant, steps))
    finally:
        for world in worlds:
            world.close()
    rows = []
    for (robot, engine), each in times.items():
        means = [float(t.mean()) * 1e-3 for t in each]
        rows.append(
            {
                "robot": robot,
                "engine": engine,
                "joints": plants[robot, engine].n,
                "steps": steps,
                "repeats": len(each),
                "us_per_step": float(np.median(means)),
                "us_per_step_repeats": means,
                "per_step": percentiles_us(np.concatenate(each)),
            }
        )
    return {"rows": rows, "skipped": skipped}


def _gravity_steps(robot: Any, steps: int) -> np.ndarray:
    """Wall time [ns] of each of ``steps`` physics steps of ``robot`` (a RobotPlant) under
    gravity compensation, τ = g(q) of the true state before the step."""
    plant, model = robot.plant, robot.model
    q, dq, effort = np.zeros(robot.n), np.zeros(robot.n), np.zeros(robot.n)
    clock = time.perf_counter_ns
    out = np.empty(steps, dtype=np.int64)
    for k in range(steps):
        plant.read_state(q, dq, effort)
        tau = model.gravity(q)
        t0 = clock()
        plant.step(tau)
        out[k] = clock() - t0
    return out
