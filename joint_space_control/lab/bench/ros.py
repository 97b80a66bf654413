"""Benchmarks over ROS 2: the lockstep loop between two processes, the plain rclpy ping-pong,
and the realtime loop at 1 kHz. Every part runs in a leased ROS domain (no other run on the
machine sees it) and stops every process it starts, also on error or Ctrl-C.

The loops are measured by the nodes themselves (their ``/diagnostics``, see
:mod:`joint_space_control.ros.loop_statistics`); the observer here subscribes to nothing
else, so the lockstep loop is exactly two processes exchanging messages.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import Any

import rclpy
import rclpy.duration
from diagnostic_msgs.msg import DiagnosticArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.client import RosClient
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.loop import wait_recorder_matched
from joint_space_control.processes.processes import ProcessGroup, isolated_env
from joint_space_control.ros.diagnostics import DIAGNOSTICS_QOS, statuses
from joint_space_control.ros.messages import REFERENCE_QOS

#: Controller parameters per law: well damped at 1 kHz on both robots (the PD gains are
#: designed per joint from B̂(q₀); the same kp, kd on every joint made iiwa's wrist
#: unstable: 1037 N·m computed on joint 7).
CONTROLLER_PARAMS = {
    "pd_gravity": {"omega_n": 20.0, "zeta": 1.0},
    "inverse_dynamics": {"omega_n": 20.0, "zeta": 1.0},
}
#: Set-point of every run: a step of 0.3 rad on every joint.
STEP = 0.3
#: What runs beside a loop while it is measured (bench.dashboard: the dashboard and a
#: browser on its page): called with the run's processes once the loop is connected and
#: paused, entered right before the resume and left after the measurement. What it yields
#: has ``ready(check)``, called once the loop runs (it returns when what runs beside is in
#: its steady state), and ``start()``, called at the mark the measurement starts from.
Beside = Callable[[ProcessGroup], AbstractContextManager[Any]]
#: The counters of ``total.*`` that :func:`_since` takes the difference of.
_COUNTERS = ("ticks", "late", "too_late")


def _beside(beside: Beside | None, group: ProcessGroup) -> AbstractContextManager[Any]:
    return nullcontext() if beside is None else beside(group)


def _mark(
    observer: Observer, side: Any, node_name: str, check: Callable[[], None]
) -> dict[str, float | str] | None:
    """With something beside the loop: once it is ready, the node's next diagnostics (the
    mark the measurement counts from); None without."""
    if side is None:
        return None
    side.ready(check)
    observer.spin_for(0.5, check)  # what queued up meanwhile
    observer.latest.pop(f"{node_name}: control loop", None)  # a fresh one
    mark = observer.wait_for_total(node_name, "total.seconds", 0.0, check, 30.0)
    side.start()
    return mark


def _since(mark: Mapping[str, Any] | None, status: dict[str, Any]) -> dict[str, Any]:
    """``status`` with its counters, seconds and rate since ``mark`` (the percentiles
    stay those since the first tick)."""
    if mark is None:
        return status
    out = dict(status)
    for key in _COUNTERS:
        out[f"total.{key}"] = float(status[f"total.{key}"]) - float(mark[f"total.{key}"])
    out["total.seconds"] = float(status["total.seconds"]) - float(mark["total.seconds"])
    out["total.rate_hz"] = out["total.ticks"] / out["total.seconds"]
    return out


#: What the loop as users run it adds to the bench's: the controller and the recorder on
#: simulated time (the README's first example sets ``use_sim_time:=true``).
AS_USERS_RUN_IT = {"use_sim_time": True}
#: The loop's topics the recorder must be matched with before the measurement starts.
RECORDED = ("/clock", "/joint_states", "/effort_command")


class Recording:
    """A :data:`Beside`: the recorder (default topics, ``use_sim_time``) in the run's
    domain, started while the loop is paused and ready once its subscriptions to
    :data:`RECORDED` are matched; stopped (its bag closed) when left."""

    def __init__(self, group: ProcessGroup, domain_id: int, output: Path) -> None:
        self.group, self.domain_id, self.output = group, domain_id, output

    def __enter__(self) -> Recording:
        self.node = self.group.start("recorder", {**AS_USERS_RUN_IT, "output": str(self.output)})
        client = RosClient(self.domain_id, f"jsc_bench_recording_{self.domain_id}")
        try:
            wait_recorder_matched(client, RECORDED, self.group.check_alive, timeout=30.0)
        finally:
            client.close()
        return self

    def ready(self, check: Callable[[], None]) -> None:
        check()

    def start(self) -> None:
        pass

    def __exit__(self, *exc: object) -> None:
        self.node.stop()
        del self.group.nodes[self.node.name]


def joints_of(robot: str) -> tuple[str, ...]:
    return RobotModel(resolve_robot(robot, "")).joint_names


class Observer(RosClient):
    """A client node in the run's domain: /diagnostics, the reference, the sim's services."""

    def __init__(self, domain_id: int) -> None:
        super().__init__(domain_id, f"jsc_bench_{domain_id}")
        self.latest: dict[str, dict[str, float | str]] = {}
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics", self._on_diagnostics, DIAGNOSTICS_QOS
        )
        self._ref_pub = self.node.create_publisher(JointTrajectory, "reference", REFERENCE_QOS)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        self.latest.update(statuses(msg))

    def status(self, node_name: str) -> dict[str, float | str] | None:
        return self.latest.get(f"{node_name}: control loop")

    def wait_for_loop(self, check: Callable[[], None], timeout: float = 30.0) -> None:
        """Until the simulator and a controller are connected both ways."""
        n = self.node
        self.spin_until(
            lambda: (
                n.count_subscribers("joint_states") >= 1
                and n.count_publishers("effort_command") >= 1
                and n.count_subscribers("effort_command") >= 1
                and self._ref_pub.get_subscription_count() >= 1
            ),
            timeout,
            "the simulator and the controller to connect",
            check,
        )

    def send_setpoint(self, joints: Sequence[str], value: float) -> None:
        msg = JointTrajectory(joint_names=list(joints))
        msg.points = [JointTrajectoryPoint(positions=[value] * len(joints))]
        self._ref_pub.publish(msg)
        if not self._ref_pub.wait_for_all_acked(rclpy.duration.Duration(seconds=10.0)):
            raise TimeoutError("reference not acknowledged")

    def wait_for_total(
        self, node_name: str, key: str, at_least: float, check: Callable[[], None], timeout: float
    ) -> dict[str, float | str]:
        """The first diagnostics of ``node_name`` whose ``key`` reached ``at_least``."""
        self.spin_until(
            lambda: float((self.status(node_name) or {}).get(key, -1.0)) >= at_least,
            timeout,
            f"{node_name} {key} >= {at_least}",
            check,
        )
        return dict(self.status(node_name))


def _summary(status: Mapping[str, Any], keys: Sequence[str]) -> dict[str, float]:
    """``{"p50_us": …}`` from ``total.<metric>.p50_us`` and the like."""
    return {k.rsplit(".", 1)[1]: float(status[k]) for k in keys}


def lockstep(
    workdir: Path,
    robot: str,
    laws: Sequence[str],
    seconds: float,
    log: Callable[[str], None],
    controller_params: Mapping[str, Any] | None = None,
    beside: Beside | None = None,
    recorded: bool = False,
    engine: str = "pybullet",
) -> list[dict[str, Any]]:
    """Lockstep throughput of sim_bridge + each law's controller (two processes) on
    ``robot``: ``seconds`` of wall time from the first tick, measured by the controller.
    ``controller_params``: added to each controller's (``use_sim_time``); ``beside``: what
    runs beside the loop during each measurement (:data:`Beside`; the figures are then
    counted from its mark: the rate, ticks and seconds, not the percentiles);
    ``recorded``: a :class:`Recording` beside it instead (one bag per law); ``engine``:
    sim_bridge's physics engine (its parameter ``engine``)."""
    joints = joints_of(robot)
    results = []
    with lease_domain() as lease, ProcessGroup(workdir, lease.domain_id) as group:
        group.start(
            "sim_bridge",
            {"robot": robot, "mode": "lockstep", "start_paused": True, "engine": engine},
        )
        observer = Observer(lease.domain_id)
        try:
            for law in laws:
                controller = _controller(law)
                log(f"lockstep {robot} {law}: {seconds:g} s")
                node = group.start(
                    controller,
                    {
                        "robot": robot,
                        "trigger": "state",
                        **CONTROLLER_PARAMS[law],
                        **(controller_params or {}),
                    },
                )
                observer.wait_for_loop(group.check_alive)
                observer.send_setpoint(joints, STEP)
                side_of = beside
                if recorded:
                    bag = group.workdir / f"bag_{law}"
                    side_of = lambda group, bag=bag: Recording(group, lease.domain_id, bag)  # noqa: E731
                with _beside(side_of, group) as side:
                    observer.trigger("/sim_bridge/resume", group.check_alive)
                    mark = _mark(observer, side, controller, group.check_alive)
                    since = float(mark["total.seconds"]) if mark else 0.0
                    status = observer.wait_for_total(
                        controller,
                        "total.seconds",
                        since + seconds,
                        group.check_alive,
                        60 + 20 * seconds,
                    )
                    status = _since(mark, status)
                    sim = observer.status("sim_bridge") or {}
                    observer.trigger("/sim_bridge/pause", group.check_alive)
                node.stop()
                del group.nodes[controller]
                results.append(
                    {
                        "robot": robot,
                        "law": law,
                        "engine": engine,
                        "steps_per_s": float(status["total.rate_hz"]),
                        "real_time_factor": float(status["total.rate_hz"]) * 1e-3,
                        "steps": int(float(status["total.ticks"])),
                        "callback": _summary(
                            status,
                            [
                                "total.compute.p50_us",
                                "total.compute.p99_us",
                                "total.compute.max_us",
                            ],
                        ),
                        "latency": _summary(
                            status,
                            [
                                "total.latency.p50_us",
                                "total.latency.p99_us",
                                "total.latency.max_us",
                            ],
                        ),
                        "sim_step_p50_us": float(sim.get("compute.p50_us", float("nan"))),
                    }
                )
        finally:
            observer.close()
    return results


