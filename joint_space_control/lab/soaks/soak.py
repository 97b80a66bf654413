"""A soak run: the realtime loop at 1 kHz for minutes, gains changed every second.

``sim_bridge`` (realtime, 1 kHz physics; joint states at 1 kHz, or at ``--rate`` on a machine
too slow for that) and one controller answering every joint state run as separate processes
in a leased ROS domain with localhost discovery. An observer node in this process

- sends smooth moves between two configurations inside the joint limits (a one-point
  trajectory reached after :data:`MOVE_TIME` seconds, a new one every :data:`MOVE_PERIOD`),
- changes the controller's ``kp``/``kd`` every second through the standard parameter services
  (``AsyncParameterClient``, what ``ros2 param set`` uses), alternating two valid sets, and
  every tenth second also sends one invalid update (a negative ``kp``) that must be rejected
  with the old values kept,
- checks every effort command it receives (finite, within the URDF effort limits),
- samples the resident memory (VmRSS) of every node process and of itself,
- keeps the newest ``/diagnostics`` status of each node.

At the end the simulator is paused, the last commands and the final diagnostics collected and
every process stopped (also on an error or Ctrl-C). The figures and the verdict come from
:mod:`joint_space_control.lab.soaks.soak_metrics`.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.json_values import jsonable
from joint_space_control.lab.soaks.soak_metrics import (
    CommandAudit,
    Thresholds,
    UpdateTally,
    memory_summary,
    move_targets,
    numeric_values,
    parse_cpu_seconds,
    parse_rss_parts,
    parse_system_cpu,
    parse_vmrss,
    passed,
    verdict,
)
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.client import RosClient
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.processes import ProcessGroup
from joint_space_control.ros.control_path import ControlPath
from joint_space_control.ros.diagnostics import DIAGNOSTICS_QOS, statuses
from joint_space_control.ros.messages import REFERENCE_QOS
from joint_space_control.ros.wire import JointStateImage

CONTROLLERS = {
    "pd_gravity": "pd_gravity_controller",
    "inverse_dynamics": "inverse_dynamics_controller",
}
#: Two valid gain sets per law, alternated every second. PD: torque gains [N·m/rad,
#: N·m·s/rad], well damped at 1 kHz on every built-in robot (as in ``jsc bench``); inverse
#: dynamics: accelerations per error (ω_n = 20 and 30 rad/s, ζ = 1).
GAIN_SETS = {
    "pd_gravity": ({"kp": 100.0, "kd": 10.0}, {"kp": 150.0, "kd": 12.0}),
    "inverse_dynamics": ({"kp": 400.0, "kd": 40.0}, {"kp": 900.0, "kd": 60.0}),
}
#: The plant's physics rate [Hz]; its joint states, which the controller answers one by one,
#: come at the loop's rate (``--rate``): 1 kHz, or a divisor of it on a machine too slow to
#: run the loop at 1 kHz beside the rest of the run.
PHYSICS_RATE = 1000.0
#: The invalid update sent every tenth second (K_P must be > 0).
INVALID_UPDATE = {"kp": -1.0}
#: Seconds between gain changes, and every how many changes an invalid one follows.
CHANGE_PERIOD = 1.0
INVALID_EVERY = 10
#: Reference: a new target every MOVE_PERIOD seconds, reached (at rest) MOVE_TIME after it.
MOVE_PERIOD = 4.0
MOVE_TIME = 2.0
#: Seconds between memory samples; default warm-up [s] left out of the growth fit.
SAMPLE_PERIOD = 2.0
#: The kernel's unit of CPU time in /proc [ticks per second].
CLOCK_TICKS = float(os.sysconf("SC_CLK_TCK"))
WARMUP = 10.0
#: Wait [s] between the graph being complete and the start (every endpoint matched).
SETTLE = 1.0
#: Wait [s] for a command before the observer serves the rest (parameters, diagnostics).
OBSERVED_WAIT = 0.005
COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=10000, reliability=ReliabilityPolicy.RELIABLE
)


def check_loop_rate(rate: float) -> None:
    """ValueError unless ``rate`` [Hz] is a whole divisor of :data:`PHYSICS_RATE` (the plant
    publishes every k-th physics step)."""
    steps = PHYSICS_RATE / rate if math.isfinite(rate) and rate > 0 else math.nan
    if not (math.isfinite(steps) and abs(steps - round(steps)) < 1e-9):
        raise ValueError(
            f"the loop's rate must divide the physics rate of {PHYSICS_RATE:g} Hz "
            f"(1000, 500, 250, 200, 125, 100, ...), not {rate:g}"
        )


@dataclass(frozen=True)
class LoopRun:
    """What every soak sets: how long it runs, the loop's robot and law, and the loop's rate
    [Hz] (the plant's joint states: a divisor of :data:`PHYSICS_RATE`, checked)."""

    minutes: float = 10.0
    robot: str = "iiwa"
    law: str = "inverse_dynamics"
    rate: float = PHYSICS_RATE

    def __post_init__(self) -> None:
        check_loop_rate(self.rate)

    @property
    def seconds(self) -> float:
        return self.minutes * 60.0


@dataclass(frozen=True)
class SoakOptions(LoopRun):
    warmup: float = WARMUP  # [s]; at most a third of a short run
    sample_period: float = SAMPLE_PERIOD
    thresholds: Thresholds = Thresholds()

    @property
    def warmup_s(self) -> float:
        return min(self.warmup, self.seconds / 3.0)


def rss_of(pid: int) -> int | None:
    """VmRSS [bytes] of a process, None when it is gone."""
    found = memory_of(pid)
    return None if found is None else found[0]


def memory_of(pid: int) -> tuple[int, dict[str, int]] | None:
    """VmRSS [bytes] of a process and its parts (:data:`.soak_metrics.RSS_PARTS`), None
    when it is gone."""
    try:
        with open(f"/proc/{pid}/status") as f:
            status = f.read()
    except OSError:
        return None
    rss = parse_vmrss(status)
    return None if rss is None else (rss, parse_rss_parts(status))


def cpu_of(pid: int) -> float | None:
    """CPU time [s] a process has used, None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return parse_cpu_seconds(f.read(), CLOCK_TICKS)
    except (OSError, IndexError, ValueError):
        return None


def system_cpu() -> dict[str, float]:
    """The machine's busy, idle and stolen CPU time [s] since boot (:func:`parse_system_cpu`)."""
    with open("/proc/stat") as f:
        return parse_system_cpu(f.read(), CLOCK_TICKS)


class SoakObserver(RosClient):
    """The observer node, in its own rclpy context in the run's domain: effort commands
    through a dedicated wait-set loop (every one of them, 1 kHz), the rest (parameters,
    services, /diagnostics) through an executor served between them."""

    def __init__(self, domain_id: int, audit: CommandAudit) -> None:
        super().__init__(domain_id, f"jsc_soak_{domain_id}")
        self.audit = audit
        self._image: JointStateImage | None = None
        self._commands = ControlPath(self.node)
        self._command_sub = self._commands.subscription(
            JointState, "effort_command", self._on_command, COMMAND_QOS, raw=True, drain=True
        )
        # Delivery of the commands to this observer [ns]: first and last stamp, the longest
        # wait between two arrivals and the longest time from publication to arrival.
        self.delivery = {"first_stamp": -1, "last_stamp": -1, "max_gap": 0, "max_lag": 0}
        self._last_arrival = -1
        self.latest: dict[str, dict[str, float | str]] = {}
        self.received: dict[str, int] = {}
        self.warnings: dict[str, int] = {}
        self.node.create_subscription(
            DiagnosticArray, "/diagnostics", self._on_diagnostics, DIAGNOSTICS_QOS
        )
        self._ref_pub = self.node.create_publisher(JointTrajectory, "reference", REFERENCE_QOS)

    def _on_command(self, raw: bytes, info: dict[str, int]) -> None:
        image = self._image
        if image is None or not image.matches(raw):
            msg = deserialize_message(raw, JointState)
            image = self._image = JointStateImage.like(msg)
        self.audit.check(image.names, image.read(raw, 2))
        d, stamp = self.delivery, JointStateImage.stamp(raw)
        if d["first_stamp"] < 0:
            d["first_stamp"] = stamp
        d["last_stamp"] = stamp
        arrival = info["received_timestamp"]
        if self._last_arrival >= 0:
            d["max_gap"] = max(d["max_gap"], arrival - self._last_arrival)
        self._last_arrival = arrival
        d["max_lag"] = max(d["max_lag"], arrival - info["source_timestamp"])

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for name, status in statuses(msg).items():
            self.latest[name] = status
            self.received[name] = self.received.get(name, 0) + 1
            if status.get("level", 0) != 0:
                self.warnings[name] = self.warnings.get(name, 0) + 1

    # -- spinning ----------------------------------------------------------------------
    def spin_once(self) -> None:
        """Commands for at most OBSERVED_WAIT, then everything else that is ready."""
        self._commands.spin_once(OBSERVED_WAIT)
        self.serve_ready()

    # -- the graph and the loop ----------------------------------------------------------
    def wait_for_loop(self, controller: str, check: Callable[[], None]) -> None:
        n = self.node
        for name in (controller, "sim_bridge"):
            self.parameter_client(name, 60.0, check)  # returns once its services are up
        self.spin_until(
            lambda: (
                n.count_publishers("joint_states") >= 1
                and n.count_subscribers("joint_states") >= 1
                and n.count_publishers("effort_command") >= 1
                and n.count_subscribers("effort_command") >= 2  # sim_bridge and this
                and self._command_sub.get_publisher_count() >= 1
                and self._ref_pub.get_subscription_count() >= 1
            ),
            60.0,
            "the simulator and the controller to connect",
            check,
        )

    def send_target(self, joints: Sequence[str], target: np.ndarray, move_time: float) -> None:
        """A one-point trajectory reached at rest ``move_time`` after receipt."""
        sec, nsec = divmod(round(move_time * 1e9), 1_000_000_000)
        msg = JointTrajectory(joint_names=list(joints))
        msg.points = [
            JointTrajectoryPoint(
                positions=[float(p) for p in target],
                time_from_start=Duration(sec=sec, nanosec=nsec),
            )
        ]
        self.send_reference(msg)

    def send_reference(self, msg: JointTrajectory) -> None:
        """A whole reference, as the generator sends it."""
        self._ref_pub.publish(msg)

    def close(self) -> None:
        self._commands.close()
        super().close()


def run(
    out: Path, options: SoakOptions = SoakOptions(), log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Run the soak, write ``out/soak.json`` and return the report (with its verdict)."""
    from joint_space_control.machine import CpuMeter, machine, versions

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if options.law not in CONTROLLERS:
        raise ValueError(f"unknown controller law '{options.law}'; known: {list(CONTROLLERS)}")
    controller = CONTROLLERS[options.law]
    model = RobotModel(resolve_robot(options.robot, ""))
    joints = model.joint_names
    targets = move_targets(*model.position_limits)
    gains = GAIN_SETS[options.law]
    audit = CommandAudit(joints, model.effort_limits)
    tally = UpdateTally()
    started_utc = datetime.now(UTC).isoformat(timespec="seconds")
    memory: dict[str, tuple[list[float], list[int]]] = {}
    log(
        f"soak: {options.robot} {controller}, realtime {options.rate:g} Hz, "
        f"{options.minutes:g} min "
        f"(warm-up {options.warmup_s:g} s), gains changed every {CHANGE_PERIOD:g} s"
    )
    with lease_domain() as lease, ProcessGroup(out / "logs", lease.domain_id) as group:
        check = group.check_alive
        group.start(
            "sim_bridge",
            {
                "robot": options.robot,
                "mode": "realtime",
                "physics_rate": PHYSICS_RATE,
                "publish_rate": options.rate,
                "start_paused": True,
                "command_timeout": 0.1,
            },
        )
        group.start(controller, {"robot": options.robot, "trigger": "state", **gains[0]})
        observer = SoakObserver(lease.domain_id, audit)
        try:
            observer.wait_for_loop(controller, check)
            pids = {name: node.proc.pid for name, node in group.nodes.items()}
            pids["jsc soak (observer)"] = os.getpid()
            memory = {name: ([], []) for name in pids}
            # The graph shows an endpoint before every writer has matched every reader: a
            # second of settling (the simulator is paused) so that no early message is lost.
            settled = time.monotonic() + SETTLE
            observer.spin_until(lambda: time.monotonic() >= settled, 5.0, "settling", check)
            observer.trigger("/sim_bridge/resume", check)
            steal = CpuMeter()
            t0 = time.monotonic()
            next_change, next_move, next_sample = 0.0, 0.0, 0.0
            changes, moves = 0, 0
            last_report = 0.0
            while (now := time.monotonic() - t0) < options.seconds:
                check()
                if now >= next_move:
                    observer.send_target(joints, targets[moves % 2], MOVE_TIME)
                    moves += 1
                    next_move += MOVE_PERIOD
                if now >= next_sample:
                    _sample_memory(memory, pids, now)
                    next_sample += options.sample_period
                if now >= next_change:
                    changes += 1
                    invalid = changes % INVALID_EVERY == 0
                    _change_gains(observer, controller, gains[changes % 2], invalid, tally, check)
                    next_change += CHANGE_PERIOD
                if now - last_report >= 60.0:
                    last_report = now
                    log(_progress(now, options.seconds, audit, tally, observer, controller))
                observer.spin_once()
            duration = time.monotonic() - t0
            cpu_steal = steal.steal()
            _sample_memory(memory, pids, duration)  # the last sample, at the end of the run
            # Stop the loop, take the commands still in flight, then wait for diagnostics
            # of an idle window: their totals are final.
            observer.trigger("/sim_bridge/pause", check)
            paused_at = dict(observer.received)
            observer.spin_until(
                lambda: all(
                    observer.received.get(name, 0) > paused_at.get(name, 0)
                    and float(observer.latest[name].get("ticks", 1.0)) == 0.0
                    for name in (f"{controller}: control loop", "sim_bridge: control loop")
                ),
                30.0,
                "the final diagnostics",
                check,
            )
            end = time.monotonic() + 0.5
            observer.spin_until(lambda: time.monotonic() >= end, 5.0, "the last commands", check)
        finally:
            observer.close()
    report = _report(
        options, controller, duration, memory, observer, audit, tally, started_utc, cpu_steal
    )
    report["machine"], report["versions"] = machine(), versions()
    report["source"] = _source()
    criteria = verdict(report, options.thresholds)
    report["criteria"] = [{"name": c.name, "met": c.met, "detail": c.detail} for c in criteria]
    report["passed"] = passed(criteria)
    (out / "soak.json").write_text(json.dumps(jsonable(report), indent=2) + "\n")
    return report


def _sample_memory(
    memory: dict[str, tuple[list[float], list[int]]], pids: dict[str, int], now: float
) -> None:
    """One VmRSS sample of every process (a process that is gone gives none)."""
    for name, pid in pids.items():
        rss = rss_of(pid)
        if rss is not None:
            memory[name][0].append(now)
            memory[name][1].append(rss)


def _change_gains(
    observer: SoakObserver,
    controller: str,
    gains: dict[str, float],
    invalid: bool,
    tally: UpdateTally,
    check: Callable[[], None],
) -> None:
    """Set ``gains`` (must be accepted); with ``invalid`` also send INVALID_UPDATE (must be
    rejected) and read the gains back (must still be ``gains``)."""
    results = observer.set_parameters(controller, gains, check=check)
    tally.valid(all(r.successful for r in results))
    if invalid:
        (result,) = observer.set_parameters(controller, INVALID_UPDATE, check=check)
        kept = observer.get_parameters(controller, list(gains), check=check)
        tally.invalid(
            not result.successful,
            result.reason,
            all(np.allclose(k, gains[n]) for k, n in zip(kept, gains, strict=True)),
        )


def _progress(
    now: float,
    total: float,
    audit: CommandAudit,
    tally: UpdateTally,
    observer: SoakObserver,
    controller: str,
) -> str:
    sim = observer.latest.get("sim_bridge: control loop", {})
    return (
        f"  {now / 60:5.1f}/{total / 60:g} min: {audit.commands} commands, "
        f"{audit.violations} violations, {tally.valid_accepted}/{tally.valid_sent} changes "
        f"accepted, {tally.invalid_rejected}/{tally.invalid_sent} invalid rejected, "
        f"sim late {sim.get('total.late', 'n/a')}, too late {sim.get('total.too_late', 'n/a')}"
    )


def _report(
    options: SoakOptions,
    controller: str,
    duration: float,
    memory: dict[str, tuple[list[float], list[int]]],
    observer: SoakObserver,
    audit: CommandAudit,
    tally: UpdateTally,
    started_utc: str,
    cpu_steal: float | None,
) -> dict[str, Any]:
    diagnostics = {
        name.removesuffix(": control loop"): numeric_values(status)
        for name, status in observer.latest.items()
    }
    ctrl = diagnostics.get(controller, {})
    sim = diagnostics.get("sim_bridge", {})
    mem = {}
    for name, (times, rss) in memory.items():
        mem[name] = {
            **memory_summary(times, rss, options.warmup_s),
            "node": name != "jsc soak (observer)",
        }
    return {
        "started_utc": started_utc,
        "robot": options.robot,
        "controller": controller,
        "law": options.law,
        "sim_mode": "realtime",
        "rate_hz": options.rate,
        "trigger": "state",
        "minutes_requested": options.minutes,
        "duration_s": duration,
        "warmup_s": options.warmup_s,
        "sample_period_s": options.sample_period,
        "gain_sets": list(GAIN_SETS[options.law]),
        "invalid_update": INVALID_UPDATE,
        "memory": mem,
        "ticks": {
            "sim_bridge": sim.get("total.ticks", math.nan),
            controller: ctrl.get("total.ticks", math.nan),
        },
        "late": sim.get("total.late", math.nan),
        "too_late": sim.get("total.too_late", math.nan),
        "controller_ticks": ctrl.get("total.ticks"),
        "commands": audit.figures(),
        "command_delivery": {
            "first_stamp_s": observer.delivery["first_stamp"] * 1e-9,
            "last_stamp_s": observer.delivery["last_stamp"] * 1e-9,
            "longest_gap_between_arrivals_ms": observer.delivery["max_gap"] * 1e-6,
            "longest_publication_to_arrival_ms": observer.delivery["max_lag"] * 1e-6,
        },
        "parameter_updates": tally.figures(),
        "diagnostics_received": {
            name.removesuffix(": control loop"): count for name, count in observer.received.items()
        },
        "diagnostics_warnings": {
            name.removesuffix(": control loop"): count for name, count in observer.warnings.items()
        },
        "diagnostics": diagnostics,
        "cpu_steal_fraction": cpu_steal,
        "thresholds": {
            "max_slope_mb_per_min": options.thresholds.max_slope_mb_per_min,
            "min_span_min": options.thresholds.min_span_min,
            "max_violations": options.thresholds.max_violations,
        },
    }


def _source() -> dict[str, Any] | None:
    """The commit of the package's checkout and the files changed in it (None outside git)."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True
        )
        status = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
        )
    except OSError:
        return None
    if commit.returncode != 0:
        return None
    changed = [line[3:] for line in status.stdout.splitlines()]
    return {"commit": commit.stdout.strip(), "changed_files": changed}
