"""``sim_bridge``: the plant as a ROS 2 node: one world, one or several robots, on PyBullet
(default) or MuJoCo (``engine``, :mod:`sim_bridge.engines`).

Publishes ``joint_states`` (position, velocity, and the motor torque applied during the last
step) and ``/clock``; applies effort commands from ``effort_command`` (JointState, joints by
name) or ``~/commands`` (Float64MultiArray in joint order). Two modes:

- ``realtime``: physics runs at ``physics_rate`` paced by the wall clock in its own thread,
  the state is published at ``publish_rate``, the newest valid command is held;
- ``lockstep``: the state for time t is published, the node waits for the command whose
  ``header.stamp`` is t (a ``~/commands`` message answers whatever state is pending), then
  steps to t + 1/publish_rate and publishes again. Nothing depends on the wall clock, so the
  same inputs give the same run. A state left unanswered for ``republish_period`` is sent
  again (late subscribers), with the same stamp. A state left unanswered for more than
  STALL_WARNING seconds (wall time) while a controller is connected (a publisher on
  ``effort_command`` or a subscriber of ``joint_states``) is reported at WARN, with its
  likely cause, once per episode (and at once when other commanders connect) and then every
  STALL_REPEAT seconds while it lasts.

Safe fallback: in realtime mode, when no valid command arrived for ``command_timeout``
(simulation time), and before the first command, the brakes are engaged (velocity servos
with zero target, limited to the effort limits): the arm stops and holds. In lockstep mode
time does not advance without a command, so there is nothing to time out.

One commander at a time (:mod:`sim_bridge.ownership`): the commands' ``header.frame_id``
names their sender; valid commands from another one than the owner are refused and counted
(``rejected.foreign_commands``) until the owner is silent for ``owner_timeout`` (at least
``command_timeout``: a stall of the owner brakes the arm but does not hand it to anyone
else), leaves the graph, or ``~/release`` is called. Every command received is judged (a
drained queue of 16).

As a ros2_control robot (``interface: ros2_control``): ``joint_states`` as
joint_state_broadcaster publishes it (every joint of the robot in its order, position,
velocity, effort; stamp = simulation time) and the commands of a forward effort controller
from ``effort_controller/commands`` (Float64MultiArray in the robot's joint order): the wrong
size dropped with a throttled line, anyone may command, and the last command is held for
ever (no brakes after ``command_timeout`` unless ``command_timeout`` is given), as a real
robot holds what its controller wrote last. The brakes hold the arm before the first
command (the controller is not active yet).

Services: ``~/reset`` (initial configuration, at rest; time keeps running forward),
``~/pause``, ``~/resume`` and ``~/release`` (std_srvs/Trigger).

Several robots in one world (``robots``; :mod:`sim_bridge.parameters`,
:mod:`sim_bridge.robot`): one PyBullet client, one ``/clock``, one physics rate and one mode;
each robot has its topics in its namespace (``<ns>/joint_states``, ``<ns>/effort_command``,
``<ns>/sim_bridge/commands``, ``.../wrench``, ``.../release``), its own commander and brakes.
In lockstep the world steps when every robot has the command for the current state; a robot
without an answer is named in the stall warning. ``/clock`` has one publisher per graph: a
``sim_bridge`` that finds another one at start refuses to start.

Imperfections, all off by default (docs/plant.md): the published positions and velocities
can be quantized and noisy (:mod:`sim_bridge.sensors`; one measurement per simulation
instant, so a state sent again carries the same numbers), the velocities left out
(``measure_velocity``), the joints given Coulomb friction and stiction, and a link pushed by
an external wrench, held from ``~/wrench`` (geometry_msgs/WrenchStamped, ``frame_id`` the
link) and scheduled from the ``wrench_*`` parameters (:mod:`sim_bridge.wrench`).

Loop statistics go to ``/diagnostics`` once a second: per lockstep step or realtime physics
tick, the period, the work of the tick, the lateness against the wall-clock schedule
(realtime) and the latency from publishing a state to receiving the command that answers it.
Commands are served by a dedicated wait-set loop and states are published as serialized
images (:mod:`joint_space_control.ros.control_path`, :mod:`joint_space_control.ros.wire`);
services, parameters and the republish timer run in a second thread, the realtime physics in
a third, all under one lock.
"""

from __future__ import annotations