def realtime(
    workdir: Path,
    robot: str,
    law: str,
    seconds: float,
    log: Callable[[str], None],
    thread_priority: int = 50,
    load: str = "quiet",
    controller_params: Mapping[str, Any] | None = None,
    beside: Beside | None = None,
    plant_params: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """sim_bridge in realtime mode at 1 kHz with the controller answering every state, for
    ``seconds`` from the resume: the simulator's schedule, jitter and latency, the brakes,
    and the scheduling the realtime threads got (``thread_priority`` asked of both nodes;
    ``load`` only labels the row: the caller makes it). ``controller_params`` and ``beside``
    as for :func:`lockstep`; ``plant_params`` added to sim_bridge's."""
    controller = _controller(law)
    joints = joints_of(robot)
    log(f"realtime {robot} {law}, {load}, thread_priority {thread_priority}: {seconds:g} s")
    with lease_domain() as lease, ProcessGroup(workdir, lease.domain_id) as group:
        group.start(
            "sim_bridge",
            {
                "robot": robot,
                "mode": "realtime",
                "start_paused": True,
                "command_timeout": 0.1,
                "thread_priority": thread_priority,
                **(plant_params or {}),
            },
        )
        group.start(
            controller,
            {
                "robot": robot,
                "trigger": "state",
                "thread_priority": thread_priority,
                **CONTROLLER_PARAMS[law],
                **(controller_params or {}),
            },
        )
        observer = Observer(lease.domain_id)
        try:
            observer.wait_for_loop(group.check_alive)
            observer.send_setpoint(joints, STEP)
            with _beside(beside, group) as side:
                observer.trigger("/sim_bridge/resume", group.check_alive)
                mark = _mark(observer, side, "sim_bridge", group.check_alive)
                since = float(mark["total.seconds"]) if mark else 0.0
                sim = observer.wait_for_total(
                    "sim_bridge",
                    "total.seconds",
                    since + seconds,
                    group.check_alive,
                    60 + 3 * seconds,
                )
                sim = _since(mark, sim)
                ctrl = observer.status(controller) or {}
        finally:
            observer.close()
    ticks = float(sim["total.ticks"])
    return {
        "robot": robot,
        "law": law,
        "load": load,
        "thread_priority": thread_priority,
        "policy": str(sim.get("scheduling.physics.policy", "")),
        "controller_policy": str(ctrl.get("scheduling.control_path.policy", "")),
        "brakes": int(float(sim.get("brake.engaged", 0))),
        "poll_fraction": float(sim.get("pacing.poll_fraction", float("nan"))),
        "seconds": float(sim["total.seconds"]),
        "ticks": int(ticks),
        "rate_hz": float(sim["total.rate_hz"]),
        "jitter": _summary(
            sim, ["total.jitter.p50_us", "total.jitter.p99_us", "total.jitter.max_us"]
        ),
        "latency": _summary(
            sim, ["total.latency.p50_us", "total.latency.p99_us", "total.latency.max_us"]
        ),
        "lateness": _summary(
            sim, ["total.lateness.p50_us", "total.lateness.p99_us", "total.lateness.max_us"]
        ),
        "late_fraction": float(sim["total.late"]) / ticks,
        "too_late_fraction": float(sim["total.too_late"]) / ticks,
        "on_time_fraction": 1.0 - float(sim["total.late"]) / ticks,
        "controller_callback": _summary(
            ctrl, ["total.compute.p50_us", "total.compute.p99_us", "total.compute.max_us"]
        )
        if ctrl
        else {},
    }


def pingpong(robot: str, seconds: float, log: Callable[[str], None]) -> dict[str, Any]:
    """The plain rclpy ping-pong (:mod:`joint_space_control.lab.bench.pingpong`) with the
    robot's joint names, two processes."""
    joints = ",".join(joints_of(robot))
    log(f"pingpong {robot}: {seconds:g} s")
    module = "joint_space_control.lab.bench.pingpong"
    with lease_domain() as lease:
        env = isolated_env(lease.domain_id)
        pong = subprocess.Popen(
            [sys.executable, "-m", module, "pong", "--joints", joints],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        try:
            ping = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    module,
                    "ping",
                    "--joints",
                    joints,
                    "--seconds",
                    str(seconds),
                ],
                env=env,
                capture_output=True,
                text=True,
                timeout=90 + seconds,
            )
        finally:
            _stop(pong)
    lines = [line for line in ping.stdout.splitlines() if line.startswith("{")]
    result = json.loads(lines[-1]) if lines else {"error": ping.stderr[-500:]}
    if "error" in result:
        raise RuntimeError(f"ping-pong failed: {result['error']}")
    return {"robot": robot, "joints": len(joints.split(",")), **result}


