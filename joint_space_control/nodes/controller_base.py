"""What every joint controller node shares: parameters, topics, references, the tick.

A concrete controller supplies its extra parameters, builds an immutable configuration from
parameter values (raising ``ValueError`` with a reason for invalid ones) and computes the
torque split from the measured state and the reference sample. Everything here is message
handling and bookkeeping; the maths is in :mod:`joint_space_control.laws`.

Topics (relative names): subscribes ``joint_states`` and ``reference``; publishes
``effort_command``, ``~/state`` (every tick), ``~/config`` (latched JSON, at start and
after every accepted parameter change) and the loop statistics on ``/diagnostics``.

The control path (references, joint states and the control timer) runs in its own wait-set
loop (:mod:`~joint_space_control.nodes.control_path`) and publishes serialized images
(:mod:`~joint_space_control.nodes.wire`); parameters and services are served by a standard
executor in a second thread. A lock makes parameter updates land between two ticks.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.laws.split import TorqueSplit
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.nodes import parameters as params
from joint_space_control.nodes.control_path import ControlPath
from joint_space_control.nodes.diagnostics import LoopDiagnostics
from joint_space_control.nodes.loop_statistics import LoopStatistics
from joint_space_control.nodes.messages import (
    CONFIG_QOS,
    CONTROL_PUBLISHER_QOS,
    CONTROL_QOS,
    REFERENCE_QOS,
    STATE_FIELDS,
    JointOrder,
    config_message,
    joint_state_arrays,
    state_message,
    trajectory_from_msg,
)
from joint_space_control.nodes.wire import Float64ArrayImage, JointStateImage, JointStateReader
from joint_space_control.trajectories.reference import Reference, Sample, Trajectory

TRIGGERS = ("timer", "state")
#: The safety counters of a controller (on /diagnostics; README "Safety").
COUNTERS = (
    "rejected.joint_states",
    "rejected.references",
    "rejected.parameters",
    "dropped.nonfinite_torques",
    "stale.stops",
    "restarts",
)
#: Longest time step integrated at once [s]; longer gaps (start-up, pauses) are cut.
MAX_DT = 0.1

COMMON_PARAMETERS = params.ROBOT_PARAMETERS + (
    params.ParamSpec("rate", 1000.0, "Control rate [Hz] with trigger=timer, > 0", read_only=True),
    params.ParamSpec(
        "trigger",
        "timer",
        "timer: command at 'rate' from the latest state; state: answer every "
        "joint state once (lockstep)",
        read_only=True,
    ),
    params.ParamSpec(
        "state_timeout",
        0.1,
        "Stop commanding when the newest joint state is older than this [s], > 0",
    ),
    params.ParamSpec(
        "kp",
        100.0,
        "Proportional gain K_P [N·m/rad], one value or one per joint, > 0",
        dynamic=True,
    ),
    params.ParamSpec(
        "kd",
        20.0,
        "Derivative gain K_D [N·m·s/rad], one value or one per joint, >= 0",
        dynamic=True,
    ),
    # The controller's own model (B̂, Ĉ, F̂, ĝ) can differ from the plant on purpose.
    params.ParamSpec(
        "model_mass_scale",
        1.0,
        "Controller model: factor on the mass and inertia of the link each joint moves, "
        "one value or one per joint, > 0",
        dynamic=True,
    ),
    params.ParamSpec(
        "model_payload_mass",
        0.0,
        "Controller model: point mass [kg] at the last link's centre of mass, >= 0",
    ),
    params.ParamSpec(
        "model_friction",
        0.0,
        "Controller model: viscous friction F̂ [N·m·s/rad], one value or one per joint, >= 0",
        dynamic=True,
    ),
    params.ParamSpec("model_gravity", True, "Controller model: false models no gravity (ĝ ≡ 0)"),
)
MODEL_PARAMETERS = ("model_mass_scale", "model_payload_mass", "model_friction", "model_gravity")


def model_perturbation(values: dict[str, Any]) -> ModelPerturbation:
    """The controller model's deliberate differences from the URDF, from parameter values."""
    payload = values["model_payload_mass"]
    if isinstance(payload, bool) or not isinstance(payload, int | float):
        raise ValueError(f"'model_payload_mass' must be a number, got {payload!r}")
    if not isinstance(values["model_gravity"], bool):
        raise ValueError(f"'model_gravity' must be true or false, got {values['model_gravity']!r}")
    return ModelPerturbation(
        friction=tuple(params.numbers(values, "model_friction")),
        mass_scale=tuple(params.numbers(values, "model_mass_scale")),
        payload_mass=float(payload),
        gravity=values["model_gravity"],
    )


