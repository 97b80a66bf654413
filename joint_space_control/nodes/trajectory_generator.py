"""``trajectory_generator``: publishes step, sinusoid, quintic and waypoint references.

The shapes are the pure functions of :mod:`joint_space_control.trajectories.shapes`; this
node holds their parameters, validates them and turns a shape into a
``trajectory_msgs/JointTrajectory`` on ``reference`` (relative name, for the controllers).

- ``~/publish`` (std_srvs/Trigger) publishes the configured shape (again). When the shape
  needs the current configuration (``quintic`` with ``start_from_current``, ``sinusoid``
  with an empty ``center``), the service waits up to :data:`JOINT_STATE_TIMEOUT` for one
  valid ``joint_states`` message and starts from its positions; the answer says what was
  published, or why not.
- ``publish_on_start``: publishes once, as soon as ``reference`` has a subscriber (and a
  joint state has arrived when one is needed). A later subscriber does not get it (see
  below); call ``~/publish``.
- Parameters can be changed at runtime; an invalid update is rejected with the reason and
  the old values stay. A change does not publish by itself.

Shapes (``shape``): ``step`` to ``target``; ``sinusoid`` q̄ + Δ sin(ωt + φ) for ``duration``
(q̄ = ``center``, or the current configuration when ``center`` is empty and
``start_from_current`` is true); ``quintic`` rest-to-rest minimum-jerk move to ``target`` in
``duration``: from the measured configuration with ``start_from_current`` (two points, so
q_d jumps at the start by the controller's tracking error, e.g. the PD's offset), otherwise
one point at ``duration`` that the controller reaches from the reference it tracks, without
any jump; ``waypoints`` as given (positions only: the controllers spline them).
``start_from_current`` has no effect on ``step`` and ``waypoints`` (absolute positions).

``header.stamp`` is 0 ("start when you receive it", for the controllers) with
``start_delay`` = 0, else now + ``start_delay`` in the node's clock (run with
``use_sim_time:=true`` against the simulator, like the controllers). While ``~/publish`` waits
for a joint state the node clock is not updated, so the stamp can be early by that wait.

The reference is *not* latched (volatile, like ``REFERENCE_QOS``): latching would not reach
the controllers anyway (their volatile subscriptions never receive a writer's history), and
a reference delivered late changes meaning: stamp 0 means "now" for whoever receives it, so a
stale step would be executed whenever a controller (re)starts, and a stamped trajectory would
be entered midway. A late subscriber asks for the reference with ``~/publish``.

Validation: every parameter on its own (types, finite values, one value or one per joint,
ranges), and the active shape as it would be published (e.g. ``waypoints`` is m × n with m
``waypoint_times``; at most ``shapes.MAX_POINTS`` samples). With ``shape: waypoints`` active,
change ``waypoints`` and ``waypoint_times`` in one atomic request (or switch the shape
first), since a one-parameter update would leave them inconsistent. Positions outside the
URDF position limits are rejected (sinusoid samples, quintic ends, waypoints; the overshoot
of the waypoint spline between points is not checked); for shapes that start from the
current configuration this check happens at publication.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.wait_for_message import wait_for_message
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.arrays import per_joint
from joint_space_control.ros import parameters as params
from joint_space_control.ros.messages import (
    CONTROL_QOS,
    REFERENCE_QOS,
    JointOrder,
    ns_to_stamp,
)
from joint_space_control.ros.node_main import run_node
from joint_space_control.throttle import ThrottledLog
from joint_space_control.trajectories import shapes
from joint_space_control.trajectories.reference import Trajectory

SHAPES = ("step", "sinusoid", "quintic", "waypoints")
#: How long ``~/publish`` waits for a joint state when it needs the current configuration
#: [s, wall clock]; the node does nothing else meanwhile.
JOINT_STATE_TIMEOUT = 2.0
#: Poll period of the publication on start [s], on the steady clock so that it also runs
#: before /clock does.
STARTUP_POLL = 0.05

PARAMETERS = params.ROBOT_PARAMETERS + (
    params.ParamSpec("shape", "step", "Reference shape", choices=SHAPES),
    params.ParamSpec("target", 0.0, "step: set-point; quintic: goal", dynamic=True, unit="rad"),
    params.ParamSpec(
        "duration",
        5.0,
        "quintic: move time; sinusoid: length",
        unit="s",
        minimum=0.0,
        exclusive=True,
        maximum=params.LONGEST,
    ),
    params.ParamSpec(
        "center",
        [],
        "sinusoid: centre q̄ [rad], one value or one per joint; empty: the current "
        "configuration (needs start_from_current)",
        kind="numbers",
    ),
    params.ParamSpec(
        "amplitude",
        0.1,
        "sinusoid: amplitude Δ",
        dynamic=True,
        unit="rad",
        minimum=-10.0,
        maximum=10.0,
    ),
    params.ParamSpec(
        "omega",
        1.0,
        "sinusoid: angular frequency ω",
        dynamic=True,
        unit="rad/s",
        minimum=0.0,
        maximum=1000.0,
    ),
    params.ParamSpec(
        "phase",
        0.0,
        "sinusoid: phase φ",
        dynamic=True,
        unit="rad",
        minimum=-2 * math.pi,
        maximum=2 * math.pi,
    ),
    params.ParamSpec(
        "sample_period",
        shapes.DEFAULT_SAMPLE_PERIOD,
        "sinusoid: sampling period",
        unit="s",
        minimum=0.0,
        exclusive=True,
        maximum=10.0,
    ),
    params.ParamSpec(
        "waypoints",
        [],
        "waypoints: positions [rad], row-major m × n (one row per waypoint)",
        kind="numbers",
    ),
    params.ParamSpec(
        "waypoint_times",
        [],
        "waypoints: m times after the start [s], >= 0, strictly increasing",
        kind="numbers",
    ),
    params.ParamSpec(
        "start_from_current",
        False,
        "Wait for one joint_states message and start from it: the quintic's start, the "
        "sinusoid's centre when 'center' is empty (no effect on step and waypoints)",
    ),
    params.ParamSpec(
        "start_delay",
        0.0,
        "header.stamp = now + start_delay (node clock); 0: stamp 0 = 'now'",
        unit="s",
        minimum=0.0,
        maximum=params.LONGEST,
    ),
    params.ParamSpec(
        "publish_on_start",
        True,
        "Publish once as soon as 'reference' has a subscriber",
        read_only=True,
    ),
)
#: What the node publishes, subscribes to and serves: (kind, relative name, type, meaning),
#: rendered into docs/reference by joint_space_control.nodes.reference.
INTERFACE = (
    (
        "publishes",
        "reference",
        "trajectory_msgs/msg/JointTrajectory",
        "the configured shape, on `~/publish` or once on start (`publish_on_start`); "
        "`header.stamp` 0 (on receipt) or now + `start_delay`; not latched",
    ),
    (
        "subscribes",
        "joint_states",
        "sensor_msgs/msg/JointState",
        "only when the shape starts from the current configuration: one valid state, at "
        "start or on `~/publish`",
    ),
    (
        "subscribes",
        "robot_description",
        "std_msgs/msg/String",
        "only with `robot:=topic`: the URDF text, latched (transient local)",
    ),
    (
        "serves",
        "~/publish",
        "std_srvs/srv/Trigger",
        "publish the configured shape (again); the answer says what was published, or why not",
    ),
)


@dataclass(frozen=True)
class GeneratorConfig:
    """Validated parameters of the generator (one value per joint where it applies)."""

    shape: str
    target: np.ndarray
    duration: float
    center: np.ndarray | None  # None: the current configuration
    amplitude: np.ndarray
    omega: np.ndarray
    phase: np.ndarray
    sample_period: float
    waypoints: np.ndarray | None  # (m, n)
    waypoint_times: np.ndarray | None
    start_from_current: bool
    start_delay: float

    @property
    def needs_current(self) -> bool:
        """Whether the shape starts from the current (measured) configuration."""
        if self.shape == "quintic":
            return self.start_from_current
        return self.shape == "sinusoid" and self.center is None

    def trajectory(self, current: np.ndarray | None = None) -> Trajectory:
        """The shape (times after its start); ``current`` when :attr:`needs_current`."""
        n = self.target.size
        if self.needs_current and current is None:
            raise ValueError(f"{self.shape} needs the current configuration")
        if self.shape == "step":
            return shapes.step(self.target, n)
        if self.shape == "quintic":
            start = current if self.start_from_current else None
            return shapes.quintic(start, self.target, self.duration, n)
        if self.shape == "sinusoid":
            center = current if self.center is None else self.center
            return shapes.sinusoid(
                center,
                self.amplitude,
                self.omega,
                self.phase,
                self.duration,
                self.sample_period,
                n,
            )
        if self.waypoints is None or self.waypoint_times is None:
            raise ValueError("shape 'waypoints' needs 'waypoints' and 'waypoint_times'")
        if len(self.waypoint_times) != len(self.waypoints):
            raise ValueError(
                f"{len(self.waypoints)} waypoints but {len(self.waypoint_times)} "
                "waypoint_times (change both in one atomic request)"
            )
        return shapes.waypoints(self.waypoints, self.waypoint_times, n=n)


def _optional_numbers(values: dict[str, Any], name: str) -> list[float] | None:
    """A number or a list of numbers; an empty list is None (not given). A YAML ``[]``
    arrives as a parameter without a value (None)."""
    value = values[name]
    if value is None or (isinstance(value, list | tuple | np.ndarray) and len(value) == 0):
        return None
    return params.numbers(values, name)


def build_config(values: dict[str, Any], n: int) -> GeneratorConfig:
    """Validate parameter values for n joints (``ValueError`` with a reason): each against its
    declaration (:data:`PARAMETERS`), then together."""
    values = params.ParamValues(PARAMETERS, values)
    shape = params.value(values, "shape")
    center = _optional_numbers(values, "center")
    omega = params.value(values, "omega", n)
    flat = _optional_numbers(values, "waypoints")
    if flat is not None and len(flat) % n:
        raise ValueError(
            f"'waypoints' has {len(flat)} values, not a multiple of the {n} joints "
            "(row-major, one row of n positions per waypoint)"
        )
    if flat is not None and not np.all(np.isfinite(flat)):
        raise ValueError("'waypoints' must be finite")
    times = _optional_numbers(values, "waypoint_times")
    if times is not None and (
        not np.all(np.isfinite(times)) or times[0] < 0 or np.any(np.diff(times) <= 0)
    ):
        raise ValueError(
            f"'waypoint_times' must be finite, >= 0 and strictly increasing, got {times}"
        )
    config = GeneratorConfig(
        shape=shape,
        target=params.value(values, "target", n),
        duration=params.value(values, "duration"),
        center=None if center is None else per_joint(center, n, "center"),
        amplitude=params.value(values, "amplitude", n),
        omega=omega,
        phase=params.value(values, "phase", n),
        sample_period=params.value(values, "sample_period"),
        waypoints=None if flat is None else np.array(flat).reshape(-1, n),
        waypoint_times=None if times is None else np.array(times),
        start_from_current=values["start_from_current"],
        start_delay=params.value(values, "start_delay"),
    )
    if shape == "sinusoid" and center is None and not config.start_from_current:
        raise ValueError(
            "'center' is empty: give the centre, or set start_from_current to centre the "
            "sinusoid on the current configuration"
        )
    # The active shape as it would be published; a stand-in for the current configuration
    # checks everything else (sizes, sample count, waypoint consistency).
    config.trajectory(np.zeros(n) if config.needs_current else None)
    return config


def joint_positions(msg: JointState, order: JointOrder) -> np.ndarray:
    """Positions of the joints in ``order`` (other joints ignored); velocities are not needed
    and not required."""
    idx = order.index(msg.name, allow_extra=True)
    if len(msg.position) != len(msg.name):
        raise ValueError(f"{len(msg.position)} positions for {len(msg.name)} names")
    q = np.asarray(msg.position, dtype=float)[idx]
    if not np.all(np.isfinite(q)):
        raise ValueError("non-finite positions")
    return q


def trajectory_message(
    traj: Trajectory, joints: Sequence[str], stamp_ns: int = 0
) -> JointTrajectory:
    """A JointTrajectory with the trajectory's points; velocities and accelerations only when
    the trajectory gives them (the controllers then fill them in, see ``reference.py``)."""
    if traj.positions.shape[1] != len(joints):
        raise ValueError(f"{traj.positions.shape[1]} columns for {len(joints)} joints")
    ns = np.rint(traj.times * 1e9).astype(np.int64)
    if np.any(np.diff(ns) <= 0):
        raise ValueError("trajectory times closer than 1 ns")
    positions = traj.positions.tolist()
    velocities = traj.velocities.tolist() if traj.velocities_given else None
    accelerations = traj.accelerations.tolist() if traj.accelerations_given else None
    msg = JointTrajectory(joint_names=list(joints))
    msg.header.stamp = ns_to_stamp(stamp_ns)
    points = []
    for k, t_ns in enumerate(ns.tolist()):
        sec, nanosec = divmod(t_ns, 1_000_000_000)
        point = JointTrajectoryPoint(
            positions=positions[k], time_from_start=Duration(sec=sec, nanosec=nanosec)
        )
        if velocities is not None:
            point.velocities = velocities[k]
        if accelerations is not None:
            point.accelerations = accelerations[k]
        points.append(point)
    msg.points = points
    return msg


class TrajectoryGenerator(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("trajectory_generator", **kwargs)
        params.declare(self, PARAMETERS)
        values = params.current_values(self, PARAMETERS)
        model = params.robot_model(values, node=self)
        self.joints = model.joint_names
        self.n = len(self.joints)
        self._lower, self._upper = model.position_limits
        self._order = JointOrder(self.joints)
        self.config = self._validate(values)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._pub = self.create_publisher(JointTrajectory, "reference", REFERENCE_QOS)
        self.create_service(Trigger, "~/publish", self._on_publish)
        # Publication on start: polled until a subscriber (and a joint state if needed).
        self._startup_timer = None
        self._state_sub = None
        self._current: np.ndarray | None = None
        self._log = ThrottledLog(self.get_logger())  # one line a second per kind
        if values["publish_on_start"]:
            self._startup_timer = self.create_timer(
                STARTUP_POLL, self._on_startup_poll, clock=Clock(clock_type=ClockType.STEADY_TIME)
            )
        self.get_logger().info(
            f"trajectory_generator: {model.spec.name}, joints {list(self.joints)}, "
            f"shape={self.config.shape}"
            + (", publishing on start" if values["publish_on_start"] else "")
        )

    # -- parameters --------------------------------------------------------------------
    def _validate(self, values: dict[str, Any]) -> GeneratorConfig:
        config = build_config(values, self.n)
        if not config.needs_current:
            self._check_limits(config.trajectory(), config.shape)
        return config

    def _check_limits(self, traj: Trajectory, shape: str) -> None:
        below = traj.positions < self._lower
        above = traj.positions > self._upper
        if np.any(below | above):
            k, j = np.argwhere(below | above)[0]
            raise ValueError(
                f"{shape} takes {self.joints[j]} to {traj.positions[k, j]:.6g} rad, outside "
                f"its position limits [{self._lower[j]:.6g}, {self._upper[j]:.6g}]"
            )

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        values = params.with_changes(self, PARAMETERS, changes)
        try:
            config = self._validate(values)
        except ValueError as err:
            self.get_logger().warning(f"rejected parameter update: {err}")
            return SetParametersResult(successful=False, reason=str(err))
        self.config = config  # swapped whole
        self.get_logger().info(
            "parameters updated: " + ", ".join(f"{p.name}={p.value}" for p in changes)
        )
        return SetParametersResult(successful=True)

    # -- publishing --------------------------------------------------------------------
    def _publish(self, config: GeneratorConfig, current: np.ndarray | None) -> str:
        """Publish the configured shape; returns what was published (ValueError: nothing)."""
        traj = config.trajectory(current)
        self._check_limits(traj, config.shape)
        stamp_ns = 0
        if config.start_delay > 0:
            stamp_ns = self.get_clock().now().nanoseconds + round(config.start_delay * 1e9)
        msg = trajectory_message(traj, self.joints, stamp_ns)
        self._pub.publish(msg)
        start = "on receipt" if stamp_ns == 0 else f"at t={stamp_ns * 1e-9:.3f} s"
        text = (
            f"published {config.shape}: {len(msg.points)} point(s) over "
            f"{traj.times[-1]:.3f} s, starting {start}, to "
            f"{self._pub.get_subscription_count()} subscriber(s)"
        )
        if current is not None:
            text += f", from q = {np.round(current, 6).tolist()}"
        self.get_logger().info(text)
        return text

    def _on_publish(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self._stop_startup()  # an explicit request replaces the pending one
        config = self.config
        current = None
        if config.needs_current:
            current, reason = self._wait_for_configuration(JOINT_STATE_TIMEOUT)
            if current is None:
                response.success = False
                response.message = f"not published: {reason}"
                self.get_logger().warning(response.message)
                return response
        try:
            response.message = self._publish(config, current)
            response.success = True
        except ValueError as err:
            response.success = False
            response.message = f"not published: {err}"
            self.get_logger().warning(response.message)
        return response

    def _wait_for_configuration(self, timeout: float) -> tuple[np.ndarray | None, str]:
        """The positions of the next valid joint state (blocks up to ``timeout`` [s])."""
        deadline = time.monotonic() + timeout
        reason = f"no joint_states within {timeout:g} s"
        while (remaining := deadline - time.monotonic()) > 0:
            ok, msg = wait_for_message(
                JointState, self, "joint_states", qos_profile=CONTROL_QOS, time_to_wait=remaining
            )
            if not ok:
                break
            try:
                return joint_positions(msg, self._order), ""
            except ValueError as err:
                reason = f"invalid joint_states: {err}"
        return None, reason

    def _on_joint_state(self, msg: JointState) -> None:
        try:
            self._current = joint_positions(msg, self._order)
        except ValueError as err:
            self._log.warning("rejected joint state", "rejected joint state: {}", err)

    def _on_startup_poll(self) -> None:
        config = self.config
        if config.needs_current:
            if self._state_sub is None:
                self.get_logger().info("waiting for joint_states to start from")
                self._state_sub = self.create_subscription(
                    JointState, "joint_states", self._on_joint_state, CONTROL_QOS
                )
            if self._current is None:
                return
        if self._pub.get_subscription_count() == 0:
            return
        current = self._current if config.needs_current else None
        self._stop_startup()
        try:
            self._publish(config, current)
        except ValueError as err:
            self.get_logger().error(f"not published on start: {err}")

    def _stop_startup(self) -> None:
        if self._startup_timer is not None:
            self.destroy_timer(self._startup_timer)
            self._startup_timer = None
        if self._state_sub is not None:
            self.destroy_subscription(self._state_sub)
            self._state_sub = None


def main(args: list[str] | None = None) -> None:
    run_node(TrajectoryGenerator, args)


if __name__ == "__main__":
    main()
