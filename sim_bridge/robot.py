"""One robot of the ``sim_bridge`` world: its plant, how it is measured, its topics, its
commander and its brakes.

The world (:mod:`sim_bridge.node`) owns time, the mode and the PyBullet client; each robot
owns what is its own: ``<ns>/joint_states`` (and ``<ns>/sim_bridge/true_joint_states``
beside an imperfect measurement), the commands from ``<ns>/effort_command`` and
``<ns>/sim_bridge/commands`` judged here (malformed or absurd: rejected and counted; from
another commander than the owner: refused, :mod:`sim_bridge.ownership`), the brakes (realtime,
after ``command_timeout`` without a valid command), ``<ns>/sim_bridge/wrench`` and
``<ns>/sim_bridge/release``. With one robot the namespace is the node's own: the topics are
``joint_states``, ``effort_command``, ``~/commands``, ``~/wrench``, ``~/release`` as always.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from joint_space_control.laws.limits import beyond_bound
from joint_space_control.ros import parameters as params
from joint_space_control.ros.graph import node_names
from joint_space_control.ros.messages import (
    CONTROL_PUBLISHER_QOS,
    JointOrder,
    effort_arrays,
    float_array,
)
from joint_space_control.ros.wire import JointStateImage, JointStateReader
from sim_bridge.ownership import ARRAY_COMMANDER, CommandOwnership
from sim_bridge.plant import Plant, World, coulomb_bounds
from sim_bridge.sensors import Encoder
from sim_bridge.wrench import WrenchSchedule

#: The safety counters of a robot (on /diagnostics; docs/safety.md).
COUNTERS = (
    "rejected.commands",
    "rejected.foreign_commands",
    "rejected.wrenches",
    "brake.engaged",
)


def quaternion(rpy: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of roll, pitch, yaw about the fixed x, y, z axes (R = Rz Ry Rx)."""
    (cr, sr), (cp, sp), (cy, sy) = ((math.cos(a / 2), math.sin(a / 2)) for a in rpy)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


