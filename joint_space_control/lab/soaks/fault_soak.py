"""``jsc soak --faults``: the realtime loop for an hour, one fault a minute, and what was
recorded says whether it survived each.

The loop is what a user runs: ``sim_bridge`` (realtime, 1 kHz physics, joint states at
``--rate``, 1 kHz unless a slower machine needs less), one controller answering every
joint state, the ``recorder`` writing a bag on the system clock (so that a restarted simulator,
whose time starts again at 0, does not send the bag back in time), the ``dashboard``, each a
process in a leased ROS domain with localhost discovery, and the reference generator, the
observer node of this process (:class:`~joint_space_control.lab.soaks.soak.SoakObserver`):
a move between two configurations every :data:`~joint_space_control.lab.soaks.soak.
MOVE_PERIOD` seconds, every command of the controller checked (finite, within the effort
limits), the processes' memory sampled.

The faults come from a seeded schedule (:mod:`~joint_space_control.lab.soaks.fault_schedule`),
each printed as it is injected, each logged with its start and its end (the wall time when it
was over: the process back and serving, the burst sent, the hogs stopped). A killed node is
restarted under its own name (its log kept per run: ``<name>.<k>.log``); a killed recorder
restarts into a new bag (``bags/NNN``). A node that exits without being killed ends the run:
a crash. The figures of the verdict are computed afterwards from the bags
(:mod:`joint_space_control.lab.soaks.fault_metrics`).
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.json_values import jsonable
from joint_space_control.lab.soaks.fault_figures import fault_figure
from joint_space_control.lab.soaks.fault_metrics import (
    FaultRecord,
    FaultThresholds,
    MemorySeries,
    evaluate,
    fault_verdict,
    format_summary,
    incarnation_memory,
    run_growth,
    summarize,
)
from joint_space_control.lab.soaks.fault_schedule import KINDS, ScheduledFault, fault_schedule
from joint_space_control.lab.soaks.fault_timeline import read_timeline
from joint_space_control.lab.soaks.loop_digest import format_loops, loop_windows
from joint_space_control.lab.soaks.node_logs import format_said, said_in, tracebacks
from joint_space_control.lab.soaks.soak import (
    CONTROLLERS,
    GAIN_SETS,
    MOVE_PERIOD,
    MOVE_TIME,
    PHYSICS_RATE,
    SETTLE,
    LoopRun,
    SoakObserver,
    cpu_of,
    memory_of,
    system_cpu,
)
from joint_space_control.lab.soaks.soak_metrics import (
    RSS_PARTS,
    CommandAudit,
    Criterion,
    format_cpu,
    move_targets,
    passed,
)
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.loop import wait_recorder_matched
from joint_space_control.processes.processes import ProcessGroup
from joint_space_control.recording.bag_writer import FLUSH_PERIOD
from joint_space_control.ros.messages import REFERENCE_QOS
from joint_space_control.ros.wire import JointStateImage

#: Topics the recorder keeps (the controller's ``~/state`` is added by name).
#: /diagnostics: each node's own account of its loop, once a second (printed when the soak
#: fails: which loop slowed or alarmed, and when).
RECORDED = ["/joint_states", "/effort_command", "/reference", "/diagnostics"]
#: How long a killed controller stays dead [s] (the plant brakes after command_timeout).
DEAD_TIME = 1.0
#: The rogue commander: how long [s], how often [Hz], and at what fraction of the limits.
ROGUE_TIME, ROGUE_RATE, ROGUE_FRACTION = 5.0, 200.0, 0.9
#: The rogue's torque changes sign every ROGUE_FLIP [s]: whichever way the arm would go.
ROGUE_FLIP = 0.5
#: CPU hogs [s]; the second /clock [s] and its rate [Hz].
HOG_TIME = 10.0
CLOCK_TIME, CLOCK_RATE = 2.0, 100.0
#: Points of the huge reference (1 ms apart).
HUGE_POINTS = 100_000
#: A process restarted must serve again within this long [s].
BACK_TIMEOUT = 60.0
#: What a dashboard's log says once it shows a robot with its plant (nodes/dashboard.py),
#: and how often [s] the soak reads a restarted dashboard's log for it.
DASHBOARD_SHOWS = "plant {plant}, controllers"
LOG_POLL = 0.2
#: Commands from the controller that show the loop running again after a fault.
RUNNING_COMMANDS = 200
#: The plant's command timeout [s] (the brakes engage after it).
COMMAND_TIMEOUT = 0.1
#: A killed recorder loses what it had not flushed (its ``flush_period``, FLUSH_PERIOD by
#: default), and the states on their way to it when it died: TAIL_MARGIN [s] more.
TAIL_MARGIN = 0.1
#: Faults during which the arm is to stay where it is (the plant braked, or a rogue
#: commanding it): no new move from the generator, and the motion judged.
HELD = ("kill_controller", "rogue_commander")
#: Faults that start from the arm at rest, with no move in progress: the huge reference
#: starts where the last move ended (from mid-move its first point would be a jump).
AT_REST = ("huge_reference",)
#: After a move's time, how long [s] the arm is given to come to rest before a held fault.
SETTLED = 0.5
#: A fault starts at least this long [s] after the previous one was over (its process back,
#: its burst sent), and the run lasts at least this long after the last: on a loaded machine
#: an injection can overrun the next fault's time, and a fault whose window ends as it is
#: over has no time to show the loop back (judged "not back").
QUIET = 5.0


@dataclass(frozen=True)
class FaultSoakOptions(LoopRun):
    minutes: float = 60.0
    period: float = 60.0  # [s] between faults
    seed: int = 0
    kinds: tuple[str, ...] = tuple(KINDS)


@dataclass
class Injected:
    """One fault as it happened: wall clock [s since the epoch] at its start and end."""

    index: int
    kind: str
    start: float
    end: float = math.nan
    detail: str = ""
    ok: bool = True  # what the injection itself expected happened (e.g. updates refused)


class FaultObserver(SoakObserver):
    """The soak's observer, auditing only the controller's own commands (the rogue's and the
    malformed ones go to the same topic: the plant judges those)."""

    def __init__(self, domain_id: int, audit: CommandAudit, controller: str) -> None:
        self.sender = f"/{controller}"
        self.others = 0  # commands from anyone else
        super().__init__(domain_id, audit)

    def _on_command(self, raw: bytes, info: dict[str, int]) -> None:
        image = self._image
        if image is None or not image.matches(raw):
            msg = deserialize_message(raw, JointState)
            if msg.header.frame_id != self.sender:
                self.others += 1
                return
            self._image = JointStateImage.like(msg)
        super()._on_command(raw, info)


class FaultSoak:
    """The run: the processes, the observer, the schedule and one injector per kind."""

    def __init__(self, out: Path, options: FaultSoakOptions, log: Callable[[str], None]):
        self.out, self.options, self.log = out, options, log
        if options.law not in CONTROLLERS:
            raise ValueError(f"unknown controller law '{options.law}'; known: {list(CONTROLLERS)}")
        self.controller = CONTROLLERS[options.law]
        self.model = RobotModel(resolve_robot(options.robot, ""))
        self.joints = list(self.model.joint_names)
        self.limits = np.asarray(self.model.effort_limits, dtype=float)
        self.targets = move_targets(*self.model.position_limits)
        self.audit = CommandAudit(tuple(self.joints), self.limits)
        self.schedule = fault_schedule(
            options.seconds, options.period, options.seed, options.kinds
        )
        self.injected: list[Injected] = []
        self.bags: list[Path] = []
        self.runs: dict[str, int] = {}  # starts of each node so far
        self.memory: dict[str, tuple[list[float], list[int]]] = {}
        # per sample, VmRSS's parts [bytes]: the process's own memory or mapped segments
        self.memory_parts: dict[str, list[dict[str, int]]] = {}
        # CPU time [s] at each sample, per process incarnation, of this harness ("soak") and
        # of the machine ("machine busy", "machine steal"): who was busy when a loop slowed
        self.cpu: dict[str, tuple[list[float], list[float]]] = {}
        self.pids: dict[str, int] = {}
        self._unmatched = ""  # why the restarted recorder was last found not matched
        self.crash: str | None = None
        # a fault whose process or loop did not come back (BACK_TIMEOUT): the run ends
        # there and is judged on what it recorded
        self.stuck: str | None = None
        self._moves = 0
        self._next_move = self._next_sample = 0.0
        self._moved_at = -math.inf
        self._holding = False  # no new move: the arm is to stay where it is
        self._t0 = 0.0
        self.port = _free_port()

    # -- the nodes -----------------------------------------------------------------------
    def _params(self, node: str) -> dict[str, Any]:
        robot = self.options.robot
        if node == "sim_bridge":
            return {
                "robot": robot,
                "mode": "realtime",
                "physics_rate": PHYSICS_RATE,
                "publish_rate": self.options.rate,
                "command_timeout": COMMAND_TIMEOUT,
                "start_paused": not self.runs.get("sim_bridge"),  # the first waits for all
            }
        if node == self.controller:
            return {"robot": robot, "trigger": "state", **GAIN_SETS[self.options.law][0]}
        if node == "recorder":
            bag = self.out / "bags" / f"{len(self.bags):03d}"
            bag.parent.mkdir(parents=True, exist_ok=True)
            self.bags.append(bag)
            return {
                "output": str(bag),
                "topics": [*RECORDED, f"/{self.controller}/state"],
            }
        return {"host": "127.0.0.1", "port": self.port}  # dashboard

    def start(self, node: str) -> None:
        k = self.runs.get(node, 0)
        self.runs[node] = k + 1
        executable = self.controller if node == self.controller else node
        started = self.group.start(executable, self._params(node), name=node, tag=f".{k}")
        key = f"{node}.{k}"
        self.pids[key] = started.proc.pid
        self.memory.setdefault(key, ([], []))

    def kill(self, node: str) -> None:
        process = self.group.nodes.pop(node)
        process.signal(signal.SIGKILL)
        process.stop()

    # -- the loop's duties ---------------------------------------------------------------
    def now(self) -> float:
        return time.monotonic() - self._t0

    def tick(self) -> None:
        """One turn: the group alive, a move when due, memory when due, the observer spun."""
        self.group.check_alive()
        now = self.now()
        if now >= self._next_move and not self._holding:
            self.observer.send_target(self.joints, self.targets[self._moves % 2], MOVE_TIME)
            self._moves += 1
            self._moved_at = now
            self._next_move = now + MOVE_PERIOD
        if now >= self._next_sample:
            self._sample(now)
            self._next_sample += 2.0
        self.observer.spin_once()

    def wait(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.tick()

    def wait_until(self, done: Callable[[], bool], what: str, timeout: float = BACK_TIMEOUT):
        end = time.monotonic() + timeout
        while not done():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out after {timeout:g} s waiting for {what}")
            self.tick()

    def _sample(self, now: float) -> None:
        for key, pid in self.pids.items():
            found = memory_of(pid)
            if found is not None:
                self.memory[key][0].append(now)
                self.memory[key][1].append(found[0])
                self.memory_parts.setdefault(key, []).append(found[1])
        used = {key: cpu_of(pid) for key, pid in [*self.pids.items(), ("soak", os.getpid())]}
        machine = system_cpu()
        used["machine busy"], used["machine steal"] = machine["busy"], machine["steal"]
        for key, seconds in used.items():
            if seconds is not None:
                t, cpu = self.cpu.setdefault(key, ([], []))
                t.append(now)
                cpu.append(seconds)

    def wait_running(self, what: str) -> None:
        """Until the controller's commands flow again (:data:`RUNNING_COMMANDS` more)."""
        start = self.audit.commands
        self.wait_until(lambda: self.audit.commands >= start + RUNNING_COMMANDS, what)

    def resend_target(self) -> None:
        """The current move again, for a controller that starts without a reference."""
        self.observer.send_target(self.joints, self.targets[(self._moves - 1) % 2], MOVE_TIME)

    # -- the faults ----------------------------------------------------------------------
    def inject(self, fault: ScheduledFault) -> Injected:
        """The fault, printed; where the arm's motion is judged (:data:`HELD`) or the fault
        starts from rest (:data:`AT_REST`), the move in progress is finished first and no
        new one starts until the fault is over."""
        held = fault.kind in HELD
        if held or fault.kind in AT_REST:
            self._holding = True
            self.wait_until(
                lambda: self.now() - self._moved_at >= MOVE_TIME + SETTLED,
                "the move in progress",
            )
        record = Injected(fault.index, fault.kind, time.time())
        self.log(
            f"  {self.now() / 60:6.2f} min  fault {fault.index + 1}/{len(self.schedule)}: "
            f"{fault.kind} ({KINDS[fault.kind]})"
        )
        try:
            getattr(self, f"_{fault.kind}")(record)
        except TimeoutError as err:  # not back: the fault is kept, the run ends (run())
            record.ok, record.detail = False, f"not back: {err}"
            self.injected.append(record)
            raise
        finally:
            record.end = time.time()
            if self._holding:
                self._holding = False
                self._next_move = max(self._next_move, self.now() + 1.0)
        if record.detail:
            self.log(f"               {record.detail}")
        return record

    def _kill_controller(self, record: Injected) -> None:
        self.kill(self.controller)
        self.wait(DEAD_TIME)
        self.start(self.controller)
        self.wait_running("the restarted controller's commands")
        self.resend_target()

    def _kill_simulator(self, record: Injected) -> None:
        self.kill("sim_bridge")
        self.start("sim_bridge")
        self.wait_running("the controller's commands to the restarted simulator")
        self.resend_target()

    def _kill_recorder(self, record: Injected) -> None:
        self.kill("recorder")
        self.start("recorder")
        self._unmatched = "no answer yet"
        try:
            self.wait_until(self._recorder_matched, "the restarted recorder's subscriptions")
        except TimeoutError as err:  # say which: a topic unmatched, or no answer at all
            raise TimeoutError(f"{err} (last: {self._unmatched})") from None
        record.detail = f"recording into {self.bags[-1].name}"

    def _recorder_matched(self) -> bool:
        try:
            wait_recorder_matched(self.observer, self.topics, self.group.check_alive, 0.5)
        except TimeoutError as err:
            self._unmatched = " ".join(str(err).split())
            return False
        return True

    def _rogue_commander(self, record: Injected) -> None:
        with self.observer.other_node("rogue_commander") as node:
            pub = node.create_publisher(JointState, "effort_command", 10)
            effort = ROGUE_FRACTION * self.limits
            before = self.observer.others
            start = time.monotonic()
            while (elapsed := time.monotonic() - start) < ROGUE_TIME:
                sign = 1.0 if int(elapsed / ROGUE_FLIP) % 2 == 0 else -1.0  # a push, then a pull
                msg = JointState(name=self.joints, effort=(sign * effort).tolist())
                msg.header.frame_id = "/rogue_commander"
                pub.publish(msg)
                self.wait(1.0 / ROGUE_RATE)
            record.detail = f"{self.observer.others - before} rogue commands sent"

    def _malformed_burst(self, record: Injected) -> None:
        n, nan = len(self.joints), math.nan
        with self.observer.other_node("malformed_sender") as node:
            effort = node.create_publisher(JointState, "effort_command", 10)
            states = node.create_publisher(JointState, "joint_states", 10)
            arrays = node.create_publisher(Float64MultiArray, "/sim_bridge/commands", 10)
            refs = node.create_publisher(JointTrajectory, "reference", 10)
            wrench = node.create_publisher(WrenchStamped, "/sim_bridge/wrench", 10)
            sent = 0

            def joint_state(names, values, frame="/malformed_sender") -> JointState:
                msg = JointState(name=list(names), position=list(values), effort=list(values))
                msg.velocity = list(values)
                msg.header.frame_id = frame
                return msg

            bad_values = [[nan] * n, [0.0] * (n - 1), [1e9] * n, [math.inf] + [0.0] * (n - 1)]
            unknown = [*self.joints[:-1], "no_such_joint"]
            messages: list[tuple[Any, Any]] = []
            for values in bad_values:
                messages += [(effort, joint_state(self.joints[: len(values)], values))]
                messages += [(states, joint_state(self.joints[: len(values)], values))]
                messages += [(arrays, Float64MultiArray(data=values))]
            messages += [(effort, joint_state(unknown, [0.0] * n))]
            messages += [(states, joint_state(unknown, [0.0] * n))]
            messages += [(refs, _trajectory(unknown, [[0.0] * n], [1.0]))]
            messages += [(refs, _trajectory(self.joints, [[nan] * n], [1.0]))]
            messages += [(refs, _trajectory(self.joints, [[0.0] * (n - 1)], [1.0]))]
            messages += [(refs, _trajectory(self.joints, [[0.0] * n] * 2, [1.0, 0.5]))]
            w = WrenchStamped()
            w.wrench.force.x = nan
            messages += [(wrench, w)]
            w2 = WrenchStamped()
            w2.header.frame_id = "no_such_link"
            w2.wrench.force.z = 10.0
            messages += [(wrench, w2)]
            for _ in range(3):
                for pub, msg in messages:
                    pub.publish(msg)
                    sent += 1
                    self.wait(0.005)
            record.detail = f"{sent} malformed messages on 5 inputs"

    def _invalid_parameters(self, record: Injected) -> None:
        nan = math.nan
        updates = [
            (self.controller, {"kp": -1.0}),
            (self.controller, {"kp": [1.0, 2.0]}),
            (self.controller, {"kp": nan}),
            (self.controller, {"kp": "stiff"}),
            (self.controller, {"robot": "planar_2dof"}),
            (self.controller, {"trigger": "sometimes"}),
            ("sim_bridge", {"command_timeout": 0.0}),
            ("sim_bridge", {"viscous_friction": -1.0}),
            ("sim_bridge", {"payload_mass": nan}),
            ("sim_bridge", {"mode": "lockstep"}),
            ("sim_bridge", {"max_torque_rate": [1.0, 2.0, 3.0]}),
            ("sim_bridge", {"reject_factor": 0.5}),
        ]
        refused = 0
        kept = True
        for node, values in updates:
            before = self.observer.get_parameters(node, list(values), check=self.tick)
            (result,) = self.observer.set_parameters(node, values, check=self.tick)
            refused += not result.successful
            after = self.observer.get_parameters(node, list(values), check=self.tick)
            kept &= _same(before, after)
        record.ok = refused == len(updates) and kept
        record.detail = f"{refused}/{len(updates)} invalid updates refused, old values " + (
            "kept" if kept else "NOT kept"
        )

    def _huge_reference(self, record: Injected) -> None:
        target = self.targets[(self._moves - 1) % 2]
        t = np.arange(1, HUGE_POINTS + 1) * 1e-3
        wiggle = 0.01 * np.sin(2 * np.pi * 0.5 * t)[:, None]
        positions = target + wiggle * np.ones(len(self.joints))
        # from a publisher of its own, destroyed after the fault, not the generator's (whose
        # writer keeps its last references): with the 10 MB one there, a restarted recorder
        # was twice not matched with the generator within 60 s (not understood further)
        msg = _trajectory(self.joints, positions, t)
        self._publish_reference("huge_reference_publisher", msg, after=1.0)
        record.detail = f"{HUGE_POINTS} points over {t[-1]:g} s"

    def _second_reference(self, record: Injected) -> None:
        other = self.targets[self._moves % 2]
        msg = _trajectory(self.joints, [other], [MOVE_TIME])
        self._publish_reference("second_reference_publisher", msg, after=0.5)

    def _publish_reference(self, name: str, msg: JointTrajectory, after: float) -> None:
        """``msg`` on ``reference`` from a node ``name`` of its own, once a subscriber is
        matched; the node is kept ``after`` [s] more, then destroyed."""
        with self.observer.other_node(name) as node:
            pub = node.create_publisher(JointTrajectory, "reference", REFERENCE_QOS)
            self.wait_until(lambda: pub.get_subscription_count() >= 1, "a reference subscriber")
            self.wait(0.5)  # matched on its side too
            pub.publish(msg)
            self.wait(after)

    def _cpu_hogs(self, record: Injected) -> None:
        cores = os.cpu_count() or 1
        code = (
            f"import time\nend = time.monotonic() + {HOG_TIME}\nwhile time.monotonic() < end: pass"
        )
        hogs = [subprocess.Popen([sys.executable, "-c", code]) for _ in range(cores)]
        try:
            self.wait(HOG_TIME)
        finally:
            for hog in hogs:
                if hog.poll() is None:
                    hog.kill()
                hog.wait()
        record.detail = f"{cores} busy processes"

    def _kill_dashboard(self, record: Injected) -> None:
        """Over when the restarted dashboard shows the robot with its plant (its log says
        so), not when its page answers: a restarted dashboard once served a page without the
        robot for 8 minutes (it had taken an unnamed endpoint for the plant)."""
        self.kill("dashboard")
        self.start("dashboard")
        self.wait_until(lambda: _port_open(self.port), "the restarted dashboard's page")
        dashboard = self.group.nodes["dashboard"]
        shown = DASHBOARD_SHOWS.format(plant="/sim_bridge")
        seen = _Every(LOG_POLL, lambda: shown in dashboard.log())
        self.wait_until(seen, f"the restarted dashboard to show the robot ({shown!r} in its log)")
        record.detail = "robot shown with its plant /sim_bridge"

    def _second_clock(self, record: Injected) -> None:
        with self.observer.other_node("second_clock") as node:
            pub = node.create_publisher(Clock, "/clock", 10)
            end = time.monotonic() + CLOCK_TIME
            sent = 0
            while time.monotonic() < end:
                pub.publish(Clock(clock=Time(sec=0, nanosec=sent)))
                sent += 1
                self.wait(1.0 / CLOCK_RATE)
            record.detail = f"{sent} /clock messages at t = 0"

    # -- the run -------------------------------------------------------------------------
    def run(self) -> None:
        options = self.options
        self.log(
            f"soak with faults: {options.robot} {self.controller}, realtime "
            f"{options.rate:g} Hz, "
            f"{options.minutes:g} min, a fault every {options.period:g} s "
            f"({len(self.schedule)} faults, seed {options.seed})"
        )
        self.topics = [*RECORDED, f"/{self.controller}/state"]
        with lease_domain() as lease, ProcessGroup(self.out / "logs", lease.domain_id) as group:
            self.group = group
            for node in ("sim_bridge", self.controller, "recorder", "dashboard"):
                self.start(node)
            self.observer = FaultObserver(lease.domain_id, self.audit, self.controller)
            try:
                self.observer.wait_for_loop(self.controller, group.check_alive)
                wait_recorder_matched(self.observer, self.topics, group.check_alive)
                settled = time.monotonic() + SETTLE
                self.observer.spin_until(
                    lambda: time.monotonic() >= settled, 5.0, "settling", group.check_alive
                )
                self.observer.trigger("/sim_bridge/resume", group.check_alive)
                self._t0 = time.monotonic()
                self.started = time.time()
                pending = list(self.schedule)
                quiet_until = 0.0  # the previous fault's end + QUIET [s from the start]
                try:
                    while pending or self.now() < max(options.seconds, quiet_until):
                        if pending and self.now() >= max(pending[0].at, quiet_until):
                            self.injected.append(self.inject(pending.pop(0)))
                            quiet_until = self.now() + QUIET
                        else:
                            self.tick()
                except RuntimeError as err:  # a node exited without being killed
                    self.crash = " ".join(str(err).split())[:2000]
                    self.log(f"  CRASH: {self.crash[:300]}")
                except TimeoutError as err:  # not back: judged, not thrown away
                    self.stuck = " ".join(str(err).split())[:2000]
                    self.log(f"  NOT BACK: {self.stuck[:300]}; the run ends here")
                self.ended = time.time()
                if self.crash is None:
                    self.observer.trigger("/sim_bridge/pause", group.check_alive)
                    self.observer.spin_for(1.0)
            finally:
                self.observer.close()


