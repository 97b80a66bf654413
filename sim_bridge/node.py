"""``sim_bridge``: the PyBullet plant as a ROS 2 node.

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
(``rejected.foreign_commands``) until the owner is silent for ``command_timeout``, leaves the
graph, or ``~/release`` is called. Every command received is judged (a drained queue of 16).

Services: ``~/reset`` (initial configuration, at rest; time keeps running forward),
``~/pause``, ``~/resume`` and ``~/release`` (std_srvs/Trigger).

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
import threading
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from joint_space_control.laws.limits import beyond_bound
from joint_space_control.ros import parameters as params
from joint_space_control.ros import realtime_threads
from joint_space_control.ros.control_path import ControlPath
from joint_space_control.ros.diagnostics import LoopDiagnostics
from joint_space_control.ros.loop_statistics import LoopStatistics
from joint_space_control.ros.messages import (
    COMMAND_QOS,
    CONTROL_PUBLISHER_QOS,
    JointOrder,
    effort_arrays,
    float_array,
)
from joint_space_control.ros.node_main import run_node
from joint_space_control.ros.realtime_threads import RealtimeThreads
from joint_space_control.ros.wire import JointStateImage, JointStateReader
from sim_bridge import pacing
from sim_bridge.ownership import ARRAY_COMMANDER, CommandOwnership
from sim_bridge.plant import Plant, coulomb_bounds
from sim_bridge.sensors import Encoder
from sim_bridge.wrench import PROFILES, WrenchSchedule

MODES = ("realtime", "lockstep")
#: The safety counters of the plant (on /diagnostics; docs/safety.md).
COUNTERS = (
    "rejected.commands",
    "rejected.foreign_commands",
    "rejected.wrenches",
    "brake.engaged",
)
#: How often [s] the graph is checked for an owner that left.
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

POSITIVE = {"minimum": 0.0, "exclusive": True}
NONNEGATIVE = {"minimum": 0.0}

PARAMETERS = (
    params.ROBOT_PARAMETERS
    + realtime_threads.PARAMETERS
    + (
        params.ParamSpec("mode", "realtime", "Plant timing", read_only=True, choices=MODES),
        params.ParamSpec(
            "physics_rate",
            1000.0,
            "Physics step rate, a multiple of publish_rate",
            read_only=True,
            unit="Hz",
            **POSITIVE,
        ),
        params.ParamSpec(
            "publish_rate",
            1000.0,
            "Joint state rate (= command period in lockstep)",
            read_only=True,
            unit="Hz",
            **POSITIVE,
        ),
        params.ParamSpec(
            "initial_positions",
            0.0,
            "Initial joint positions (clipped into the joint limits)",
            read_only=True,
            dynamic=True,
            unit="rad",
        ),
        params.ParamSpec(
            "viscous_friction",
            0.0,
            "Plant viscous friction F (the URDF's joint damping is not applied)",
            dynamic=True,
            unit="N·m·s/rad",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "payload_mass",
            0.0,
            "Point mass at the centre of mass of the last joint's link (plant only)",
            unit="kg",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "command_timeout",
            0.1,
            "Realtime: brake when no valid command for this long",
            unit="s",
            **POSITIVE,
        ),
        params.ParamSpec(
            "max_torque_rate",
            0.0,
            "Torque-rate limit on the applied torque (0: off)",
            dynamic=True,
            unit="N·m/s",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "republish_period",
            0.5,
            "Lockstep: send an unanswered state again after this wall time",
            read_only=True,
            unit="s",
            **POSITIVE,
        ),
        params.ParamSpec(
            "start_paused", False, "Start paused (call ~/resume to run)", read_only=True
        ),
        params.ParamSpec(
            "pause_at",
            0.0,
            "Lockstep: pause once the state at this simulation time is published "
            "(0: never); setting it again re-arms it",
            unit="s",
            **NONNEGATIVE,
        ),
        params.ParamSpec("gui", False, "Open the PyBullet GUI", read_only=True),
        params.REJECT_FACTOR,
        # -- imperfections (docs/plant.md), all off by default --
        params.ParamSpec(
            "encoder_counts",
            0.0,
            "Encoder counts per revolution: published positions rounded to 2π/counts (0: off)",
            dynamic=True,
            unit="counts/rev",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "position_noise",
            0.0,
            "σ of the Gaussian noise on the published positions, before quantization",
            dynamic=True,
            unit="rad",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "velocity_noise",
            0.0,
            "σ of the Gaussian noise on the published velocities",
            dynamic=True,
            unit="rad/s",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "noise_seed",
            0,
            "Seed of the measurement noise (numpy default_rng); setting it restarts the noise",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "measure_velocity",
            True,
            "false: joint_states carry no velocities (an empty velocity array)",
            read_only=True,
        ),
        params.ParamSpec(
            "coulomb_friction",
            0.0,
            "Plant Coulomb friction F_c (a velocity motor with target 0 and at most F_c)",
            dynamic=True,
            unit="N·m or N",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "static_friction",
            0.0,
            "Stiction F_s >= F_c, held below 1e-3 rad/s (0: same as coulomb_friction)",
            dynamic=True,
            unit="N·m or N",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "wrench_link",
            "",
            "Link of the scheduled wrench ('': the last controlled joint's child link)",
        ),
        params.ParamSpec(
            "wrench_force",
            [0.0, 0.0, 0.0],
            "Scheduled force on the robot, world frame, at the link frame's origin (0: off)",
            kind="numbers",
            length=3,
            unit="N",
        ),
        params.ParamSpec(
            "wrench_torque",
            [0.0, 0.0, 0.0],
            "Scheduled torque on the robot, world frame (0 and a zero force: off)",
            kind="numbers",
            length=3,
            unit="N·m",
        ),
        params.ParamSpec(
            "wrench_profile", "step", "Scheduled wrench profile in time", choices=PROFILES
        ),
        params.ParamSpec(
            "wrench_start",
            0.0,
            "Scheduled wrench: start time (simulation)",
            unit="s",
            **NONNEGATIVE,
        ),
        params.ParamSpec(
            "wrench_duration", 0.0, "Scheduled wrench: length of a pulse", unit="s", **NONNEGATIVE
        ),
        params.ParamSpec(
            "wrench_frequency",
            0.0,
            "Scheduled wrench: frequency of a sinusoid",
            unit="Hz",
            **NONNEGATIVE,
        ),
    )
)


class SimBridge(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("sim_bridge", **kwargs)
        params.declare(self, PARAMETERS)
        v = params.current_values(self, PARAMETERS)
        model = params.robot_model(v, node=self)
        spec = model.spec
        self.joints = model.joint_names
        self.n = len(self.joints)
        self.mode = params.value(v, "mode")
        physics_rate = params.value(v, "physics_rate")
        publish_rate = params.value(v, "publish_rate")
        substeps = round(physics_rate / publish_rate)
        if substeps < 1 or abs(substeps * publish_rate - physics_rate) > 1e-6 * physics_rate:
            raise ValueError("physics_rate must be an integer multiple of publish_rate")
        self.substeps = substeps
        self.physics_dt_ns = round(1e9 / physics_rate)
        self.period_ns = substeps * self.physics_dt_ns
        self.command_timeout = params.value(v, "command_timeout")
        self.reject_factor = params.value(v, "reject_factor")
        republish = params.value(v, "republish_period")
        self.plant = Plant(
            spec,
            self.joints,
            physics_rate,
            friction=params.value(v, "viscous_friction", self.n),
            payload_mass=params.value(v, "payload_mass"),
            initial_positions=self._initial_positions(v, model),
            locked_positions=model.locked_positions,
            effort_limits=model.effort_limits,
            gui=bool(v["gui"]),
        )
        self.plant.set_torque_rate_limit(params.value(v, "max_torque_rate", self.n))
        for warning in self.plant.warnings:
            self.get_logger().warning(warning)
        try:
            self.plant.set_coulomb_friction(*self._coulomb(v))
            self.plant.set_wrench_schedule(self._schedule(v))
        except ValueError:
            self.plant.close()
            raise
        self.encoder = Encoder(self.n, *self._encoder(v), seed=self._seed(v))
        self._measure_velocity = bool(v["measure_velocity"])
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._lock = threading.Lock()  # plant and time, shared with the realtime thread
        self._order = JointOrder(self.joints)
        self._t_ns = 0
        self._tau: np.ndarray | None = None  # newest valid command (realtime)
        self._tau_t_ns = 0
        self._awaiting: int | None = None  # lockstep: stamp of the state waiting for answer
        self._sent_wall = 0.0
        self._awaiting_since = 0.0  # when the awaited state was first published (monotonic)
        self._stall_warned = 0.0  # when the stall was last reported (monotonic; 0: not yet)
        self._stall_nodes: tuple[str, ...] = ()  # the commanders named then
        self._paused = bool(v["start_paused"])
        self._pause_at_ns = self._pause_time(v)
        self._braking = True
        self._timed_out = False  # braking because commands stopped (not before the first)
        self.counts = dict.fromkeys(COUNTERS, 0)
        self._running = True
        # Command latency: when each recent state was published (perf_counter ns).
        self._sent_stamp = array.array("q", [-1] * SENT_HISTORY)
        self._sent_at = array.array("q", [0] * SENT_HISTORY)
        self._latency_ns = -1  # realtime: of the newest command, for the next tick's row
        self.loop_stats = LoopStatistics()
        self._polled_ns = 0  # realtime: time the physics thread spent polling the clock
        self._polled_said = 0
        self._tick_sim_ns = self.period_ns if self.mode == "lockstep" else self.physics_dt_ns

        velocities = self.n if self._measure_velocity else 0
        self._state_image = JointStateImage(self.joints, (self.n, velocities, self.n))
        self._q, self._dq = np.zeros(self.n), np.zeros(self.n)  # true state, when measured
        # The true state beside the measurement (imperfect measurement only): analysis of
        # noise experiments (the true error, the true final positions).
        self._true_image = JointStateImage(self.joints)
        self._true_pub = self.create_publisher(
            JointState, "~/true_joint_states", CONTROL_PUBLISHER_QOS
        )
        self._measured_ns: int | None = None  # time of the state in the image
        self._clock_msg = Clock()
        self._effort_reader = JointStateReader(
            self._order, (2,), lambda m: (effort_arrays(m, self._order),), allow_extra=False
        )
        self._state_pub = self.create_publisher(JointState, "joint_states", CONTROL_PUBLISHER_QOS)
        self._clock_pub = self.create_publisher(Clock, "/clock", CONTROL_PUBLISHER_QOS)
        self.control_path = ControlPath(self)
        # realtime: the physics thread and the command path are on time first (lockstep has
        # no deadline and runs flat out: at FIFO priority it would starve the machine)
        self.realtime = RealtimeThreads(self, v)
        if self.mode == "realtime":
            self.control_path.on_serve = lambda: self.realtime.configure("command path")
            self.control_path.on_executor = self.realtime.configure_executor
        self.control_path.subscription(
            JointState, "effort_command", self._on_effort, COMMAND_QOS, raw=True, drain=True
        )
        self.control_path.subscription(
            Float64MultiArray, "~/commands", self._on_array, COMMAND_QOS, drain=True
        )
        self._diagnostics = LoopDiagnostics(
            self, self.loop_stats, spec.name, self._diagnostic_values, self._alarm
        )
        self.create_subscription(WrenchStamped, "~/wrench", self._on_wrench, 10)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_service(Trigger, "~/pause", self._on_pause)
        self.create_service(Trigger, "~/resume", self._on_resume)
        self.create_service(Trigger, "~/release", self._on_release)
        self._ownership = CommandOwnership()
        self.create_timer(
            OWNER_CHECK, self._check_owner, clock=RosClock(clock_type=ClockType.STEADY_TIME)
        )

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
        self.get_logger().info(
            f"sim_bridge: {spec.name} {list(self.joints)}, {self.mode}, physics "
            f"{physics_rate:g} Hz, publish {publish_rate:g} Hz"
            + (", paused" if self._paused else "")
        )

    # -- parameters --------------------------------------------------------------------
    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        values = params.with_changes(self, PARAMETERS, changes)
        try:
            friction = params.value(values, "viscous_friction", self.n)
            payload = params.value(values, "payload_mass")
            timeout = params.value(values, "command_timeout")
            reject_factor = params.value(values, "reject_factor")
            pause_at = self._pause_time(values)
            max_rate = params.value(values, "max_torque_rate", self.n)
            coulomb = self._coulomb(values)
            schedule = self._schedule(values)
            encoder = self._encoder(values)
            seed = self._seed(values)
        except ValueError as err:
            self.get_logger().warning(f"rejected parameter update: {err}")
            return SetParametersResult(successful=False, reason=str(err))
        with self._lock:
            self.plant.set_friction(friction)
            self.plant.set_torque_rate_limit(max_rate)
            if payload != self.plant.payload_mass:
                self.plant.set_payload(payload)
            self.command_timeout = timeout
            self.reject_factor = reject_factor
            if coulomb != (tuple(self.plant.coulomb), tuple(self.plant.static)):
                self.plant.set_coulomb_friction(*coulomb)
            self.plant.set_wrench_schedule(schedule)
            self.encoder.configure(*encoder)
            if any(p.name == "noise_seed" for p in changes):
                self.encoder.reseed(seed)
            if any(p.name == "pause_at" for p in changes):
                self._pause_at_ns = pause_at
        return SetParametersResult(successful=True)

    def _coulomb(self, values: dict[str, Any]) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(F_c, F_s) per joint, checked (F_s = F_c where ``static_friction`` is 0)."""
        fc, fs = coulomb_bounds(
            params.value(values, "coulomb_friction", self.n),
            params.value(values, "static_friction", self.n),
        )
        return tuple(fc), tuple(fs)

    def _schedule(self, values: dict[str, Any]) -> WrenchSchedule:
        """The scheduled wrench; its link must be one of the plant's."""
        schedule = WrenchSchedule(
            params.value(values, "wrench_force"),
            params.value(values, "wrench_torque"),
            params.value(values, "wrench_profile"),
            params.value(values, "wrench_start"),
            params.value(values, "wrench_duration"),
            params.value(values, "wrench_frequency"),
            link=params.value(values, "wrench_link"),
        )
        try:
            self.plant.link_index(schedule.link)
        except ValueError as err:
            raise ValueError(f"'wrench_link': {err}") from None
        return schedule

    def _encoder(self, values: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            params.value(values, "encoder_counts", self.n),
            params.value(values, "position_noise", self.n),
            params.value(values, "velocity_noise", self.n),
        )

    @staticmethod
    def _seed(values: dict[str, Any]) -> int:
        seed = params.value(values, "noise_seed")
        if seed != int(seed):
            raise ValueError(f"'noise_seed' must be an integer, got {seed}")
        return int(seed)

    def _initial_positions(self, values: dict[str, Any], model: Any) -> np.ndarray:
        """``initial_positions``, clipped into the joint limits (with a log line when it
        had to be: a zero configuration can lie outside them, Panda joint 4 say)."""
        q0 = params.value(values, "initial_positions", self.n)
        clipped, outside = model.clip_into_limits(q0)
        if outside:
            self.get_logger().warning(
                f"initial positions of {outside} are outside their joint limits: clipped "
                f"into them, starting at {clipped.tolist()}"
            )
        return clipped

    @staticmethod
    def _pause_time(values: dict[str, Any]) -> int | None:
        """``pause_at`` in ns, or None when off (0)."""
        value = params.value(values, "pause_at")
        return round(value * 1e9) if value > 0 else None

    def _diagnostic_values(self, summary: Mapping[str, float]) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "sim_time_s": self._t_ns * 1e-9,
            "real_time_factor": summary["rate_hz"] * self._tick_sim_ns * 1e-9,
            "braking": int(self.mode == "realtime" and self._braking),
            "owner": self._ownership.owner or "",
            **self.counts,
            **self.realtime.diagnostics(),
            **self._poll_fraction(summary),
        }

    def _poll_fraction(self, summary: Mapping[str, float]) -> dict[str, float]:
        """Realtime: the share of the window the physics thread polled the clock (a CPU it
        keeps from normal threads at FIFO priority; pacing module docstring)."""
        if self.mode != "realtime":
            return {}
        polled, self._polled_said = self._polled_ns - self._polled_said, self._polled_ns
        seconds = summary["seconds"]
        return {"pacing.poll_fraction": polled * 1e-9 / seconds if seconds > 0 else 0.0}

    def _alarm(self) -> str | None:
        if self._timed_out:
            return f"no valid command for {self.command_timeout} s: brakes engaged"
        return None

    # -- publishing --------------------------------------------------------------------
    def _publish_state(self) -> None:
        """Publish /clock and the joint state at the current time (with the lock held)."""
        image = self._state_image
        exact = self.encoder.exact and self._measure_velocity
        if self._measured_ns != self._t_ns:  # a new state: measured once
            if exact:
                self.plant.read_state(image.position, image.velocity, image.effort)
            else:
                self.plant.read_state(self._q, self._dq, image.effort)
                self.encoder.measure(self._q, self._dq, image.position, image.velocity)
            self._measured_ns = self._t_ns
        image.set_stamp(self._t_ns)
        if not exact and self._true_pub.get_subscription_count():
            truth = self._true_image
            truth.position[:], truth.velocity[:], truth.effort[:] = self._q, self._dq, image.effort
            truth.set_stamp(self._t_ns)
            self._true_pub.publish(truth.to_bytes())
        if self._clock_pub.get_subscription_count():  # volatile: nobody listening, no loss
            clock = self._clock_msg.clock
            clock.sec, clock.nanosec = divmod(self._t_ns, 1_000_000_000)
            self._clock_pub.publish(self._clock_msg)
        if self.mode == "lockstep":
            self._sent_wall = time.monotonic()
            if self._awaiting != self._t_ns:  # a new state (not sent again)
                self._awaiting_since = self._sent_wall
            self._awaiting = self._t_ns
        slot = (self._t_ns // self.period_ns) % SENT_HISTORY
        self._sent_stamp[slot] = self._t_ns
        self._sent_at[slot] = time.perf_counter_ns()
        self._state_pub.publish(image.to_bytes())
        if self.mode == "lockstep" and self._pause_at_ns is not None:
            if self._t_ns >= self._pause_at_ns:
                # Paused with this state out: its answer is ignored; ~/resume sends the
                # same state again, and the controller repeats its answer to it.
                self._paused, self._pause_at_ns = True, None

    def _publish_first_state(self) -> None:
        with self._lock:
            if not self._paused and self._awaiting is None:
                self._publish_state()

    def _republish(self, after: float) -> None:
        with self._lock:
            if self._awaiting is not None and not self._paused:
                if time.monotonic() - self._sent_wall > after:
                    self._publish_state()

    def _check_stall(self) -> None:
        """Lockstep: report a state that stays unanswered while a controller is connected."""
        with self._lock:
            waiting = self._awaiting is not None and not self._paused
            since, t_ns = self._awaiting_since, self._t_ns
        now = time.monotonic()
        if not waiting or now - since < STALL_WARNING:
            self._stall_warned = 0.0
            return
        commanders = self.get_publishers_info_by_topic(self.resolve_topic_name("effort_command"))
        listeners = self.get_subscriptions_info_by_topic(self.resolve_topic_name("joint_states"))
        if not commanders and not listeners:
            return
        names = tuple(
            sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in commanders})
        )
        # again after STALL_REPEAT, or at once when other commanders are connected
        if self._stall_warned and names == self._stall_nodes:
            if now - self._stall_warned < STALL_REPEAT:
                return
        self._stall_warned, self._stall_nodes = now, names
        waited = f"the state at t={t_ns * 1e-9:.3f} s is unanswered for {now - since:.1f} s"
        if commanders:
            self.get_logger().warning(
                f"lockstep: {waited} while {', '.join(names)} publish(es) effort_command: "
                "likely a controller with trigger: timer and use_sim_time:=true, which waits "
                "for /clock, which a lockstep plant advances only on commands (use "
                "trigger:=state or auto), or one that stamps its commands with another time "
                "than the state's (header.stamp must be the state's stamp)"
            )
        else:
            names = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in listeners})
            self.get_logger().warning(
                f"lockstep: {waited}; {', '.join(names)} subscribe(s) joint_states but nobody "
                "publishes effort_command (a controller that failed to start, or one "
                "remapped to another command topic?)"
            )

    def _latency(self, stamp_ns: int, received: int) -> int:
        """From publishing the state stamped ``stamp_ns`` to ``received`` [ns]; -1 when that
        state is not among the recent ones."""
        slot = (stamp_ns // self.period_ns) % SENT_HISTORY
        if self._sent_stamp[slot] != stamp_ns:
            return -1
        return received - self._sent_at[slot]

    # -- commands ----------------------------------------------------------------------
    def _on_effort(self, raw: bytes, info: Any) -> None:
        received = time.perf_counter_ns()
        try:
            stamp, (tau,) = self._effort_reader.read(raw)
        except ValueError as err:
            self.counts["rejected.commands"] += 1
            self.get_logger().warning(f"rejected effort command: {err}", throttle_duration_sec=1.0)
            return
        if self._absurd(tau):
            return
        self._command(tau, stamp, received, self._effort_reader.frame_id)

    def _on_array(self, msg: Float64MultiArray, info: Any) -> None:
        received = time.perf_counter_ns()
        try:
            tau = float_array(msg, self.n)
        except ValueError as err:
            self.counts["rejected.commands"] += 1
            self.get_logger().warning(f"rejected command array: {err}", throttle_duration_sec=1.0)
            return
        if self._absurd(tau):
            return
        self._command(tau, None, received, ARRAY_COMMANDER)

    def _absurd(self, tau: np.ndarray) -> bool:
        """A command beyond ``reject_factor`` × the effort limits: rejected and counted (its
        sender is broken; clamping would apply the limit as if it meant it)."""
        if not beyond_bound(tau, self.plant.effort_limits, self.reject_factor):
            return False
        self.counts["rejected.commands"] += 1
        self.get_logger().warning(
            f"rejected command {tau.tolist()}: beyond {self.reject_factor:g} × the effort "
            f"limits {self.plant.effort_limits.tolist()} (reject_factor)",
            throttle_duration_sec=1.0,
        )
        return True

    def _command(self, tau: np.ndarray, stamp_ns: int | None, received: int, sender: str) -> None:
        with self._lock:
            # one commander at a time: its silence is measured on simulation time in
            # realtime (as the brakes), on wall time in lockstep (time waits for commands)
            now = self._t_ns * 1e-9 if self.mode == "realtime" else time.monotonic()
            if not self._ownership.admit(sender, now, self.command_timeout):
                self._foreign(sender)
                return
            if self.mode == "realtime":
                self._tau, self._tau_t_ns = tau, self._t_ns
                if stamp_ns is not None:
                    self._latency_ns = self._latency(stamp_ns, received)
                return
            if self._paused or self._awaiting is None:
                return
            if stamp_ns is not None and stamp_ns != self._awaiting:
                return  # answers an older state
            answered = self._awaiting
            self._awaiting = None
            latency = self._latency(answered, received)
            self.plant.step(tau, self.substeps, self._t_ns * 1e-9)
            self._t_ns += self.period_ns
            self._publish_state()
        self.loop_stats.tick(received, time.perf_counter_ns(), latency, -1, self.period_ns)

    def _foreign(self, sender: str) -> None:
        """A valid command from another commander than the owner: refused (lock held)."""
        self.counts["rejected.foreign_commands"] += 1
        owner = self._ownership.owner
        self.get_logger().warning(
            f"rejected a command from {sender or '(unnamed)'!r}: {owner or '(unnamed)'!r} "
            "commands this plant (it is freed when its commands stop for command_timeout, "
            "when it leaves, or by ~/release)",
            throttle_duration_sec=1.0,
        )

    def _check_owner(self) -> None:
        """Free the plant when its owner left the graph (executor thread)."""
        publishers = self.get_publishers_info_by_topic(self.resolve_topic_name("effort_command"))
        present = {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in publishers}
        if publishers:
            present.add("")  # an unnamed commander may be any of them
        if self.get_publishers_info_by_topic(self.resolve_topic_name("~/commands")):
            present.add(ARRAY_COMMANDER)
        with self._lock:
            left = self._ownership.left(present)
        if left is not None:
            self.get_logger().info(f"{left or '(unnamed)'!r} left: the plant is free")

    def _on_release(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self._lock:
            owner = self._ownership.release()
        response.success = True
        response.message = (
            f"released {owner or '(unnamed)'!r}" if owner is not None else "nobody owned it"
        )
        self.get_logger().info(f"~/release: {response.message}")
        return response

    def _on_wrench(self, msg: WrenchStamped) -> None:
        """Hold the wrench on the link ``header.frame_id`` names ('': the last controlled
        joint's child link) until the next message; a zero wrench removes it."""
        f, mu = msg.wrench.force, msg.wrench.torque
        try:
            with self._lock:
                self.plant.hold_wrench(msg.header.frame_id, (f.x, f.y, f.z), (mu.x, mu.y, mu.z))
        except ValueError as err:
            self.counts["rejected.wrenches"] += 1
            self.get_logger().warning(f"rejected wrench: {err}", throttle_duration_sec=1.0)

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
            with self._lock:
                ticking = not self._paused
                if ticking:
                    self._physics_step()
                    k += 1
                    if k % self.substeps == 0:
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
        fresh = (
            self._tau is not None and (self._t_ns - self._tau_t_ns) * 1e-9 <= self.command_timeout
        )
        if fresh:
            if self._braking:
                self.get_logger().info("valid commands: torque control")
                self._braking = self._timed_out = False
            self.plant.step(self._tau, 1, self._t_ns * 1e-9)
        else:
            if not self._braking:
                self.get_logger().warning(
                    f"no valid command for {self.command_timeout} s: brakes engaged"
                )
                self._braking = self._timed_out = True
                self.counts["brake.engaged"] += 1
            self.plant.brake(1, self._t_ns * 1e-9)
        self._t_ns += self.physics_dt_ns

    # -- services ----------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self._lock:
            self.plant.reset()
            self._measured_ns = None
            self._tau = None
            if self.mode == "lockstep" and not self._paused:
                self._publish_state()
        response.success, response.message = True, "reset to the initial configuration"
        return response

    def _on_pause(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self._lock:
            self._paused = True
            self._awaiting = None
        response.success, response.message = True, "paused"
        return response

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        with self._lock:
            was_paused, self._paused = self._paused, False
            if self.mode == "realtime":
                self._tau = None  # commands from before the pause are stale
            elif was_paused or self._awaiting is None:
                self._publish_state()
        response.success, response.message = True, "running"
        return response

    def close(self) -> None:
        self._running = False
        thread = getattr(self, "_thread", None)
        if thread is not None:
            thread.join(timeout=1.0)
        self.plant.close()


def main(args: list[str] | None = None) -> None:
    run_node(SimBridge, args)


if __name__ == "__main__":
    main()