import array
import math
import os
import signal
import threading
import time
from collections.abc import Mapping
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from joint_space_control.ros import parameters as params
from joint_space_control.ros.control_path import ControlPath
from joint_space_control.ros.diagnostics import LoopDiagnostics
from joint_space_control.ros.graph import node_names
from joint_space_control.ros.loop_statistics import LoopStatistics
from joint_space_control.ros.messages import (
    COMMAND_QOS,
    CONTROL_PUBLISHER_QOS,
    FORWARD_COMMAND_QOS,
    paused_message,
)
from joint_space_control.ros.node_main import run_node
from joint_space_control.ros.realtime_threads import RealtimeThreads
from joint_space_control.ros.wire import clock_bytes
from joint_space_control.throttle import ThrottledLog
from sim_bridge import pacing
from sim_bridge.engines import open_world
from sim_bridge.ownership import ARRAY_COMMANDER
from sim_bridge.parameters import (
    MODES,  # noqa: F401  (re-exported: the modes of the node)
    PARAMETERS,
    ROBOT_OWN,
    changed_by_robot,
    lockstep_period,
    prefixed,
    robot_names,
    robot_values,
)
from sim_bridge.robot import COUNTERS, SimRobot  # noqa: F401  (COUNTERS: re-exported)
from sim_bridge.torque_plant import PlantFaultError

#: How often [s] the graph is checked for an owner that left (and for another /clock).
OWNER_CHECK = 0.25
#: Recent states whose publication time is kept for the command latency (realtime).
SENT_HISTORY = 64
#: Realtime: a tick this far behind its schedule [ns] resets the schedule (machine stalled).
MAX_BEHIND_NS = 100_000_000
#: Lockstep: warn when a state stays unanswered this long [s, wall] with a controller around
#: (checked every quarter of it: the warning comes within a second).
STALL_WARNING = 0.75
#: ... and again every this long [s] while it stays unanswered.
STALL_REPEAT = 10.0
#: At start, how long [s] discovery is given (from the node's creation) to show another
#: publisher of /clock before this one publishes its own.
CLOCK_DISCOVERY = 0.5
#: ... and how long [s] one discovered later still counts as found at start (a loaded
#: machine discovers slowly): the node then stops with the same one line and exit code 2.
CLOCK_REFUSAL = 5.0
#: How long [s] a young simulator listens to /clock for another one running ahead of it.
CLOCK_ANSWER = 3.0
#: ... and by how much [ns] the other's time must be ahead of its own.
CLOCK_AHEAD_NS = 200_000_000
#: What the node publishes, subscribes to and serves: (kind, relative name, type, meaning),
#: rendered into docs/reference by joint_space_control.nodes.reference. With ``robots``
#: each robot's topics and ``~/release`` are in its namespace (``<robot>/joint_states``,
#: ``<robot>/sim_bridge/wrench``, ...); ``/clock`` and the other services are the world's.
INTERFACE = (
    (
        "publishes",
        "joint_states",
        "sensor_msgs/msg/JointState",
        "position [rad], velocity [rad/s] (empty with `measure_velocity: false`), effort = "
        "the torque applied during the last step [N·m]; stamp = simulation time",
    ),
    (
        "publishes",
        "~/true_joint_states",
        "sensor_msgs/msg/JointState",
        "the true state beside an imperfect measurement (noise, quantization, no velocity), "
        "while it has a subscriber",
    ),
    (
        "publishes",
        "/clock",
        "rosgraph_msgs/msg/Clock",
        "simulation time, every published state; one publisher per ROS domain",
    ),
    (
        "publishes",
        "/diagnostics",
        "diagnostic_msgs/msg/DiagnosticArray",
        "loop statistics, the owner, the brakes and the safety counters, once a second",
    ),
    (
        "subscribes",
        "effort_command",
        "sensor_msgs/msg/JointState",
        "effort [N·m] by joint name, any order; `header.frame_id` names the commander (one "
        "at a time); lockstep: the stamp is that of the state answered",
    ),
    (
        "subscribes",
        "~/commands",
        "std_msgs/msg/Float64MultiArray",
        "effort [N·m] in the robot's joint order, as ros2_control's forward command "
        "controller sends it (a commander of its own)",
    ),
    (
        "subscribes",
        "effort_controller/commands",
        "std_msgs/msg/Float64MultiArray",
        "only with `interface: ros2_control` (instead of `effort_command` and `~/commands`): "
        "effort [N·m] in the robot's joint order; the wrong size dropped; the last one held",
    ),
    (
        "subscribes",
        "~/wrench",
        "geometry_msgs/msg/WrenchStamped",
        "an external wrench on the link `header.frame_id` names, world frame, at the link "
        "frame's origin; held until the next one (zero removes it)",
    ),
    (
        "subscribes",
        "robot_description",
        "std_msgs/msg/String",
        "only with `robot:=topic`: the URDF text, latched (transient local)",
    ),
    (
        "subscribes",
        "/clock",
        "rosgraph_msgs/msg/Clock",
        "only in its first seconds, while another node publishes /clock: a simulator "
        "already running in the domain makes this one refuse to start",
    ),
    (
        "serves",
        "~/reset",
        "std_srvs/srv/Trigger",
        "every robot back to its initial configuration, at rest; time runs on",
    ),
    (
        "serves",
        "~/pause",
        "std_srvs/srv/Trigger",
        "stop stepping; answers `paused; last state stamped <ns> ns`",
    ),
    ("serves", "~/resume", "std_srvs/srv/Trigger", "step again; answers `running`"),
    (
        "serves",
        "~/release",
        "std_srvs/srv/Trigger",
        "free the plant from its commander: the next valid command claims it",
    ),
)