def _trajectory(joints, positions, times) -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(joints))
    for q, t in zip(positions, times, strict=True):
        sec, nsec = divmod(round(float(t) * 1e9), 1_000_000_000)
        msg.points.append(
            JointTrajectoryPoint(
                positions=[float(x) for x in q], time_from_start=Duration(sec=sec, nanosec=nsec)
            )
        )
    return msg


def _same(before: list[Any], after: list[Any]) -> bool:
    def norm(v: Any) -> Any:
        return list(v) if isinstance(v, list | tuple | np.ndarray) else v

    return all(norm(a) == norm(b) for a, b in zip(before, after, strict=True))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Every:
    """``check()`` called at most once per ``period`` [s]; the last answer in between."""

    def __init__(self, period: float, check: Callable[[], bool]) -> None:
        self.period, self.check = period, check
        self._next, self._last = 0.0, False

    def __call__(self) -> bool:
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.period
            self._last = self.check()
        return self._last


def _port_open(port: int) -> bool:
    """The dashboard's page answers (as a browser asks for it)."""
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=0.5) as page:
            return page.status == 200
    except OSError:
        return False


def run(
    out: Path, options: FaultSoakOptions = FaultSoakOptions(), log: Callable[[str], None] = print
) -> dict[str, Any]:
    """Run the soak with faults, judge it from its bags and write ``out/soak.json`` and
    ``out/soak.png``; returns the report (with its verdict)."""
    from joint_space_control.machine import machine, versions

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    soak = FaultSoak(out, options, log)
    soak.run()
    log(f"judging the run from its {len(soak.bags)} bags")
    report = assess(soak, out, log)
    report["machine"], report["versions"] = machine(), versions()
    (out / "soak.json").write_text(json.dumps(jsonable(report), indent=2) + "\n")
    return report


