"""Benchmarks without ROS: the control laws per tick, the Pinocchio calls they make, and the
closed loop of plant + law in one process (the ceiling for the loop over ROS)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.inverse_dynamics import inverse_dynamics
from joint_space_control.laws.pd_gravity import pid_torque_split
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.trajectories.reference import Reference, Sample, Trajectory

#: The laws benchmarked, by the controller that runs them.
LAWS = {
    "pd_gravity": "pd_gravity_controller",
    "inverse_dynamics": "inverse_dynamics_controller",
}


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
    """Per-tick time of ``law`` on ``robot`` as its controller computes it (model calls
    included), and of the Pinocchio calls alone, over ``ticks`` random states."""
    model = RobotModel(resolve_robot(robot, ""))
    states = _states(model, ticks, seed)
    gains = PDGains.build(model.n, 100.0, 20.0)
    samples = [Sample(qd, dqd, ddqd) for _, _, qd, dqd, ddqd in states]
    m, d = model.model, model.data
    if law == "pd_gravity":
        integral, estimate = np.zeros(model.n), np.zeros(model.n)

        def run_law(k: int) -> Any:
            q, dq = states[k][0], states[k][1]
            gravity = model.gravity(q) + estimate
            return pid_torque_split(q, dq, samples[k].q, integral, gains, gravity)

        configs = [model.configuration(s[0]) for s in states]

        def run_pinocchio(k: int) -> Any:
            return pin.computeGeneralizedGravity(m, d, configs[k])

        calls = "computeGeneralizedGravity"
    elif law == "inverse_dynamics":

        def run_law(k: int) -> Any:
            return inverse_dynamics(model, states[k][0], states[k][1], samples[k], gains)

        configs = [(model.configuration(s[0]), np.array(s[1])) for s in states]

        def run_pinocchio(k: int) -> Any:
            qc, v = configs[k]
            pin.crba(m, d, qc)
            pin.nonLinearEffects(m, d, qc, v)
            return pin.computeGeneralizedGravity(m, d, qc)

        calls = "crba + nonLinearEffects + computeGeneralizedGravity"
    else:
        raise ValueError(f"unknown law {law!r}; known: {list(LAWS)}")
    run_law(0), run_pinocchio(0)  # imports, first-call set-up
    return {
        "robot": robot,
        "law": law,
        "joints": model.n,
        "law_per_tick": percentiles_us(time_each(run_law, ticks)),
        "pinocchio_calls": calls,
        "pinocchio_per_tick": percentiles_us(time_each(run_pinocchio, ticks)),
    }


def in_process_loop(robot: str, law: str, steps: int) -> dict[str, Any]:
    """Closed loop of the PyBullet plant and ``law`` in one process, no ROS: steps per
    second of plant state → reference sample → law → clamp → plant step (1 kHz)."""
    from sim_bridge.plant import Plant  # pybullet: only where the plant is needed

    spec = resolve_robot(robot, "")
    model = RobotModel(spec)
    plant = Plant(spec, model.joint_names, 1000.0, locked_positions=model.locked_positions)
    try:
        n = model.n
        gains = (
            PDGains.build(n, 100.0, 20.0)
            if law == "pd_gravity"
            else PDGains.build(n, 400.0, 40.0)  # ω_n = 20 rad/s, ζ = 1
        )
        target = np.full(n, 0.3)
        reference = Reference(
            Trajectory.build(0.0, np.array([0.0]), target[None, :]),
            Sample(np.zeros(n), np.zeros(n), np.zeros(n)),
        )
        q, dq, effort = np.empty(n), np.empty(n), np.empty(n)
        integral = np.zeros(n)
        limits = plant.effort_limits

        def step(k: int) -> None:
            plant.read_state(q, dq, effort)
            ref = reference.sample(k * 1e-3)
            if law == "pd_gravity":
                split = pid_torque_split(q, dq, ref.q, integral, gains, model.gravity(q))
            else:
                split = inverse_dynamics(model, q, dq, ref, gains)
            plant.step(np.clip(split.total, -limits, limits), 1)

        step(0)
        t0 = time.perf_counter()
        per_step = time_each(step, steps)
        elapsed = time.perf_counter() - t0
    finally:
        plant.close()
    return {
        "robot": robot,
        "law": law,
        "steps": steps,
        "steps_per_s": steps / elapsed,
        "per_step": percentiles_us(per_step),
    }


def pacing_floor(seconds: float, late_us: float = 200.0, too_late_us: float = 1000.0) -> dict:
    """A Python thread paced at 1 kHz exactly as sim_bridge's realtime physics thread
    (:func:`sim_bridge.pacing.sleep_until`), doing nothing else and without ROS: how well
    this machine can hold 1 kHz at all."""
    import threading

    from sim_bridge import pacing

    n = max(1, round(seconds * 1000))
    lateness = np.zeros(n, dtype=np.int64)

    def run() -> None:
        pacing.set_timer_slack(1)
        deadline = time.perf_counter_ns() + 1_000_000
        for k in range(n):
            pacing.sleep_until(deadline)
            lateness[k] = time.perf_counter_ns() - deadline
            deadline += 1_000_000

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    late = lateness * 1e-3
    return {
        "seconds": seconds,
        "ticks": n,
        "lateness": percentiles_us(lateness),
        "on_time_fraction": float(np.mean(late <= late_us)),
        "too_late_fraction": float(np.mean(late > too_late_us)),
    }