class SimBridge(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("sim_bridge", **kwargs)
        created = time.monotonic()
        overrides = getattr(self, "_parameter_overrides", {})
        given = overrides.get("robots")
        names = robot_names(given.value if given is not None else [])
        specs = PARAMETERS + tuple(spec for name in names for spec in prefixed(name))
        self._specs = specs
        params.declare(self, specs)
        v = params.current_values(self, specs)
        if names:
            ignored = sorted({spec.name for spec in ROBOT_OWN} & set(overrides))
            if ignored:
                self.get_logger().warning(
                    f"ignored top-level {', '.join(ignored)}: with 'robots' each robot's "
                    "parameters are <name>.<parameter>"
                )
        self.mode = params.value(v, "mode")
        physics_rate = params.value(v, "physics_rate")
        publish_rate = params.value(v, "publish_rate")
        substeps, self.physics_dt_ns = lockstep_period(v)
        self.substeps = substeps
        self.period_ns = substeps * self.physics_dt_ns
        self.command_timeout = params.value(v, "command_timeout")
        self.owner_timeout = params.value(v, "owner_timeout")
        self.reject_factor = params.value(v, "reject_factor")
        self.interface = params.value(v, "interface")
        # as a ros2_control robot the last command is held for ever, unless a
        # command_timeout is asked for
        self._hold_commands = self.interface == "ros2_control" and "command_timeout" not in (
            overrides
        )
        republish = params.value(v, "republish_period")
        self._open_world(v, names, physics_rate)
        self._refuse_second_clock(created)
        self._created = created
        self._init_loop_state(v)
        self._create_interfaces(v)
        self._start(republish, physics_rate, publish_rate)

    def _open_world(
        self, v: params.ParamValues, names: tuple[str, ...], physics_rate: float
    ) -> None:
        """The world of the engine the parameters name, each robot loaded into it (the
        world closed again when one cannot be), framed in PyBullet's window with ``gui``."""
        self.lock = threading.Lock()  # world and time, shared with the realtime thread
        # what may recur at every tick or message: one line a second per kind (throttle.py)
        self.log = ThrottledLog(self.get_logger())
        self.world = open_world(params.value(v, "engine"), physics_rate, gui=bool(v["gui"]))
        self.robots: list[SimRobot] = []
        try:
            for name in names or ("",):
                self.robots.append(SimRobot(self, name, robot_values(v, name), self.world))
        except Exception:
            self.world.close()
            raise
        self._plants = [robot.plant for robot in self.robots]
        if self.world.gui:  # every robot as it starts, no panels (PyBullet's window)
            from sim_bridge.view import frame_view

            bodies = [robot.plant.body for robot in self.robots]
            if len(bodies) == 1:
                frame_view(self.world.client, bodies)
            else:  # from the side: robots placed along x stand side by side
                frame_view(self.world.client, bodies, yaw=0.0, pitch=-15.0)

    def _init_loop_state(self, v: params.ParamValues) -> None:
        """The loop's time, the lockstep handshake, pausing, faults, latency and statistics."""
        self._foreign_clock = None  # a /clock subscription while young, to compare times
        self._listening_since = 0.0
        self._clock_ahead = False
        self.exit_error: str | None = None  # why the node stops by itself (run_node: exit 2)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._t_ns = 0
        self._last_state_ns: int | None = None  # stamp of the last state sent (~/pause says)
        self._awaiting: int | None = None  # lockstep: stamp of the state waiting for answer
        self._sent_wall = 0.0
        self._awaiting_since = 0.0  # when the awaited state was first published (monotonic)
        self._stall_warned = 0.0  # when the stall was last reported (monotonic; 0: not yet)
        self._stall_said: tuple[str, ...] = ()  # what was named then
        self._paused = bool(v["start_paused"])
        self._fault: str | None = None  # why the simulation stopped (blown up) until reset
        self._pause_at_ns = self._pause_time(v)
        self._running = True
        self._clock_said = False
        # Command latency: when each recent state was published (perf_counter ns).
        self._sent_stamp = array.array("q", [-1] * SENT_HISTORY)
        self._sent_at = array.array("q", [0] * SENT_HISTORY)
        self._latency_ns = -1  # realtime: of the newest command, for the next tick's row
        self.loop_stats = LoopStatistics()
        self._polled_ns = 0  # realtime: time the physics thread spent polling the clock
        self._polled_said = 0
        self._tick_sim_ns = self.period_ns if self.mode == "lockstep" else self.physics_dt_ns

    def _create_interfaces(self, v: params.ParamValues) -> None:
        """/clock, the control path (each robot's commands, at realtime priority in realtime
        mode), the services, /diagnostics and the commander check."""
        self._clock_pub = self.create_publisher(Clock, "/clock", CONTROL_PUBLISHER_QOS)
        self.control_path = ControlPath(self)
        # realtime: the physics thread and the command path are on time first (lockstep has
        # no deadline and runs flat out: at FIFO priority it would starve the machine)
        self.realtime = RealtimeThreads(self, v)
        if self.mode == "realtime":
            self.control_path.on_serve = lambda: self.realtime.configure("command path")
            self.control_path.on_executor = self.realtime.configure_executor
        for robot in self.robots:
            if robot.ros2_control:
                self.control_path.subscription(
                    Float64MultiArray,
                    robot.topics["commands"],
                    lambda msg, info, r=robot: self._on_forward(r, msg),
                    FORWARD_COMMAND_QOS,
                    drain=True,
                )
                continue
            self.control_path.subscription(
                JointState,
                robot.topics["effort_command"],
                lambda raw, info, r=robot: self._on_effort(r, raw),
                COMMAND_QOS,
                raw=True,
                drain=True,
            )
            self.control_path.subscription(
                Float64MultiArray,
                robot.topics["commands"],
                lambda msg, info, r=robot: self._on_array(r, msg),
                COMMAND_QOS,
                drain=True,
            )
            self.create_service(
                Trigger,
                robot.private + "release",
                lambda request, response, r=robot: self._on_release(r, response),
            )
        hardware = ", ".join(robot.spec.name for robot in self.robots)
        self._diagnostics = LoopDiagnostics(
            self, self.loop_stats, hardware, self._diagnostic_values, self._alarm
        )
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_service(Trigger, "~/pause", self._on_pause)
        self.create_service(Trigger, "~/resume", self._on_resume)
        self.create_timer(
            OWNER_CHECK, self._check_graph, clock=RosClock(clock_type=ClockType.STEADY_TIME)
        )

    def _start(self, republish: float, physics_rate: float, publish_rate: float) -> None:
        """Lockstep: the timers that send a state again and report a stall, and the first
        state; realtime: the physics thread. Says what runs."""
        if self.mode == "lockstep":
            self.create_timer(republish / 4, lambda: self._republish(republish))
            self.create_timer(
                STALL_WARNING / 4,
                self._check_stall,
                clock=RosClock(clock_type=ClockType.STEADY_TIME),
            )
            # The first state goes out from the control-path thread once it serves commands:
            # published here, its answer could arrive while the process still sets up (a
            # start-up garbage collection, say) and be overwritten in the keep-last-1 queue.
            self.control_path.post(self._publish_first_state)
        else:
            self._thread = threading.Thread(target=self._realtime_loop, daemon=True)
            self._thread.start()
        robots = "; ".join(
            (f"{r.name}: " if r.name else "") + f"{r.spec.name} {list(r.joints)}"
            for r in self.robots
        )
        self.get_logger().info(
            f"sim_bridge: {robots}, {self.mode} on {self.world.engine}, physics "
            f"{physics_rate:g} Hz, publish "
            f"{publish_rate:g} Hz" + (", paused" if self._paused else "")
        )

    # -- one clock per graph -----------------------------------------------------------
    def _clock_publishers(self) -> list[str]:
        """The nodes other than this one that publish /clock. A publisher with this node's
        own name is taken for a previous instance of it that was killed (its participant
        stays in the graph for a while after a SIGKILL): a restarted simulator starts."""
        me = self.get_fully_qualified_name()
        return sorted(node_names(self.get_publishers_info_by_topic("/clock")) - {me})

    def _refuse_second_clock(self, created: float) -> None:
        """Another node publishing /clock in this domain (a second simulator): refuse to
        start (ValueError: one line, exit code 2). Discovery had the model loading to find
        it, and at least CLOCK_DISCOVERY seconds."""
        time.sleep(max(0.0, CLOCK_DISCOVERY - (time.monotonic() - created)))
        others = self._clock_publishers()
        if others:
            self.world.close()
            raise ValueError(second_clock(others))

    # -- parameters --------------------------------------------------------------------
    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        values = params.with_changes(self, self._specs, changes)
        changed = {p.name for p in changes}
        try:
            timeout = params.value(values, "command_timeout")
            owner_timeout = params.value(values, "owner_timeout")
            reject_factor = params.value(values, "reject_factor")
            pause_at = self._pause_time(values)
            by_robot = changed_by_robot((r.name for r in self.robots), changed)
            updates = [
                robot.update(robot_values(values, robot.name), by_robot[robot.name])
                for robot in self.robots
                if robot.name in by_robot
            ]
        except ValueError as err:
            self.get_logger().warning(f"rejected parameter update: {err}")
            return SetParametersResult(successful=False, reason=str(err))
        with self.lock:
            for apply in updates:
                apply()
            self.command_timeout = timeout
            if "command_timeout" in changed:  # asked for: the brakes after it, again
                self._hold_commands = False
            self.owner_timeout = owner_timeout
            self.reject_factor = reject_factor
            if "pause_at" in changed:
                self._pause_at_ns = pause_at
        return SetParametersResult(successful=True)

    @staticmethod
    def _pause_time(values: Mapping[str, Any]) -> int | None:
        """``pause_at`` in ns, or None when off (0)."""
        value = params.value(values, "pause_at")
        return round(value * 1e9) if value > 0 else None

    # -- diagnostics -------------------------------------------------------------------
    def _diagnostic_values(self, summary: Mapping[str, float]) -> dict[str, Any]:
        realtime = self.mode == "realtime"
        values: dict[str, Any] = {
            "mode": self.mode,
            "engine": self.world.engine,
            "sim_time_s": self._t_ns * 1e-9,
            "real_time_factor": summary["rate_hz"] * self._tick_sim_ns * 1e-9,
        }
        if len(self.robots) > 1:
            values["robots"] = ", ".join(robot.name for robot in self.robots)
            values["braking"] = int(realtime and any(r.braking for r in self.robots))
        for robot in self.robots:
            values.update(robot.diagnostics(realtime))
        values.update(self.realtime.diagnostics())
        values.update(self._poll_fraction(summary))
        return values

    def _poll_fraction(self, summary: Mapping[str, float]) -> dict[str, float]:
        """Realtime: the share of the window the physics thread polled the clock (a CPU it
        keeps from normal threads at FIFO priority; pacing module docstring)."""
        if self.mode != "realtime":
            return {}
        polled, self._polled_said = self._polled_ns - self._polled_said, self._polled_ns
        seconds = summary["seconds"]
        return {"pacing.poll_fraction": polled * 1e-9 / seconds if seconds > 0 else 0.0}

    def _alarm(self) -> str | None:
        alarms = [a for r in self.robots if (a := r.alarm(self.command_timeout))]
        if self._fault is not None:
            alarms.insert(0, self._fault)
        return "; ".join(alarms) or None

    # -- publishing --------------------------------------------------------------------
    def _publish_state(self) -> None:
        """Publish /clock and every robot's joint state at the current time (lock held)."""
        if self._clock_pub.get_subscription_count():  # volatile: nobody listening, no loss
            self._clock_pub.publish(clock_bytes(self._t_ns))  # before the states, every step
        if self.mode == "lockstep":
            self._sent_wall = time.monotonic()
            if self._awaiting != self._t_ns:  # a new state (not sent again)
                self._awaiting_since = self._sent_wall
            self._awaiting = self._t_ns
        slot = (self._t_ns // self.period_ns) % SENT_HISTORY
        self._sent_stamp[slot] = self._t_ns
        self._sent_at[slot] = time.perf_counter_ns()
        for robot in self.robots:
            robot.publish_state(self._t_ns)
        self._last_state_ns = self._t_ns
        if self.mode == "lockstep" and self._pause_at_ns is not None:
            if self._t_ns >= self._pause_at_ns:
                # Paused with this state out: its answer is ignored; ~/resume sends the
                # same state again, and the controller repeats its answer to it.
                self._paused, self._pause_at_ns = True, None

    def _publish_first_state(self) -> None:
        with self.lock:
            if not self._paused and self._awaiting is None:
                self._publish_state()

    def _republish(self, after: float) -> None:
        with self.lock:
            if self._awaiting is not None and not self._paused:
                if time.monotonic() - self._sent_wall > after:
                    self._publish_state()

    def _check_stall(self) -> None:
        """Lockstep: report a state that stays unanswered while a controller is connected,
        naming the robots whose answer is missing."""
        with self.lock:
            waiting = self._awaiting is not None and not self._paused
            since, t_ns = self._awaiting_since, self._t_ns
            missing = [r for r in self.robots if r.answer is None]
        now = time.monotonic()
        if not waiting or now - since < STALL_WARNING:
            self._stall_warned = 0.0
            return
        lines, said = [], []
        for robot in missing:
            commanders = self.get_publishers_info_by_topic(robot.topics["effort_command"])
            listeners = self.get_subscriptions_info_by_topic(robot.topics["joint_states"])
            if not commanders and not listeners and len(self.robots) == 1:
                return  # nobody around: nothing to say
            names = tuple(sorted(node_names(commanders)))
            said.append(f"{robot.name}:{','.join(names)}")
            who = f"{robot.name}: " if robot.name else ""
            if commanders:
                lines.append(
                    f"{who}{', '.join(names)} publish(es) {robot.names['effort_command']}: "
                    "likely a controller with trigger: timer and use_sim_time:=true, which "
                    "waits for /clock, which a lockstep plant advances only on commands (use "
                    "trigger:=state or auto), or one that stamps its commands with another "
                    "time than the state's (header.stamp must be the state's stamp)"
                )
            elif listeners:
                subscribers = sorted(node_names(listeners))
                lines.append(
                    f"{who}{', '.join(subscribers)} subscribe(s) {robot.names['joint_states']} "
                    f"but nobody publishes {robot.names['effort_command']} (a controller "
                    "that failed to start, or one remapped to another command topic?)"
                )
            else:
                lines.append(
                    f"{who}no controller: nobody publishes {robot.names['effort_command']} "
                    "(in lockstep the world steps when every robot has answered)"
                )
        # again after STALL_REPEAT, or at once when other commanders are connected
        said = tuple(said)
        if self._stall_warned and said == self._stall_said:
            if now - self._stall_warned < STALL_REPEAT:
                return
        self._stall_warned, self._stall_said = now, said
        waited = f"the state at t={t_ns * 1e-9:.3f} s is unanswered for {now - since:.1f} s"
        self.get_logger().warning(f"lockstep: {waited}; " + "; ".join(lines))

    def _latency(self, stamp_ns: int, received: int) -> int:
        """From publishing the state stamped ``stamp_ns`` to ``received`` [ns]; -1 when that
        state is not among the recent ones."""
        slot = (stamp_ns // self.period_ns) % SENT_HISTORY
        if self._sent_stamp[slot] != stamp_ns:
            return -1
        return received - self._sent_at[slot]

    # -- commands ----------------------------------------------------------------------
    def _on_effort(self, robot: SimRobot, raw: bytes) -> None:
        received = time.perf_counter_ns()
        command = robot.read_effort(raw)
        if command is not None:
            stamp, tau = command
            self._command(robot, tau, stamp, received, robot.effort_reader.frame_id)

    def _on_array(self, robot: SimRobot, msg: Float64MultiArray) -> None:
        received = time.perf_counter_ns()
        tau = robot.read_array(msg)
        if tau is not None:
            self._command(robot, tau, None, received, ARRAY_COMMANDER)

    def _on_forward(self, robot: SimRobot, msg: Float64MultiArray) -> None:
        received = time.perf_counter_ns()
        tau = robot.read_forward(msg)
        if tau is not None:
            self._command(robot, tau, None, received, None)

    def _command(
        self,
        robot: SimRobot,
        tau: Any,
        stamp_ns: int | None,
        received: int,
        sender: str | None,
    ) -> None:
        """A valid command from ``sender`` (None: a ros2_control robot's, no commander)."""
        with self.lock:
            # one commander at a time: its silence is measured on simulation time in
            # realtime (as the brakes), on wall time in lockstep (time waits for commands)
            now = self._t_ns * 1e-9 if self.mode == "realtime" else time.monotonic()
            timeout = max(self.owner_timeout, self.command_timeout)
            if sender is not None and not robot.admit(sender, now, timeout):
                return
            if self.mode == "realtime":
                robot.tau, robot.tau_t_ns = tau, self._t_ns
                if stamp_ns is not None:
                    self._latency_ns = self._latency(stamp_ns, received)
                return
            if self._paused or self._awaiting is None:
                return
            if stamp_ns is not None and stamp_ns != self._awaiting:
                return  # answers an older state
            robot.answer = tau
            if any(r.answer is None for r in self.robots):
                return  # the world steps when every robot has answered
            latency = self._latency(self._awaiting, received)
            self._awaiting = None
            self._step_lockstep()
        self.loop_stats.tick(received, time.perf_counter_ns(), latency, -1, self.period_ns)

    def _step_lockstep(self) -> None:
        """Every robot's answer held over one period, the world stepped (lock held)."""
        answers = [robot.answer for robot in self.robots]
        for robot in self.robots:
            robot.answer = None
        try:
            self.world.step_torques(self._plants, answers, self.substeps, self._t_ns * 1e-9)
        except PlantFaultError as err:
            self._stop_on_fault(err)
            return
        self._t_ns += self.period_ns
        self._publish_state()

    def _stop_on_fault(self, err: PlantFaultError) -> None:
        """The simulation blew up (lock held): stop where it is, say so once at ERROR and
        on /diagnostics until ``~/reset`` starts it afresh (no state is published
        meanwhile: there is none worth acting on)."""
        self._fault = str(err)
        self._paused = True
        self._awaiting = None
        for robot in self.robots:
            robot.answer = None
        self.get_logger().error(f"{err}; call ~/reset to start again")

    def _check_graph(self) -> None:
        """Free a plant whose owner left the graph; say once that another node publishes
        /clock (executor thread)."""
        for robot in self.robots:
            present = robot.commanders_present()
            with self.lock:
                left = robot.ownership.left(present)
            if left is not None:
                who = f"{robot.name}: " if robot.name else ""
                self.get_logger().info(f"{who}{left or '(unnamed)'!r} left: the plant is free")
        if not self._clock_said:
            self._check_clock()

    def _check_clock(self) -> None:
        """Another /clock publisher (executor thread): a simulator younger than
        CLOCK_REFUSAL that hears a /clock ahead of its own time (the other has run longer)
        stops (one line, exit code 2); otherwise it says so once at ERROR."""
        others = self._clock_publishers()
        if not others:
            if self._foreign_clock is not None:  # it went (stopped itself): listen no more
                self.control_path.destroy_subscription(self._foreign_clock)
                self._foreign_clock = None
            return
        young = time.monotonic() - self._created < CLOCK_REFUSAL
        if young and self._foreign_clock is None:  # listen: the older one runs ahead
            self._foreign_clock = self.create_subscription(Clock, "/clock", self._on_clock, 10)
            self._listening_since = time.monotonic()
            return
        if not self._clock_ahead and self._foreign_clock is not None:
            if time.monotonic() - self._listening_since < CLOCK_ANSWER:
                return
        self._clock_said = True
        if self._foreign_clock is not None:
            self.control_path.destroy_subscription(self._foreign_clock)
            self._foreign_clock = None
        if self._clock_ahead:
            self.exit_error = second_clock(others)  # found at start, late: refused
            # stopped as by a signal (the clean path: the context goes down first, then
            # the threads; run_node then says why, exit code 2)
            os.kill(os.getpid(), signal.SIGTERM)
        else:
            self.get_logger().error(
                f"{', '.join(others)} publish(es) /clock too: use_sim_time nodes now see "
                "two clocks. One simulator per ROS domain (several robots: one world, "
                "docs/robots.md, Several robots)"
            )

    def _on_clock(self, msg: Clock) -> None:
        """A /clock message: this node's own (at or before its time) or another's."""
        t_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        if t_ns > self._t_ns + CLOCK_AHEAD_NS:
            self._clock_ahead = True

    def _on_release(self, robot: SimRobot, response: Trigger.Response) -> Any:
        with self.lock:
            message = robot.release()
        response.success, response.message = True, message
        who = robot.private if robot.name else "~/"
        self.get_logger().info(f"{who}release: {message}")
        return response

    # -- realtime ----------------------------------------------------------------------
    def _realtime_loop(self) -> None:
        """:meth:`_run_realtime` until the node closes. A signal (Ctrl-C, SIGTERM) shuts the
        context down from the main thread while this thread may be publishing: that ends
        the loop quietly, the main thread then closes the node (no traceback on a stop)."""
        try:
            self._run_realtime()
        except Exception:
            if self.context.ok():
                raise

    def _run_realtime(self) -> None:
        """Physics at ``physics_rate`` on the wall clock: tick k starts at t0 + k·dt (or as
        soon after as the machine allows; a tick more than 100 ms behind restarts the
        schedule instead of catching up)."""
        pacing.set_timer_slack(1)
        fifo = self.realtime.configure("physics").policy == "SCHED_FIFO"
        spin = pacing.SPIN_FIFO_NS if fifo else pacing.SPIN_NS
        dt = self.physics_dt_ns
        deadline = time.perf_counter_ns()
        k = 0
        while self._running:
            start = time.perf_counter_ns()
            with self.lock:
                ticking = not self._paused
                if ticking:
                    self._physics_step()
                    k += 1
                    if k % self.substeps == 0 and not self._paused:
                        self._publish_state()
                latency, self._latency_ns = self._latency_ns, -1
            end = time.perf_counter_ns()
            if ticking:
                self.loop_stats.tick(start, end, latency, start - deadline, dt)
            deadline += dt
            if end - deadline > MAX_BEHIND_NS:
                deadline = end
            self._polled_ns += pacing.sleep_until(deadline, spin)

    def _physics_step(self) -> None:
        """One physics step of the world: each robot under its command or its brakes."""
        t = self._t_ns * 1e-9
        timeout = math.inf if self._hold_commands else self.command_timeout
        for robot in self.robots:
            robot.begin_tick(self._t_ns, timeout)
        for robot in self.robots:
            robot.apply(0, t)
        try:
            self.world.step()
        except PlantFaultError as err:
            self._stop_on_fault(err)
            return
        for robot in self.robots:
            robot.end_tick()
        self._t_ns += self.physics_dt_ns

    # -- services ----------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self.lock:
            for robot in self.robots:
                robot.reset()
            if self._fault is not None:  # the stop of a blown-up simulation ends here
                self._fault, self._paused = None, False
            if self.mode == "lockstep" and not self._paused:
                self._publish_state()
        response.success, response.message = True, "reset to the initial configuration"
        return response

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self.lock:
            self._paused = True
            self._awaiting = None
            for robot in self.robots:
                robot.answer = None
            last = self._last_state_ns  # no state goes out after this, paused
        response.success, response.message = True, paused_message(last)
        return response

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self.lock:
            was_paused, self._paused = self._paused, False
            if self.mode == "realtime":
                for robot in self.robots:
                    robot.tau = None  # commands from before the pause are stale
            elif was_paused or self._awaiting is None:
                self._publish_state()
        response.success, response.message = True, "running"
        return response

    def close(self) -> None:
        self._running = False
        thread = getattr(self, "_thread", None)
        if thread is not None:
            thread.join(timeout=1.0)
        self.world.close()


def second_clock(others: list[str]) -> str:
    """Why a second simulator in a ROS domain does not start."""
    return (
        f"{', '.join(others)} already publish(es) /clock in this ROS domain: two clocks would "
        "make every use_sim_time node jump between two simulations. Put every robot in one "
        "world instead (one sim_bridge with 'robots': docs/robots.md, Several robots; example "
        "config/two_robots.yaml) or run the second simulation in another ROS_DOMAIN_ID"
    )


def main(args: list[str] | None = None) -> None:
    run_node(SimBridge, args)


if __name__ == "__main__":
    main()