def _stop(proc: subprocess.Popen, timeout: float = 5.0) -> None:
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if proc.poll() is not None:
            return
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            continue


def _controller(law: str) -> str:
    from joint_space_control.lab.bench.compute import LAWS

    return LAWS[law]


def analyze_time(workdir: Path, seconds: float, log: Callable[[str], None]) -> dict[str, Any]:
    """Record ``seconds`` of a lockstep run (planar_2dof, PD + g) with the recorder, then
    time the ``jsc analyze`` pipeline on the bag (metrics, figures, report; without the
    summary ``jsc analyze`` prints)."""
    import yaml

    from joint_space_control.analysis.bag import BagError
    from joint_space_control.analysis.pipeline import ResultsWriteError, analyze_bag_to
    from joint_space_control.processes.loop import ClosedLoop

    log(f"jsc analyze: recording {seconds:g} s of simulated time")
    bag = workdir / "bag"
    with ClosedLoop(
        workdir / "logs",
        None,
        "planar_2dof",
        controller_params=CONTROLLER_PARAMS["pd_gravity"],
        record=bag,
    ) as loop:
        loop.start(list(joints_of("planar_2dof")), [[STEP, -STEP]])
        loop.run_until(seconds, timeout=120 + 20 * seconds)
        loop.pause()
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    messages = int(meta["rosbag2_bagfile_information"]["message_count"])
    t0 = time.perf_counter()
    try:
        analyze_bag_to(workdir / "report", bag)  # no progress callback: quiet
    except (BagError, ResultsWriteError) as err:
        raise RuntimeError(f"jsc analyze failed: {err}") from err
    elapsed = time.perf_counter() - t0
    return {
        "messages": messages,
        "seconds": elapsed,
        "seconds_per_million_messages": elapsed / messages * 1e6,
    }
