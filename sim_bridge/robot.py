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

As a ros2_control robot (the world's ``interface: ros2_control``) the commands come from
``<ns>/effort_controller/commands`` only (Float64MultiArray in the robot's joint order, as
the forward effort controller writes them): anyone may send them (no commander), a message
of the wrong size is dropped with a throttled line, and the last one is held.
"""

from __future__ import annotations

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
from sim_bridge.parameters import ROS2_CONTROL_COMMANDS
from sim_bridge.robot_plant import RobotPlant
from sim_bridge.torque_plant import TorqueWorld

#: The safety counters of a robot (on /diagnostics; docs/safety.md).
COUNTERS = (
    "rejected.commands",
    "rejected.foreign_commands",
    "rejected.wrenches",
    "brake.engaged",
)


class SimRobot:
    """A robot in the world; ``name`` is its namespace ("" : the node's, one robot)."""

    def __init__(
        self, node: Node, name: str, values: params.ParamValues, world: TorqueWorld
    ) -> None:
        self.node = node
        self.name = name
        prefix = f"{name}/" if name else ""
        self.private = f"{name}/{node.get_name()}/" if name else "~/"
        topic = prefix + "robot_description"
        self.body = RobotPlant(
            values,
            world,
            lambda text: self._log().warning(self._say(text)),
            lambda timeout: params.description_from_topic(node, timeout, topic),
        )
        self.plant, self.encoder = self.body.plant, self.body.encoder
        self.spec = self.body.spec
        self.label = name or self.spec.name
        self.joints = self.body.joints
        n = self.n = self.body.n
        self.measure_velocity = self.body.measure_velocity

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
        self._truth = JointStateImage(self.joints)
        #: the topics as a log line names them (relative, as given)
        #: as a ros2_control robot: commands from the forward effort controller's topic
        self.ros2_control = node.interface == "ros2_control"
        command = prefix + (ROS2_CONTROL_COMMANDS if self.ros2_control else "effort_command")
        self.names = {"joint_states": prefix + "joint_states", "effort_command": command}
        self.topics = {
            "joint_states": node.resolve_topic_name(prefix + "joint_states"),
            "effort_command": node.resolve_topic_name(command),
            "commands": node.resolve_topic_name(
                command if self.ros2_control else self.private + "commands"
            ),
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
    def update(self, values: params.ParamValues, changed: set[str]) -> Any:
        """Check new values (ValueError with the reason); returns the function that applies
        them (with the world's lock held)."""
        return self.body.update(values, changed)

    # -- state -------------------------------------------------------------------------
    def publish_state(self, t_ns: int) -> None:
        """The joint state at t_ns, measured once per instant (world lock held)."""
        image, body = self.image, self.body
        body.measure(t_ns, image.position, image.velocity, image.effort)
        image.set_stamp(t_ns)
        if not body.exact and self.true_pub.get_subscription_count():
            truth = self._truth
            truth.position[:], truth.velocity[:] = body.true_position, body.true_velocity
            truth.effort[:] = image.effort
            truth.set_stamp(t_ns)
            self.true_pub.publish(truth.to_bytes())
        self.state_pub.publish(image.to_bytes())

    def reset(self) -> None:
        self.body.reset()
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

    def read_forward(self, msg: Float64MultiArray) -> np.ndarray | None:
        """τ of a forward command controller's array (one value per joint, in the robot's
        joint order), else None: the wrong size is dropped as that controller drops it, a
        non-finite or absurd one is rejected (each counted, with a throttled line)."""
        if len(msg.data) != self.n:
            self.counts["rejected.commands"] += 1
            self._throttled(
                "size",
                self._say("dropped a command of {} values on {}: the robot has {} joints {}"),
                len(msg.data),
                self.names["effort_command"],
                self.n,
                list(self.joints),
            )
            return None
        return self.read_array(msg)

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