class SimRobot:
    """A robot in the world; ``name`` is its namespace ("" : the node's, one robot)."""

    def __init__(self, node: Node, name: str, values: params.ParamValues, world: World) -> None:
        self.node = node
        self.name = name
        prefix = f"{name}/" if name else ""
        self.private = f"{name}/{node.get_name()}/" if name else "~/"
        model = params.robot_model(
            values, node=node, description_topic=prefix + "robot_description"
        )
        self.spec = model.spec
        self.label = name or model.spec.name
        self.joints = model.joint_names
        n = self.n = len(self.joints)
        self.plant = Plant(
            model.spec,
            self.joints,
            friction=params.value(values, "viscous_friction", n),
            payload_mass=params.value(values, "payload_mass"),
            initial_positions=self._initial_positions(values, model),
            locked_positions=model.locked_positions,
            effort_limits=model.effort_limits,
            world=world,
            base_position=params.value(values, "base_position"),
            base_orientation=quaternion(params.value(values, "base_rpy")),
        )
        self.plant.set_torque_rate_limit(params.value(values, "max_torque_rate", n))
        for warning in self.plant.warnings:
            self._log().warning(self._say(warning))
        self.plant.set_coulomb_friction(*self._coulomb(values))
        self.plant.set_wrench_schedule(self._schedule(values))
        self.encoder = Encoder(n, *self._encoder(values), seed=seed_of(values))
        self.measure_velocity = bool(values["measure_velocity"])

        self.counts = dict.fromkeys(COUNTERS, 0)
        self.ownership = CommandOwnership()
        self.tau: np.ndarray | None = None  # newest valid command (realtime)
        self.tau_t_ns = 0
        self.answer: np.ndarray | None = None  # lockstep: the command for the awaited state
        self.braking = True
        self.timed_out = False  # braking because commands stopped (not before the first)
        self._order = JointOrder(self.joints)
        self.effort_reader = JointStateReader(
            self._order, (2,), lambda m: (effort_arrays(m, self._order),), allow_extra=False
        )
        velocities = n if self.measure_velocity else 0
        self.image = JointStateImage(self.joints, (n, velocities, n))
        self._q, self._dq = np.zeros(n), np.zeros(n)  # true state, when measured
        self._truth = JointStateImage(self.joints)
        self.measured_ns: int | None = None  # time of the state in the image
        #: the topics as a log line names them (relative, as given)
        self.names = {t: prefix + t for t in ("joint_states", "effort_command")}
        self.topics = {
            "joint_states": node.resolve_topic_name(prefix + "joint_states"),
            "effort_command": node.resolve_topic_name(prefix + "effort_command"),
            "commands": node.resolve_topic_name(self.private + "commands"),
        }
        self.state_pub = node.create_publisher(
            JointState, prefix + "joint_states", CONTROL_PUBLISHER_QOS
        )
        self.true_pub = node.create_publisher(
            JointState, self.private + "true_joint_states", CONTROL_PUBLISHER_QOS
        )
        node.create_subscription(WrenchStamped, self.private + "wrench", self._on_wrench, 10)

    def _log(self) -> Any:
        return self.node.get_logger()

    def _throttled(self, kind: str, text: Any, *args: object) -> None:
        """A warning that may recur at every message: one line a second per kind and robot,
        with how many were held back (joint_space_control.throttle)."""
        self.node.log.warning((self.name, kind), text, *args)

    def _say(self, text: str) -> str:
        """A log line about this robot: named when the world has several."""
        return f"{self.name}: {text}" if self.name else text

    # -- parameters --------------------------------------------------------------------
    def _initial_positions(self, values: params.ParamValues, model: Any) -> np.ndarray:
        """``initial_positions``, clipped into the joint limits (with a log line when it
        had to be: a zero configuration can lie outside them, Panda joint 4 say)."""
        q0 = params.value(values, "initial_positions", self.n)
        clipped, outside = model.clip_into_limits(q0)
        if outside:
            self._log().warning(
                self._say(
                    f"initial positions of {outside} are outside their joint limits: clipped "
                    f"into them, starting at {clipped.tolist()}"
                )
            )
        return clipped

    def _coulomb(self, values: params.ParamValues) -> tuple[tuple[float, ...], ...]:
        """(F_c, F_s) per joint, checked (F_s = F_c where ``static_friction`` is 0)."""
        fc, fs = coulomb_bounds(
            params.value(values, "coulomb_friction", self.n),
            params.value(values, "static_friction", self.n),
        )
        return tuple(fc), tuple(fs)

    def _schedule(self, values: params.ParamValues) -> WrenchSchedule:
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

    def _encoder(self, values: params.ParamValues) -> tuple[np.ndarray, ...]:
        return (
            params.value(values, "encoder_counts", self.n),
            params.value(values, "position_noise", self.n),
            params.value(values, "velocity_noise", self.n),
        )

    def update(self, values: params.ParamValues, changed: set[str]) -> Any:
        """Check new values (ValueError with the reason); returns the function that applies
        them (with the world's lock held)."""
        friction = params.value(values, "viscous_friction", self.n)
        payload = params.value(values, "payload_mass")
        max_rate = params.value(values, "max_torque_rate", self.n)
        coulomb = self._coulomb(values)
        schedule = self._schedule(values)
        encoder = self._encoder(values)
        seed = seed_of(values)

        def apply() -> None:
            plant = self.plant
            plant.set_friction(friction)
            plant.set_torque_rate_limit(max_rate)
            if payload != plant.payload_mass:
                plant.set_payload(payload)
            if coulomb != (tuple(plant.coulomb), tuple(plant.static)):
                plant.set_coulomb_friction(*coulomb)
            plant.set_wrench_schedule(schedule)
            self.encoder.configure(*encoder)
            if "noise_seed" in changed:
                self.encoder.reseed(seed)

        return apply

    # -- state -------------------------------------------------------------------------
    def publish_state(self, t_ns: int) -> None:
        """The joint state at t_ns, measured once per instant (world lock held)."""
        image = self.image
        exact = self.encoder.exact and self.measure_velocity
        if self.measured_ns != t_ns:  # a new state: measured once
            if exact:
                self.plant.read_state(image.position, image.velocity, image.effort)
            else:
                self.plant.read_state(self._q, self._dq, image.effort)
                self.encoder.measure(self._q, self._dq, image.position, image.velocity)
            self.measured_ns = t_ns
        image.set_stamp(t_ns)
        if not exact and self.true_pub.get_subscription_count():
            truth = self._truth
            truth.position[:], truth.velocity[:], truth.effort[:] = self._q, self._dq, image.effort
            truth.set_stamp(t_ns)
            self.true_pub.publish(truth.to_bytes())
        self.state_pub.publish(image.to_bytes())

    def reset(self) -> None:
        self.plant.reset()
        self.measured_ns = None
        self.tau = None
        self.answer = None

    # -- commands ----------------------------------------------------------------------
    def read_effort(self, raw: bytes) -> tuple[int, np.ndarray] | None:
        """(stamp, τ) of a valid ``effort_command``, else None (rejected and counted)."""
        try:
            stamp, (tau,) = self.effort_reader.read(raw)
        except ValueError as err:
            self.counts["rejected.commands"] += 1
            self._throttled("effort", self._say("rejected effort command: {}"), err)
            return None
        return None if self._absurd(tau) else (stamp, tau)

    def read_array(self, msg: Float64MultiArray) -> np.ndarray | None:
        """τ of a valid ``~/commands`` array, else None (rejected and counted)."""
        try:
            tau = float_array(msg, self.n)
        except ValueError as err:
            self.counts["rejected.commands"] += 1
            self._throttled("array", self._say("rejected command array: {}"), err)
            return None
        return None if self._absurd(tau) else tau

    def _absurd(self, tau: np.ndarray) -> bool:
        """A command beyond ``reject_factor`` × the effort limits: rejected and counted (its
        sender is broken; clamping would apply the limit as if it meant it)."""
        factor = self.node.reject_factor
        if not beyond_bound(tau, self.plant.effort_limits, factor):
            return False
        self.counts["rejected.commands"] += 1
        self._throttled(
            "absurd",
            lambda: self._say(
                f"rejected command {tau.tolist()}: beyond {factor:g} × the effort "
                f"limits {self.plant.effort_limits.tolist()} (reject_factor)"
            ),
        )
        return True

    def admit(self, sender: str, now: float, timeout: float) -> bool:
        """One commander at a time (world lock held): False, counted and said, for a valid
        command from another one than the owner."""
        if self.ownership.admit(sender, now, timeout):
            return True
        self.counts["rejected.foreign_commands"] += 1
        owner = self.ownership.owner
        self._throttled(
            "foreign",
            lambda: self._say(
                f"rejected a command from {sender or '(unnamed)'!r}: {owner or '(unnamed)'!r} "
                "commands this plant (it is freed when its commands stop for command_timeout, "
                "when it leaves, or by ~/release)"
            ),
        )
        return False

    def commanders_present(self) -> set[str]:
        """The commanders on the graph (executor thread), to free the plant when its owner
        left (:meth:`CommandOwnership.left`, with the world's lock held)."""
        node = self.node
        publishers = node.get_publishers_info_by_topic(self.topics["effort_command"])
        present = node_names(publishers)
        if publishers:
            present.add("")  # an unnamed commander may be any of them
        if node.get_publishers_info_by_topic(self.topics["commands"]):
            present.add(ARRAY_COMMANDER)
        return present

    def release(self) -> str:
        owner = self.ownership.release()
        return f"released {owner or '(unnamed)'!r}" if owner is not None else "nobody owned it"

    def _on_wrench(self, msg: WrenchStamped) -> None:
        """Hold the wrench on the link ``header.frame_id`` names ('': the last controlled
        joint's child link) until the next message; a zero wrench removes it."""
        f, mu = msg.wrench.force, msg.wrench.torque
        try:
            with self.node.lock:
                self.plant.hold_wrench(msg.header.frame_id, (f.x, f.y, f.z), (mu.x, mu.y, mu.z))
        except ValueError as err:
            self.counts["rejected.wrenches"] += 1
            self._throttled("wrench", self._say("rejected wrench: {}"), err)

    # -- realtime ----------------------------------------------------------------------
    def begin_tick(self, t_ns: int, timeout: float) -> None:
        """Torque control with a fresh command, else the brakes (realtime, lock held)."""
        if self.tau is not None and (t_ns - self.tau_t_ns) * 1e-9 <= timeout:
            if self.braking:
                self.node.log.info(
                    (self.name, "torque"), lambda: self._say("valid commands: torque control")
                )
                self.braking = self.timed_out = False
            self.plant.begin_torque(self.tau)
            return
        if not self.braking:
            self.node.log.warning(
                (self.name, "brakes"),
                lambda: self._say(f"no valid command for {timeout} s: brakes engaged"),
            )
            self.braking = self.timed_out = True
            self.counts["brake.engaged"] += 1
        self.plant.begin_brake()

    def apply(self, k: int, t: float) -> None:
        """Sub-step k of the current tick (torque or brakes), before the world steps."""
        if self.braking:
            self.plant.apply_brake(k, t)
        else:
            self.plant.apply_torque(k, t)

    def end_tick(self) -> None:
        if self.braking:
            self.plant.end_brake()
        else:
            self.plant.end_torque()

    # -- diagnostics -------------------------------------------------------------------
    def diagnostics(self, realtime: bool) -> dict[str, Any]:
        """This robot's values (prefixed with its name in a world of several)."""
        key = f"{self.name}." if self.name else ""
        values = {
            "braking": int(realtime and self.braking),
            "owner": self.ownership.owner or "",
            **self.counts,
        }
        return {key + k: v for k, v in values.items()}

    def alarm(self, timeout: float) -> str | None:
        if self.timed_out:
            return self._say(f"no valid command for {timeout} s: brakes engaged")
        return None


def seed_of(values: params.ParamValues) -> int:
    seed = params.value(values, "noise_seed")
    if seed != int(seed):
        raise ValueError(f"'noise_seed' must be an integer, got {seed}")
    return int(seed)