class JointController(Node):
    """Base class of the controller nodes (not a node on its own)."""

    #: Extra parameters of the concrete controller.
    LAW_PARAMETERS: tuple[params.ParamSpec, ...] = ()
    #: The executable (and default node name) of the concrete controller.
    EXECUTABLE = ""

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self._specs = COMMON_PARAMETERS + self.LAW_PARAMETERS
        params.declare(self, self._specs)
        values = params.current_values(self, self._specs)
        self._perturbation = model_perturbation(values)
        self.model = params.robot_model(values, self._perturbation, self)
        spec = self.model.spec
        self.joints = self.model.joint_names
        self.n = len(self.joints)
        self.effort_limits = self.model.effort_limits
        self._lowest_effort = -self.effort_limits
        self._robot_name = spec.name
        self._rate = rate = params.positive(values, "rate")
        self.trigger = params.choice(values, "trigger", TRIGGERS)
        self.config = self.build_config(values, self.model)
        self._state_timeout = params.positive(values, "state_timeout")
        self._lock = threading.Lock()  # parameter updates wait for the end of a tick
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._order = JointOrder(self.joints)
        self._reader = JointStateReader(
            self._order, (0, 1), lambda m: joint_state_arrays(m, self._order), allow_extra=True
        )
        self._q: np.ndarray | None = None
        self._dq: np.ndarray | None = None
        self._state_ns = -1
        self._state_sent_ns = -1  # when the newest state was published (system clock)
        self._answered_ns = -1
        self._t_last: float | None = None
        self._reference: Reference | None = None
        self._reference_last = np.inf  # time of its last point after its start [s]
        self._held: Sample | None = None  # its sample from then on
        self._pending: list[Trajectory] = []
        self._command = JointStateImage(self.joints, (0, 0, self.n))
        self._command_bytes = b""
        self._state = Float64ArrayImage(state_message(self.joints), 1 + len(STATE_FIELDS) * self.n)
        self._silent = False
        # Safety counters, on /diagnostics (README "Safety").
        self.counts = dict.fromkeys(COUNTERS, 0)
        self._nominal_ns = round(1e9 / rate) if self.trigger == "timer" else -1
        self.loop_stats = LoopStatistics()

        self._pub = self.create_publisher(JointState, "effort_command", CONTROL_PUBLISHER_QOS)
        self._state_pub = self.create_publisher(
            Float64MultiArray, "~/state", CONTROL_PUBLISHER_QOS
        )
        self._config_pub = self.create_publisher(String, "~/config", CONFIG_QOS)
        self._publish_config(values)
        self.control_path = ControlPath(self)
        # The reference subscription comes first, so that a reference and a joint state
        # that are both waiting are handled in that order (deterministic lockstep start).
        self.control_path.subscription(
            JointTrajectory, "reference", self._on_reference, REFERENCE_QOS
        )
        self.control_path.subscription(
            JointState, "joint_states", self._on_joint_state, CONTROL_QOS, raw=True
        )
        if self.trigger == "timer":
            self.control_path.timer(1.0 / rate, self._on_timer)
        self._diagnostics = LoopDiagnostics(
            self, self.loop_stats, spec.name, self._diagnostic_values, self._alarm
        )
        self.get_logger().info(
            f"{node_name}: {spec.name}, joints {list(self.joints)}, trigger={self.trigger}"
            + (f" at {rate:g} Hz" if self.trigger == "timer" else "")
        )

    # -- to be provided by the concrete controller ------------------------------------
    def build_config(self, values: dict[str, Any], model: RobotModel) -> Any:
        """An immutable configuration with at least ``gains`` (:class:`PDGains`) and the
        controller ``model`` it computes with."""
        raise NotImplementedError

    def law_name(self, config: Any) -> str:
        """The law in force, as named in ``~/config`` (README)."""
        raise NotImplementedError

    def compute(self, q: np.ndarray, dq: np.ndarray, ref: Sample, dt: float) -> TorqueSplit:
        raise NotImplementedError

    def after_command(
        self, ref: Sample, q: np.ndarray, tau_unclamped: np.ndarray, dt: float
    ) -> None:
        """Update internal state (integrators) once the command is out."""

    def reset_state(self) -> None:
        """Forget internal state (integrators): bumpless start after a gap or restart."""

    # -- parameters --------------------------------------------------------------------
    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        values = params.with_changes(self, self._specs, changes)
        try:
            model = self._model_for(values)
            config = self.build_config(values, model)
            timeout = params.positive(values, "state_timeout")
        except ValueError as err:
            self.counts["rejected.parameters"] += 1
            self.get_logger().warning(f"rejected parameter update: {err}")
            return SetParametersResult(successful=False, reason=str(err))
        with self._lock:  # between two ticks
            self.config = config  # swapped whole; a tick reads it once
            self.model, self._perturbation = model, model_perturbation(values)
            self._state_timeout = timeout
        self._publish_config(values)
        self.get_logger().info(
            "parameters updated: " + ", ".join(f"{p.name}={p.value}" for p in changes)
        )
        return SetParametersResult(successful=True)

    def _diagnostic_values(self, summary: Any) -> dict[str, Any]:
        return {"trigger": self.trigger, "commanding": int(not self._silent), **self.counts}

    def _alarm(self) -> str | None:
        """Why the controller is not doing its job right now (an ERROR on /diagnostics)."""
        if self._silent:
            return f"no joint state for more than {self._state_timeout} s: not commanding"
        return None

    def _model_for(self, values: dict[str, Any]) -> RobotModel:
        """The current model, or a new one if the model parameters changed."""
        return self.model.with_perturbation(model_perturbation(values))

    def _publish_config(self, values: dict[str, Any]) -> None:
        lower, upper = self.model.position_limits
        self._config_pub.publish(
            config_message(
                {
                    "node": self.get_fully_qualified_name(),
                    "executable": self.EXECUTABLE,
                    "law": self.law_name(self.config),
                    "robot": self._robot_name,
                    "joints": list(self.joints),
                    "rate": self._rate,
                    "trigger": self.trigger,
                    "effort_limits": self.effort_limits,
                    "position_limits": [[lo, hi] for lo, hi in zip(lower, upper, strict=True)],
                    "kp": self.config.gains.kp,
                    "kd": self.config.gains.kd,
                    "parameters": values,
                }
            )
        )

    # -- inputs ------------------------------------------------------------------------
    def _now(self) -> float:
        """The controller's time [s]: the newest state's stamp when answering states, else
        the node clock (simulation time with use_sim_time)."""
        if self.trigger == "state":
            return max(self._state_ns, 0) * 1e-9
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_reference(self, msg: JointTrajectory, info: Any = None) -> None:
        try:
            traj = trajectory_from_msg(
                msg, self._order, self._now(), 0, self.model.position_limits
            )
        except ValueError as err:
            self.counts["rejected.references"] += 1
            self.get_logger().warning(f"rejected reference: {err}", throttle_duration_sec=1.0)
            return
        self._pending = [p for p in self._pending if p.start < traj.start] + [traj]
        self.get_logger().info(
            f"reference accepted: {len(traj.times)} point(s) from t={traj.start:.3f} s"
        )

    def _on_joint_state(self, raw: bytes, info: dict[str, int]) -> None:
        start = time.perf_counter_ns()
        try:
            stamp, (q, dq) = self._reader.read(raw)
        except ValueError as err:
            self.counts["rejected.joint_states"] += 1
            self.get_logger().warning(f"rejected joint state: {err}", throttle_duration_sec=1.0)
            return
        previous = self._state_ns
        if stamp < previous:
            self.get_logger().warning(
                "joint state time went backwards: restarting from the measured configuration"
            )
            self.counts["restarts"] += 1
            self._restart()
            previous = -1
        self._q, self._dq, self._state_ns = q, dq, stamp
        self._state_sent_ns = info["source_timestamp"]
        if self.trigger == "state":
            if stamp == self._answered_ns:  # the same state again: repeat the answer
                self._pub.publish(self._command_bytes)
                return
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
        if self._q is None:
            return
        now = self._now()
        if now - self._state_ns * 1e-9 > self._state_timeout:
            if not self._silent:
                self.get_logger().error(
                    f"no joint state for more than {self._state_timeout} s: not commanding"
                )
                self._silent = True
                self.counts["stale.stops"] += 1
            return
        if self._silent:
            self.get_logger().info("joint states are back: commanding again")
            self._silent = False
            self.counts["restarts"] += 1
            self._restart()
        sent = self._tick(now)
        if sent < 0:
            return
        self.loop_stats.tick(
            start, time.perf_counter_ns(), sent - self._state_sent_ns, -1, self._nominal_ns
        )

    def _restart(self) -> None:
        self._reference, self._held, self._reference_last = None, None, np.inf
        self._pending = []
        self._t_last = None
        self.reset_state()

    # -- the tick ----------------------------------------------------------------------
    def _sample(self, t: float) -> Sample:
        if self._reference is None:  # hold the configuration measured at start
            self._set_reference(Reference.hold(self._q, t))
        while self._pending and self._pending[0].start <= t:
            traj = self._pending.pop(0)
            self._set_reference(Reference(traj, self._reference.sample(traj.start)))
        # past the last point (Reference.sample's own test): the same sample every tick
        if t - self._reference.trajectory.start >= self._reference_last:
            if self._held is None:
                self._held = self._reference.sample(t)
            return self._held
        return self._reference.sample(t)

    def _set_reference(self, reference: Reference) -> None:
        self._reference, self._held = reference, None
        self._reference_last = reference.knots[0][-1]  # after its start [s]

    def _tick(self, t: float) -> int:
        """Compute and publish the command and the state; returns when the command was
        published [ns, system clock], or -1 when a non-finite torque was computed: then
        nothing is published (the plant keeps its last command, then its timeout acts)."""
        with self._lock:
            q, dq = self._q, self._dq
            dt = 0.0 if self._t_last is None else min(max(t - self._t_last, 0.0), MAX_DT)
            self._t_last = t
            ref = self._sample(t)
            split = self.compute(q, dq, ref, dt)
            unclamped = split.total
            if not np.isfinite(unclamped).all():
                self.counts["dropped.nonfinite_torques"] += 1
                self.get_logger().error(
                    f"non-finite torque {unclamped} at t={t:.4f} s (q={q}, q̇={dq}): "
                    "no command sent",
                    throttle_duration_sec=1.0,
                )
                self._t_last = None  # integrate nothing across the gap
                return -1
            cmd = self._command
            tau = np.clip(unclamped, self._lowest_effort, self.effort_limits, out=cmd.effort)
            cmd.set_stamp(self._state_ns)
            self._command_bytes = cmd.to_bytes()
            self._pub.publish(self._command_bytes)
            sent = time.time_ns()
            self._answered_ns = self._state_ns
            if self._state_pub.get_subscription_count():  # nobody listening: nothing to build
                data = self._state.data
                data[0] = self._state_ns * 1e-9
                np.concatenate(
                    (
                        ref.q,
                        ref.dq,
                        ref.ddq,
                        q,
                        dq,
                        ref.q - q,
                        ref.dq - dq,
                        split.feedback,
                        split.model,
                        split.gravity,
                        unclamped,
                        tau,
                    ),
                    out=data[1:],
                )
                self._state_pub.publish(self._state.to_bytes())
            self.after_command(ref, q, unclamped, dt)
        return sent