def assess(soak: FaultSoak, out: Path, log: Callable[[str], None]) -> dict[str, Any]:
    """What the bags, the logs and the memory samples say of the run."""
    thresholds = FaultThresholds(period_ns=round(1e9 / soak.options.rate))
    faults = [FaultRecord(f.index, f.kind, f.start, f.end, f.detail) for f in soak.injected]
    timeline = read_timeline(soak.bags, f"/{soak.controller}/state", log=log)
    assessment = evaluate(faults, timeline, soak.limits, thresholds, run_end=soak.ended)
    series = [
        MemorySeries(key.rsplit(".", 1)[0], int(key.rsplit(".", 1)[1]), t, rss)
        for key, (t, rss) in soak.memory.items()
    ]
    memory = incarnation_memory(series, thresholds.warmup_s)
    over_run = run_growth(series, thresholds.warmup_s)
    criteria = fault_verdict(faults, assessment, timeline.bags, thresholds, memory, over_run)
    found = tracebacks(out / "logs")
    loops = loop_windows(timeline.loops, soak.started)
    logged = said_in(out / "logs")
    criteria.append(
        Criterion(
            "no traceback in any node's log",
            not found,
            ", ".join(f"{name}: {count}" for name, count in found.items()) or "none",
        )
    )
    criteria.append(
        Criterion(
            "no node crashed (exited without being killed)",
            soak.crash is None,
            soak.crash or "none",
        )
    )
    criteria.append(
        Criterion(
            f"every fault's process and loop back within {BACK_TIMEOUT:g} s",
            soak.stuck is None,
            soak.stuck or "yes",
        )
    )
    refused = [f for f in soak.injected if not f.ok]
    criteria.append(
        Criterion(
            "every injection did what it must (invalid updates refused, old values kept)",
            not refused,
            "; ".join(f"fault {f.index + 1} {f.kind}: {f.detail}" for f in refused) or "yes",
        )
    )
    tails = [o for o in assessment.outcomes if o.lost_at_kill is not None]
    worst_tail = max((o.lost_at_kill for o in tails), default=0)
    criteria.append(
        Criterion(
            "a killed recorder lost at most what it had not flushed yet "
            f"({FLUSH_PERIOD:g} s + {TAIL_MARGIN:g} s of states)",
            worst_tail <= (FLUSH_PERIOD + TAIL_MARGIN) * 1000.0 if tails else None,
            f"largest tail {worst_tail} states over {len(tails)} kills"
            if tails
            else "no recorder killed",
        )
    )
    audit = soak.audit.figures()
    criteria.append(
        Criterion(
            "the controller's commands finite and within the effort limits",
            audit["violations"] == 0 and audit["commands"] > 0,
            f"{audit['commands']} checked, {audit['violations']} violations",
        )
    )
    figure = fault_figure(
        timeline,
        faults,
        out / "soak.png",
        assessment.outcomes,
        thresholds,
        title=f"Fault soak: {soak.options.robot} {soak.controller}",
    )
    summaries = summarize(assessment.outcomes)
    options = soak.options
    return {
        "options": {
            "minutes": options.minutes,
            "period_s": options.period,
            "seed": options.seed,
            "robot": options.robot,
            "controller": soak.controller,
            "kinds": list(options.kinds),
            "rate_hz": options.rate,
        },
        "started": soak.started,
        "ended": soak.ended,
        "duration_s": soak.ended - soak.started,
        "crash": soak.crash,
        "stuck": soak.stuck,
        "faults": [f.__dict__ for f in soak.injected],
        "outcomes": [asdict(o) for o in assessment.outcomes],
        "by_kind": [asdict(k) for k in summaries],
        "by_kind_text": format_summary(summaries),
        "states": {
            "lost_inside_bags": assessment.lost_inside,
            "lost_between_bags": assessment.lost_between,
            "lost_before_faults": assessment.lost_before_faults,
            "recorded": int(timeline.js_wall.size),
        },
        "efforts_beyond_limits": assessment.efforts_beyond,
        "peak_effort_over_limit": assessment.peak_effort_ratio,
        "commands": audit,
        "other_commands": soak.observer.others,
        "bags": [asdict(b) for b in timeline.bags],
        "memory": memory,
        "memory_over_run": over_run,
        # every sample, [s from the start, MB] per process incarnation: where it grew
        "memory_samples": {
            key: {
                "t": t,
                "rss_mb": [r / 1e6 for r in rss],
                **{
                    part: [p.get(part, 0) / 1e6 for p in soak.memory_parts.get(key, [])]
                    for part in RSS_PARTS
                },
            }
            for key, (t, rss) in soak.memory.items()
        },
        # every sample, [s from the start, CPU s used], and the cores each kept busy
        "cpu_samples": {key: {"t": t, "cpu_s": cpu} for key, (t, cpu) in soak.cpu.items()},
        "cpu_text": format_cpu(soak.cpu),
        "tracebacks": found,
        # what each node said: its loop per 10 s (/diagnostics), its log's warnings
        "loops": {name: [asdict(w) for w in rows] for name, rows in loops.items()},
        "loops_text": format_loops(loops),
        "logged": {name: [asdict(g) for g in groups] for name, groups in logged.items()},
        "logged_text": format_said(logged),
        "thresholds": asdict(thresholds),
        "figure": str(figure),
        "criteria": [{"name": c.name, "met": c.met, "detail": c.detail} for c in criteria],
        "passed": passed(criteria),
    }
