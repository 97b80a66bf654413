"""What every joint controller node shares: parameters, topics, references, the tick.

A concrete controller supplies its extra parameters, builds an immutable configuration from
parameter values (raising ``ValueError`` with a reason for invalid ones) and computes the
torque split from the measured state and the reference sample. Everything here is message
handling and bookkeeping; the maths is in :mod:`joint_space_control.laws`.

Topics (relative names): subscribes ``joint_states`` and ``reference``; publishes
``effort_command`` (or ``commands`` with ``command_interface: forward_command``), ``~/state``
(every tick), ``~/config`` (latched JSON, at start and after every accepted parameter
change) and the loop statistics on ``/diagnostics``.

Towards a ros2_control robot (``command_interface: forward_command``): the command is a
std_msgs/Float64MultiArray on ``commands`` in ``command_joints`` order, as the forward
effort controller takes it, and such a robot holds its last command for ever. So whenever
this node stops commanding (stale states, a non-finite torque, a state it cannot answer,
Ctrl-C or SIGTERM) it first sends the command that holds the arm at rest where it was last
measured (:meth:`~joint_space_control.control.controller.Controller.holding_torque`: ĝ(q),
or zeros to a robot that compensates gravity itself) and says so in one line.

The control path (references, joint states and the control timer) runs in its own wait-set
loop (:mod:`~joint_space_control.ros.control_path`) and publishes serialized images
(:mod:`~joint_space_control.ros.wire`); parameters and services are served by a standard
executor in a second thread. A lock makes parameter updates land between two ticks.

Trigger (``trigger``): ``state`` answers every joint state once (a lockstep plant waits for
that answer); ``timer`` commands at ``rate`` on the node clock from the newest state;
``auto`` (the default) follows the plant: the node reads the ``mode`` parameter of the
publishers of its ``joint_states`` topic through their parameter services
(:mod:`~joint_space_control.ros.plant_mode`, asynchronously in the executor thread):
``lockstep`` → ``state``, anything else or no answer within 2 s → ``timer``. Until that is
known the node sends nothing (a realtime plant holds its brakes meanwhile) and keeps the
references it receives; once the plant is known to be lockstep, the newest waiting state
is answered at once. The resolved trigger is logged and shown in ``~/config`` and on
/diagnostics (``trigger``; ``pending`` while unknown).

Sampling (:mod:`~joint_space_control.control.sampling`, docs/parameters.md "Sampling and
velocity"): ``rate`` is the control rate with either trigger; answering states, the core
computes a torque at the states on the 1/rate grid and this node answers the states in
between with the held command (``~/state`` is published once per control period). The q̇ the
law uses is the measured one or an estimate from the positions (``velocity_source``); an
empty velocity array is a well-formed state (a plant that does not measure velocity) unless
the velocity must be measured. /diagnostics adds ``control_period`` (realised) and
``velocity`` (in use).

Stale states: with the timer, the node stops commanding when no joint state *arrived* for
``state_timeout`` seconds, measured on its own steady clock at receipt (not by comparing
the states' stamps, simulation time, with the node clock), and restarts from the measured
configuration when they come back.

Time going backwards: once (a restarted simulator, seen in the states' stamps) the node
restarts from the measured configuration; back and forth (two simulators in one domain:
3 backward jumps within 2 s of wall time, :mod:`~joint_space_control.time_jumps`) it says so
once at ERROR and does not restart at each jump, for the states' stamps and for the node
clock (``/clock`` with use_sim_time, seen by a jump callback on the node clock). /diagnostics
counts both (``joint_states.backward_jumps``, ``clock.backward_jumps``) and is ERROR while
they last.

Per-tick log lines go through :class:`~joint_space_control.throttle.ThrottledLog`: one line
a second per kind, with the count held back.

Gains (:func:`~joint_space_control.laws.gains.choose_gains`): ``omega_n`` > 0 designs them
from ω_n, ζ; else ``kp`` > 0 (with ``kd``) gives them; else the default ω_n (10 rad/s) with
``zeta``. A concrete controller may design its gains at the configuration measured at start
(``GAINS_NEED_CONFIGURATION``): they are then designed at the first state, again after a
restart, and at that configuration when ω_n, ζ or the model change; ``~/config`` is
published again with the gains in force.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import JumpThreshold, TimeJump
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.control.configure import (  # noqa: F401  (re-exported)
    COMMON_PARAMETERS,
    MODEL_PARAMETERS,
    TRIGGERS,
    ControllerKind,
    command_order,
    model_perturbation,
)
from joint_space_control.control.policy import ControlPolicy, Kind, Taken
from joint_space_control.control.sampling import VelocitySource
from joint_space_control.laws.gains import GainChoice
from joint_space_control.laws.limits import beyond_bound, joints_beyond
from joint_space_control.laws.plausible import PlausibleStates
from joint_space_control.memory import give_back_free_memory
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.ros import parameters as params
from joint_space_control.ros.control_path import ControlPath
from joint_space_control.ros.diagnostics import LoopDiagnostics
from joint_space_control.ros.loop_statistics import LoopStatistics
from joint_space_control.ros.messages import (
    CONFIG_QOS,
    CONTROL_PUBLISHER_QOS,
    CONTROL_QOS,
    FORWARD_COMMAND_QOS,
    REALTIME_STATE_QOS,
    REFERENCE_QOS,
    STATE_FIELDS,
    JointOrder,
    config_message,
    joint_state_arrays,
    prepare_reference_reader,
    state_message,
    trajectory_from_bytes,
)
from joint_space_control.ros.plant_mode import PLANT_SEEN, PlantModeWatcher
from joint_space_control.ros.realtime_threads import RealtimeThreads
from joint_space_control.ros.reference_worker import IN_THREAD_BYTES, ReferenceBuilder
from joint_space_control.ros.wire import (
    Float64ArrayImage,
    ForwardCommandImage,
    JointStateImage,
    JointStateReader,
    fill_images,
)
from joint_space_control.staleness import MAX_AGE, Lag
from joint_space_control.throttle import ThrottledLog
from joint_space_control.time_jumps import BackwardJumps
from joint_space_control.trajectories.reference import Trajectory

#: The safety counters of a controller (on /diagnostics; docs/safety.md).
COUNTERS = (
    "rejected.joint_states",
    "rejected.references",
    "superseded.references",
    "rejected.parameters",
    "dropped.nonfinite_torques",
    "stale.stops",
    "stale.joint_states",
    "restarts",
    "beyond_bound.torques",
    "clock.backward_jumps",
    "joint_states.backward_jumps",
)
#: What a controller node publishes, subscribes to, serves and calls: (kind, relative name,
#: type, meaning), rendered into docs/reference by joint_space_control.nodes.reference.
INTERFACE = (
    (
        "subscribes",
        "joint_states",
        "sensor_msgs/msg/JointState",
        "the measured state: joints matched by name (extra joints ignored), positions, "
        "velocities (an empty array: estimated, `velocity_source`); best effort behind a "
        "realtime plant",
    ),
    (
        "subscribes",
        "reference",
        "trajectory_msgs/msg/JointTrajectory",
        "one point: a set-point; several: a timed trajectory (positions, optional velocities "
        "and accelerations); `header.stamp` is its start, 0: on receipt",
    ),
    (
        "subscribes",
        "robot_description",
        "std_msgs/msg/String",
        "only with `robot:=topic`: the URDF text, latched (transient local)",
    ),
    (
        "publishes",
        "effort_command",
        "sensor_msgs/msg/JointState",
        "names + effort [N·m] within the effort limits (minus ĝ(q) with "
        "`gravity_compensated_by_hardware`); stamp = the joint state answered; "
        "`header.frame_id` = this node's full name (the commander)",
    ),
    (
        "publishes",
        "commands",
        "std_msgs/msg/Float64MultiArray",
        "instead of `effort_command` with `command_interface: forward_command`: efforts "
        "[N·m] in `command_joints` order, as ros2_control's forward effort controller takes "
        "them (reliable, keep last 10); the holding command ĝ(q) before it stops commanding",
    ),
    (
        "publishes",
        "~/state",
        "std_msgs/msg/Float64MultiArray",
        "once per control period while it has a subscriber: the stamp, then q_d, q̇_d, q̈_d, "
        "q, q̇, the errors and the torque split per joint (rows named in the layout)",
    ),
    (
        "publishes",
        "~/config",
        "std_msgs/msg/String",
        "the configuration in force as JSON (law, robot, joints, limits, gains, every "
        "parameter); latched, again after every accepted change",
    ),
    (
        "publishes",
        "/diagnostics",
        "diagnostic_msgs/msg/DiagnosticArray",
        "loop statistics and safety counters, once a second",
    ),
    (
        "calls",
        "<publisher of joint_states>/get_parameters",
        "rcl_interfaces/srv/GetParameters",
        "the plant's `mode`: `trigger: auto` follows it, and states are dropped as stale "
        "only behind a realtime plant",
    ),
)
#: Said once (ERROR) when the node clock goes backwards repeatedly (time_jumps.py).
CLOCK_JUMPS = (
    "/clock goes backwards and forwards: more than one node publishes /clock in this domain "
    "(two simulators?); put every robot in one sim_bridge world ('robots': docs/robots.md, "
    "Several robots) or run each simulator in a ROS domain of its own"
)
#: ... and when the joint states' stamps do.
STATE_JUMPS = (
    "joint state time goes backwards and forwards: more than one node publishes {} (two "
    "simulators?); not restarting at each jump (docs/safety.md)"
)
#: At shutdown, how long [s] the holding command may take to reach its subscribers.
HOLD_ACK_TIMEOUT = 1.0
NO_VELOCITY = (
    "rejected joint state: no velocity, and velocity_source is 'measured' (set auto, "
    "backward_difference or filtered_difference to estimate it)"
)


class JointController(Node):
    """Base class of the controller nodes (not a node on its own)."""

    #: The concrete controller: its executable (and default node name), its core (the
    #: object the node drives), its parameters and configuration
    #: (:mod:`joint_space_control.control.configure`).
    KIND: ControllerKind

    @property
    def config(self) -> Any:
        """The configuration in force (the core's, swapped whole on a parameter update)."""
        return self.core.config

    @property
    def core(self) -> Any:
        """The controller the policy steps (its configuration, state and step)."""
        return self.policy.core

    @property
    def model(self) -> RobotModel:
        """The controller's model in force."""
        return self.policy.model

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._specs = self.KIND.parameters
        params.declare(self, self._specs)
        values = params.current_values(self, self._specs)
        model = params.robot_model(values, model_perturbation(values), self)
        spec = model.spec
        self.joints = model.joint_names
        self.n = len(self.joints)
        self.effort_limits = model.effort_limits
        self._plausible = PlausibleStates(*model.position_limits, self.joints)
        self._robot_name = spec.name
        self._rate = rate = params.value(values, "rate")
        self._interface = params.value(values, "command_interface")
        self._command_order = command_order(values, tuple(self.joints))
        self.trigger_parameter = params.value(values, "trigger")
        # the trigger in force: "timer" | "state" | "pending" (auto, plant mode not known)
        self.trigger = "pending" if self.trigger_parameter == "auto" else self.trigger_parameter
        self._trigger_reason = ""
        # the controller and what the node does with it (no ROS): the policy
        self.policy = ControlPolicy(self.KIND, values, model, self.trigger)
        self._velocity_said: VelocitySource | None = None  # the source last logged
        self._period_warned = False
        self._gravity_checked = False  # g(q) against the effort limits, at the first state
        self._lock = threading.Lock()  # parameter updates wait for the end of a tick
        # what may recur at every tick or message: one line a second per kind (throttle.py)
        self._log = ThrottledLog(self.get_logger())
        # time going back once is a restarted simulator; back and forth, two of them
        self._clock_jumps = BackwardJumps()
        self._state_jumps = BackwardJumps()
        self._lag = Lag()  # how far behind the plant the joint states are taken
        self._realtime_plant = False  # known to be realtime (plant_mode): Lag judged
        self._jumps_said: set[str] = set()
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._init_inputs(rate)
        self._create_interfaces(values, spec.name)

    def _init_inputs(self, rate: float) -> None:
        """How states and references are read and kept, the command and ~/state images,
        the safety counters, and the node clock's backward jumps."""
        self._order = JointOrder(self.joints)
        self._reader = JointStateReader(
            self._order,
            (0, 1),
            lambda m: joint_state_arrays(m, self._order),
            allow_extra=True,
            optional=(1,),  # a plant that does not measure velocity
        )
        self._q: np.ndarray | None = None
        self._dq: np.ndarray | None = None
        self._state_ns = -1
        self._state_sent_ns = -1  # when the newest state was published (system clock)
        self._state_arrival = 0.0  # when it arrived (time.monotonic) [s]
        self._deferred: list[bytes] = []  # references received while pending
        # references are built off the control path with trigger=timer (see _on_reference)
        self._reference_thread = ThreadPoolExecutor(1, thread_name_prefix="references")
        self._reference_builder = ReferenceBuilder()
        prepare_reference_reader()
        # references are numbered as they arrive (policy.arrive): they take effect in that
        # order (a large one built off the control path must not replace a small one that
        # arrived after it and was taken at once), and a restart forgets those that arrived
        # before it
        # header.frame_id names the commander: the plant accepts one at a time (docs/safety.md)
        self._forward = self._interface == "forward_command"
        self._command: JointStateImage | ForwardCommandImage = (
            ForwardCommandImage(self._command_order)
            if self._forward
            else JointStateImage(
                self.joints, (0, 0, self.n), frame_id=self.get_fully_qualified_name()
            )
        )
        self._holding = False  # the holding command was sent; no command computed since
        self._command_bytes = b""
        self._state = Float64ArrayImage(state_message(self.joints), 1 + len(STATE_FIELDS) * self.n)
        self._silent = False
        # Safety counters, on /diagnostics (docs/safety.md).
        self.counts = dict.fromkeys(COUNTERS, 0)
        self._nominal_ns = round(1e9 / rate) if self.trigger == "timer" else -1
        self._timer = None
        self.loop_stats = LoopStatistics()
        # every backward jump of the node clock (/clock with use_sim_time), in the thread
        # that takes /clock (the control path's); kept: the callback lives as long as its
        # handle
        self._clock_jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(
                min_forward=None, min_backward=Duration(nanoseconds=-1), on_clock_change=False
            ),
            post_callback=self._on_clock_jump,
        )

    def _create_interfaces(self, values: params.ParamValues, robot: str) -> None:
        """The publishers, the control path (references, joint states, the timer, /clock)
        with its thread priority, /diagnostics and the plant's mode."""
        if self._forward:  # as ros2_control's forward command controller subscribes
            self._pub = self.create_publisher(Float64MultiArray, "commands", FORWARD_COMMAND_QOS)
        else:
            self._pub = self.create_publisher(JointState, "effort_command", CONTROL_PUBLISHER_QOS)
        self._state_pub = self.create_publisher(
            Float64MultiArray, "~/state", CONTROL_PUBLISHER_QOS
        )
        self._config_pub = self.create_publisher(String, "~/config", CONFIG_QOS)
        self._publish_config()
        self.control_path = ControlPath(self)
        self.realtime = RealtimeThreads(self, values)
        self.control_path.on_serve = lambda: self.realtime.configure("control path")
        if self.realtime.middleware_priority > 0 or not self.get_parameter("use_sim_time").value:
            # with use_sim_time and the middleware threads left normal, the executor stays
            # normal too: at FIFO, serving /clock, it starved the DDS threads that deliver the
            # joint states (states missing for 0.1 s at a time, two controllers on two cores)
            self.control_path.on_executor = self.realtime.configure_executor
        # The reference subscription comes first, so that a reference and a joint state
        # that are both waiting are handled in that order (deterministic lockstep start).
        self.control_path.subscription(
            JointTrajectory, "reference", self._on_reference, REFERENCE_QOS, raw=True
        )
        self._state_sub = self.control_path.subscription(
            JointState, "joint_states", self._on_joint_state, CONTROL_QOS, raw=True
        )  # best effort once the plant is known to run in realtime (_follow_plant)
        self._state_topic = self._state_sub.topic_name
        if self.trigger_parameter != "state":
            self._timer = self.control_path.timer(1.0 / self._rate, self._on_timer)
        self.control_path.take_clock()  # after the states: a tick is not delayed by it
        self._diagnostics = LoopDiagnostics(
            self, self.loop_stats, robot, self._diagnostic_values, self._alarm
        )
        # the plant's mode, whatever the trigger: stale states are dropped only behind a
        # realtime plant (a lockstep plant waits for the answer to the state it sent)
        self._watcher = PlantModeWatcher(self, "joint_states", self._on_plant_mode)
        self.get_logger().info(
            f"{self.get_name()}: {robot}, joints {list(self.joints)}, "
            + self._trigger_text()
            + f", gains {self._gains_text()}"
        )

    def _trigger_text(self) -> str:
        if self.trigger == "pending":
            return "trigger=auto: pending (reading the joint_states publisher's 'mode')"
        text = f"trigger={self.trigger}" + (
            f" at {self._rate:g} Hz" if self.trigger == "timer" else ""
        )
        if self.trigger_parameter == "auto":
            text += f" (auto: {self._trigger_reason})"
        return text

    def _gains_text(self) -> str:
        choice: GainChoice = self.config.choice
        gains = self.config.gains
        if choice.designed:
            text = f"from omega_n={choice.omega_n.tolist()}, zeta={choice.zeta.tolist()}" + (
                " (default omega_n)" if choice.source == "default" else ""
            )
        else:
            text = "from kp, kd"
        if gains is None:
            return text + ", designed at the first measured configuration"
        return text + f": kp={gains.kp.tolist()}, kd={gains.kd.tolist()}"

    # -- parameters --------------------------------------------------------------------
    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        """rclpy's, with every refusal counted and logged (:meth:`_refused`)."""
        return [self._refused(r) for r in super().set_parameters(parameter_list)]

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """rclpy's (what the parameter services call), with a refusal counted and logged."""
        return self._refused(super().set_parameters_atomically(parameter_list))

    def _refused(self, result: SetParametersResult) -> SetParametersResult:
        """Count a refused update in ``rejected.parameters`` and log its reason, whoever
        refused it: the on-set callback (a value this node's check refuses) or rclpy before
        it (a double outside the descriptor's floating_point_range, a wrong type, a
        read-only parameter)."""
        if not result.successful:
            self.counts["rejected.parameters"] += 1
            self.get_logger().warning(f"rejected parameter update: {result.reason}")
        return result

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        values = params.with_changes(self, self._specs, changes)
        try:
            apply = self.policy.prepare(values)
        except ValueError as err:  # counted and logged by _refused
            return SetParametersResult(successful=False, reason=str(err))
        with self._lock:  # between two ticks
            apply()
        self._publish_config()
        self.get_logger().info(
            "parameters updated: " + ", ".join(f"{p.name}={p.value}" for p in changes)
        )
        return SetParametersResult(successful=True)

    def _diagnostic_values(self, summary: Any) -> dict[str, Any]:
        return {
            "trigger": self.trigger,
            "trigger_parameter": self.trigger_parameter,
            "commanding": int(not self._silent),
            "control_period": self._control_period(),
            "velocity": (self.core.velocity_used or self.core.sampling.velocity).value,
            "plant": PLANT_SEEN[self._watcher.decision],
            "joint_states_reliability": self._state_sub.qos_profile.reliability.name.lower(),
            **self.counts,
            **self.realtime.diagnostics(),
        }

    def _control_period(self) -> float:
        """The control period T_s [s]: realised (answering states), else nominal."""
        realised = self.core.control_period.realised
        return 1.0 / self._rate if realised is None else realised

    def _alarm(self) -> str | None:
        """Why the controller is not doing its job right now (an ERROR on /diagnostics)."""
        if self._silent:
            return f"no joint state for more than {self.policy.state_timeout} s: not commanding"
        if self._clock_jumps.repeating:
            return "/clock goes backwards and forwards (two simulators in this domain?)"
        if self._state_jumps.repeating:
            topic = self._state_topic
            return f"joint state time goes backwards and forwards (two publishers of {topic}?)"
        return None

    def _publish_config(self) -> None:
        document = self.policy.config_document(
            self.get_fully_qualified_name(), self.trigger_parameter
        )
        self._config_pub.publish(config_message(document))

    # -- inputs ------------------------------------------------------------------------
    def _now(self) -> float:
        """The controller's time [s]: the newest state's stamp when answering states, else
        the node clock (simulation time with use_sim_time)."""
        if self.trigger == "state":
            return max(self._state_ns, 0) * 1e-9
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_reference(self, raw: bytes, info: Any = None) -> None:
        """A reference's bytes (control path). With ``trigger: state`` it is validated and
        splined before the next state is answered (a large one in the builder's process,
        waited for), so that a lockstep run, whose time waits for the answer, does not
        depend on timing. Otherwise, and for a large one behind a plant known to run in
        realtime, which does not wait (waiting there stalled the loop for 35-40 s on a
        loaded machine while the builder, at nice 19, read a 100,000-point reference: the
        plant braked, then the arm was pulled after the reference at the effort limits),
        the reference thread has it built
        (:class:`~joint_space_control.ros.reference_worker.ReferenceBuilder`: a large one in
        a process of its own, so the loop never shares the interpreter with it) and the
        trajectory is swapped in between two ticks once ready: the tick never waits."""
        if self.trigger == "pending":  # its time base (state stamps or clock) is not known
            self._deferred.append(raw)
            return
        now = self._now()
        large = len(raw) > IN_THREAD_BYTES
        arrived = self.policy.arrive()
        if self.trigger == "state" and not large:
            self._take_reference(self._build_reference(raw, now), arrived)
            return
        if self.trigger == "state" and not self._realtime_plant:
            # a large one in the builder's process, waited for: its hundreds of thousands
            # of objects are read there, not spread over this process's memory for good
            # (a controller stepped up 180 MB over six 100,000-point references; flat now)
            built = self._reference_builder.build(
                raw, self.joints, now, self.model.position_limits
            )
            self._take_reference(built, arrived)
            give_back_free_memory()  # what taking it freed (the transfer, the old pages)
            return
        try:
            self._reference_thread.submit(self._prepare_reference, raw, now, arrived)
        except RuntimeError:  # the thread is shut down: the node is closing
            pass

    def _build_reference(self, raw: bytes, now: float) -> Trajectory | str:
        """The validated trajectory (a zero ``header.stamp`` starts it ``now``), or why it
        is rejected."""
        try:
            return trajectory_from_bytes(raw, self._order, now, 0, self.model.position_limits)
        except ValueError as err:
            return str(err)

    def _prepare_reference(self, raw: bytes, arrival: float, arrived: int) -> None:
        """The reference thread: build, then hand over to the control path."""
        result = self._reference_builder.build(
            raw, self.joints, arrival, self.model.position_limits
        )
        self.control_path.post(lambda: self._take_reference(result, arrived, arrival))

    def _take_reference(
        self, result: Trajectory | str, arrived: int, arrival: float | None = None
    ) -> None:
        """Schedule a built trajectory, or count and say why it was rejected (control
        path). ``arrived`` numbers the references as they arrived: one that arrived before a
        restart is dropped (the restart forgot the references); one whose build ended after a
        newer one was taken is dropped, counted in ``superseded.references`` (behind a
        realtime plant with ``trigger: state``, a large reference is built off the control
        path while a small one is taken at once: swapped in seconds later, the fault soak's
        100,000-point reference sent q_d back 2.7 rad, to where the arm had been). One built
        off the control path from its ``arrival`` whose stamp was zero ("now") starts now,
        when it is taken, as joint_trajectory_controller starts such a trajectory at its
        first sample: its beginning is not lost to the build time."""
        start = None
        if arrival is not None and not isinstance(result, str) and result.start == arrival:
            start = self._now()
        taken = self.policy.take_reference(result, arrived, start)
        if taken is Taken.REJECTED:
            self.counts["rejected.references"] += 1
            self._log.warning("rejected reference", "rejected reference: {}", result)
            return
        if taken is Taken.SUPERSEDED:
            self.counts["superseded.references"] += 1
            self._log.warning(
                "superseded reference",
                "dropped a reference of {} point(s) built after a newer one was taken",
                len(result.times),
            )
            return
        if taken is not Taken.TAKEN:  # forgotten: it arrived before a restart
            return
        if start is not None:
            result = dataclasses.replace(result, start=start)
        self.get_logger().info(
            f"reference accepted: {len(result.times)} point(s) from t={result.start:.3f} s"
        )

    def close(self) -> None:
        """Stop the reference thread and process (a reference being built is dropped);
        towards a robot that holds its last command, send the holding command first."""
        self._hold("stopping", wait=True)
        self._clock_jump_handle.unregister()
        self._reference_thread.shutdown(wait=False, cancel_futures=True)
        self._reference_builder.close()

    def _on_joint_state(self, raw: bytes, info: dict[str, int]) -> None:
        start = time.perf_counter_ns()
        if self._realtime_plant and self._lag.too_old(info["source_timestamp"], time.time_ns()):
            # a backlog the plant's writer re-sends to a controller that fell behind: an
            # arm that is no longer there; dropped, the controller catches up (staleness.py)
            self.counts["stale.joint_states"] += 1
            self._log.warning(
                "stale joint states",
                lambda: (
                    f"dropped joint states more than {MAX_AGE * 1e3:g} ms old: this controller "
                    f"fell behind the plant ({self._lag.dropped} so far)"
                ),
            )
            return
        try:
            stamp, (q, dq) = self._reader.read(raw)
        except ValueError as err:
            self.counts["rejected.joint_states"] += 1
            self._log.warning("rejected joint state", "rejected joint state: {}", err)
            return
        if not dq.size and self.core.sampling.velocity is VelocitySource.MEASURED:
            self.counts["rejected.joint_states"] += 1
            self._log.warning("no velocity", NO_VELOCITY)
            return
        absurd = self._plausible.reason(q, dq)
        if absurd:
            self.counts["rejected.joint_states"] += 1
            self._log.warning("rejected joint state", "rejected joint state: {}", absurd)
            return
        previous = self._state_ns
        if stamp < previous:
            previous = -1
            self.counts["joint_states.backward_jumps"] += 1
            if self._state_jumps.jumped():  # two plants on one topic: a restart would not help
                self._say_once("joint_states", STATE_JUMPS.format(self._state_topic))
            else:  # a restarted simulator
                self._log.warning(
                    "time went backwards",
                    "joint state time went backwards: restarting from the measured configuration",
                )
                self.counts["restarts"] += 1
                self._restart()
        self._q, self._dq, self._state_ns = q, dq, stamp
        self._state_sent_ns = info["source_timestamp"]
        self._state_arrival = time.monotonic()
        if self.trigger == "state":
            if stamp == self.policy.answered_ns:  # the same state again: repeat the answer
                self._pub.publish(self._command_bytes)
                return
            self._answer(start, previous)

    def _answer(self, start: int, previous: int) -> None:
        """trigger=state: answer the newest state (``previous``: the stamp before it)."""
        stamp = self._state_ns
        sent = self._tick(stamp * 1e-9)
        if sent < 0:
            return
        self.loop_stats.tick(
            start,
            time.perf_counter_ns(),
            sent - self._state_sent_ns,
            -1,
            stamp - previous if previous >= 0 else -1,
        )

    def _on_timer(self) -> None:
        start = time.perf_counter_ns()
        if self._q is None or self.trigger != "timer":
            return
        now = self._now()
        # judged by arrival on this node's steady clock: the stamps are the plant's time
        if time.monotonic() - self._state_arrival > self.policy.state_timeout:
            if not self._silent:
                self._log.error(
                    "not commanding",
                    "no joint state for more than {} s: not commanding",
                    self.policy.state_timeout,
                )
                self._silent = True
                self.counts["stale.stops"] += 1
                self._hold("no joint state")
            return
        if self._silent:
            self._log.info("commanding again", "joint states are back: commanding again")
            self._silent = False
            self.counts["restarts"] += 1
            self._restart()
        sent = self._tick(now)
        if sent < 0:
            return
        self.loop_stats.tick(
            start, time.perf_counter_ns(), sent - self._state_sent_ns, -1, self._nominal_ns
        )

    def _on_clock_jump(self, jump: TimeJump) -> None:
        """The node clock went backwards (in the control path, which takes /clock): counted;
        said once when it keeps doing so. Nothing restarts: a restarted simulator is seen in
        the joint states' stamps (rcl's timer restarts its period by itself)."""
        self.counts["clock.backward_jumps"] += 1
        if self._clock_jumps.jumped():
            self._say_once("clock", CLOCK_JUMPS)

    def _say_once(self, what: str, text: str) -> None:
        if what not in self._jumps_said:
            self._jumps_said.add(what)
            self.get_logger().error(text)

    def _restart(self) -> None:
        # references being built now are of the time before; gains designed at start are
        # designed again at the next state
        with self._lock:
            self.policy.restart()

    # -- trigger: auto -----------------------------------------------------------------
    def _on_plant_mode(self, trigger: str, reason: str) -> None:
        """The plant mode watcher decided (executor thread): hand over to the control path.
        ``trigger`` is "state" behind a lockstep plant, "timer" behind any other."""
        self._realtime_plant = trigger == "timer"
        self.control_path.post(self._follow_plant)
        if self.trigger_parameter == "auto":
            self.control_path.post(lambda: self._set_trigger(trigger, reason))

    def _follow_plant(self) -> None:
        """The joint states' QoS for the plant's mode (control path): reliable behind a
        lockstep plant, which waits for the answer to each state; best effort behind a plant
        that declares ``mode: realtime``, so that a controller that stalled or started late
        takes the newest state, not the writer's backlog (REALTIME_STATE_QOS): with
        ``trigger: state`` kept reliable there, the fault soak's restarted controller was
        handed states over 100 ms old for a minute and never commanded again. Behind any
        other publisher, best effort on the timer and reliable with ``trigger: state`` (each
        state answered: subscribing again would lose the states sent while the new reader
        is matched; CI lost one so, in tests that publish states themselves)."""
        newest_only = self._realtime_plant and (
            self.trigger_parameter != "state" or self._watcher.realtime
        )
        qos = REALTIME_STATE_QOS if newest_only else CONTROL_QOS
        if self._state_sub.qos_profile != qos:
            self._state_sub = self.control_path.resubscribe(self._state_sub, qos)

    def _set_trigger(self, trigger: str, reason: str) -> None:
        """Switch to ``trigger`` (control-path thread)."""
        if trigger == self.trigger:
            return
        was = self.trigger
        self.trigger, self._trigger_reason = trigger, reason
        self._nominal_ns = round(1e9 / self._rate) if trigger == "timer" else -1
        with self._lock:
            self.policy.set_trigger(trigger)
        if self._timer is not None:
            if trigger == "timer":
                self._timer.reset()
            else:
                self._timer.cancel()
        if was != "pending":  # another plant: another time base, start over from it
            self._restart()
        self.get_logger().info(self._trigger_text())
        self._publish_config()
        deferred, self._deferred = self._deferred, []
        for raw in deferred:
            self._on_reference(raw)
        if (
            trigger == "state"
            and self._q is not None
            and self._state_ns != self.policy.answered_ns
        ):
            # the plant has been waiting for this answer
            self._answer(time.perf_counter_ns(), -1)

    def _say_sampling(self) -> None:
        """Log the velocity in use when it changes (INFO), and once that the states' period
        does not divide the control period."""
        used = self.core.velocity_used
        if used is not self._velocity_said:
            self._velocity_said = used
            source = self.core.sampling.velocity
            carry = "carry" if used is VelocitySource.MEASURED else "carry no"
            how = f" (auto: the joint states {carry} velocity)" if source == "auto" else ""
            cutoff = (
                f", cutoff {self.core.sampling.cutoff:g} Hz"
                if used is VelocitySource.FILTERED_DIFFERENCE
                else ""
            )
            self.get_logger().info(f"velocity: {used.value}{cutoff}{how}")
        period = self.core.control_period
        if period.indivisible and not self._period_warned:
            self._period_warned = True
            self.get_logger().warning(
                f"the joint states' period does not divide the control period 1/rate = "
                f"{period.period * 1e3:g} ms: the realised period is the nearest multiple of "
                f"it, {period.realised * 1e3:g} ms (on /diagnostics: control_period)"
            )

    def _say_unholdable(self, q: np.ndarray) -> None:
        """Once, at the first measured configuration: the joints whose gravity torque there
        (the controller model's g(q)) is beyond their effort limit. The commands are clamped
        at the limits, so the arm cannot hold that configuration, whatever the gains."""
        beyond = joints_beyond(self.model.gravity(q), self.effort_limits, self.joints)
        if beyond:
            self.get_logger().warning(
                f"the arm cannot hold its configuration against gravity: g(q) needs {beyond} "
                f"at q = {np.round(q, 4).tolist()} rad; the commands are clamped at the "
                "effort limits, so it sags there (start elsewhere, lighten the payload, or "
                "set effort_limits if the hardware has more)"
            )

    # -- the tick ----------------------------------------------------------------------
    def _tick(self, t: float) -> int:
        """Step the controller and publish the command and the state; returns when the
        command was published [ns, system clock], or -1 when a non-finite torque was
        computed: then nothing is published (the plant keeps its last command, then its
        timeout acts)."""
        with self._lock:
            answer = self.policy.step(t, self._q, self._dq, self._state_ns)
            step = answer.step
            if step is not None and not self._gravity_checked:
                self._gravity_checked = True
                self._say_unholdable(self._q)
            if answer.kind is Kind.HELD:  # inside a control period: the held torque answers
                if not self._forward:
                    self._command.set_stamp(self._state_ns)
                self._command_bytes = self._command.to_bytes()
                self._pub.publish(self._command_bytes)
                return time.time_ns()
            if step is None:  # velocity_source measured, this state has none
                self._log.error("no command", "no command: {}", answer.reason)
                self._hold("no command")
                return -1
            if step.tau is None:
                self.counts["dropped.nonfinite_torques"] += 1
                self._log.error("non-finite torque", "{}: no command sent", answer.reason)
                self._hold("non-finite torque")
                return -1
            factor = self.policy.reject_factor
            if beyond_bound(step.unclamped, self.effort_limits, factor):
                # legitimate at saturation (still clamped and sent), but a law this far
                # beyond the limits points at a bug or a broken input: counted, said
                self.counts["beyond_bound.torques"] += 1
                self._log.warning(
                    "beyond bound",
                    lambda: (
                        f"computed torque beyond {factor:g} × the effort limits "
                        "(reject_factor): clamped; "
                        + joints_beyond(step.unclamped, self.effort_limits, self.joints, factor)
                    ),
                )
            listening = self._state_pub.get_subscription_count() > 0  # else: nothing to build
            fill_images(self._command, self._state if listening else None, self._state_ns, step)
            self._command_bytes = self._command.to_bytes()
            self._pub.publish(self._command_bytes)
            self._holding = False
            sent = time.time_ns()
            if listening:
                self._state_pub.publish(self._state.to_bytes())
        self._say_sampling()
        if answer.designed:  # at the first measured configuration, again after each restart
            self._log.info(
                "gains designed",
                lambda: f"gains {self._gains_text()} at q0={self.core.q0.tolist()}",
            )
            self._publish_config()
        return sent

    def _hold(self, why: str, wait: bool = False) -> None:
        """Towards a robot that holds its last command (``forward_command``): send the
        command that holds the arm at rest at the last measured q (ĝ(q), or zeros where the
        hardware compensates gravity) and say so, once until commands are computed again.
        ``wait``: until the subscribers have it (at shutdown, before the publisher goes)."""
        if not self._forward or self._q is None or self._holding:
            return
        tau = self.core.holding_torque(self._q)  # the model in force: swapped whole
        self._command.write(tau)
        self._command_bytes = self._command.to_bytes()
        self._pub.publish(self._command_bytes)
        self._holding = True
        if self.core.gravity_by_hardware:
            what = "zeros (the robot compensates gravity)"
        else:
            q = np.round(self._q, 4).tolist()
            what = f"ĝ(q) = {np.round(tau, 4).tolist()} N·m at q = {q} rad"
        text = f"{why}: sent the holding command {what}; the robot holds it"
        if why == "stopping":
            self.get_logger().info(text)
        else:
            self._log.warning("holding", text)
        if wait:
            self._pub.wait_for_all_acked(Duration(seconds=HOLD_ACK_TIMEOUT))
