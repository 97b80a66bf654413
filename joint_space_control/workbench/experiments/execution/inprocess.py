"""The in-process engine: a scenario's lockstep run on the loop of
:mod:`joint_space_control.simulation`, recorded to a bag only when asked.

The ROS engine (:class:`~joint_space_control.processes.loop.ClosedLoop`) starts
``sim_bridge``, a controller per robot and the recorder as processes. This engine runs the
same plant objects and the same controller policy (:class:`~joint_space_control.simulation.
world.World`) in this process: the same numbers, bit for bit. Its run is measured from
memory (:class:`~joint_space_control.simulation.response.Response`); with ``record`` it is
also written as the recorder records it: a rosbag2 bag (MCAP) with the same topics and the
same serialized messages (``joint_states``, ``effort_command``, ``reference``, each
controller's ``~/state`` and ``~/config``, the plant's true state beside an imperfect
measurement, ``/clock``), logged at the simulated time of each message (1 ns apart at one
instant, in the order the nodes publish). ``/parameter_events`` and ``/diagnostics``
(wall-time topics) are not written.

What cannot run here, and is refused in one line (:class:`EngineError`): the realtime mode
(a run against the wall clock: use the ROS engine), and a run where the lockstep plant would
wait for ever (a controller that sends no command), as does a simulation that blew up.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import serialize_message

from joint_space_control.control.controller import STATE_FIELDS
from joint_space_control.recording.bag_writer import BagWriter
from joint_space_control.ros.messages import config_message, reference_message, state_message
from joint_space_control.ros.wire import Float64ArrayImage, JointStateImage, clock_bytes
from joint_space_control.simulation.world import Arm, LoopError, World, in_namespace
from joint_space_control.workbench.experiments.scenarios.format import RobotSetup

JOINT_STATE = "sensor_msgs/msg/JointState"
#: The world's methods that drive a run (their refusals are the engine's errors).
DRIVING = frozenset(
    ("send_reference", "run_until", "positions", "gains", "set_controller", "set_plant")
)


class EngineError(RuntimeError):
    """The run cannot go on in this engine (the reason is the message)."""


class InProcessLoop:
    """A scenario's world of robots (one robot: its setup's name is "") run in lockstep in
    this process, written to the bag ``record`` when it is closed (None: no bag).

    ``sim_params``: the world's sim_bridge parameters (a robot's own are in its setup's
    ``plant``). Drive it with :meth:`send_reference`, :meth:`run_until`,
    :meth:`set_controller`, :meth:`set_plant`; read it with :meth:`response`; close it."""

    def __init__(
        self,
        setups: Sequence[RobotSetup],
        sim_params: Mapping[str, Any],
        record: Path | None = None,
    ) -> None:
        arms = [Arm(s.name, s.robot, s.controller, s.parameters, s.plant) for s in setups]
        try:
            self.world = World(arms, sim_params)
        except LoopError as err:
            raise EngineError(str(err)) from None
        self.record = record

    def __getattr__(self, name: str) -> Any:
        """The world's attributes (``controllers``, ``plants``, ``warnings``, ...) and its
        driving methods (``send_reference``, ``run_until``, ``positions``, ``gains``,
        ``set_controller``, ``set_plant``), whose refusals become
        :class:`EngineError` with the same one-line reason."""
        if name == "world":  # not set: __init__ failed
            raise AttributeError(name)
        found = getattr(self.world, name)
        if name not in DRIVING:
            return found

        def driving(*args: Any, **kwargs: Any) -> Any:
            try:
                return found(*args, **kwargs)
            except (ValueError, LoopError) as err:
                raise EngineError(str(err)) from None

        return driving

    def arrays(self, namespace: str = "") -> tuple[np.ndarray, ...]:
        """The robot's published states: t [s], q, q̇, τ (the motor torque of the step
        before), one row per state."""
        states = self.world.records[self.world.names.index(namespace)].states
        t = np.array([s[0] for s in states], dtype=float) * 1e-9
        q, dq, tau = (np.array([s[k] for s in states]).reshape(len(states), -1) for k in (2, 3, 4))
        return t, q, dq, tau

    def close(self) -> None:
        """Write the bag when one is asked for (complete once closed), close the world
        (once: closing again does nothing)."""
        record, self.record = self.record, None
        try:
            if record is not None:
                write_bag(self.world, record)
        finally:
            self.world.close()


def _topics(arm: Arm, executable: str) -> dict[str, tuple[str, str]]:
    """A robot's recorded topics by role: (name, type)."""
    return {
        role: ("/" + in_namespace(arm.name, name), msgtype)
        for role, name, msgtype in (
            ("configs", f"{executable}/config", "std_msgs/msg/String"),
            ("references", "reference", "trajectory_msgs/msg/JointTrajectory"),
            ("states", "joint_states", JOINT_STATE),
            ("truth", "sim_bridge/true_joint_states", JOINT_STATE),
            ("commands", "effort_command", JOINT_STATE),
            ("steps", f"{executable}/state", "std_msgs/msg/Float64MultiArray"),
        )
    }


def recording(world: World, bag: Path | None = None) -> dict[str, Any]:
    """What a recorder on simulation time records of the world's run: its topics, their
    types and message counts, its log times (``bag``: where it was written, None: it was
    not)."""
    counts = {"/clock": len(world.clock)}
    types = {"/clock": "rosgraph_msgs/msg/Clock"}
    for arm, controlled, record in zip(world.arms, world.controllers, world.records, strict=True):
        for role, (name, msgtype) in _topics(arm, controlled.kind.executable).items():
            counts[name], types[name] = len(getattr(record, role)), msgtype
    last = world.log.ns
    return {
        "bag": None if bag is None else str(bag),
        "storage": None if bag is None else "mcap",
        "start_time_ns": 0,
        "duration_s": max(last, 0) * 1e-9,
        "message_count": sum(counts.values()),
        "message_counts": counts,
        "topic_types": types,
    }


def write_bag(world: World, path: Path) -> None:
    """The world's run as the recorder records it: every message the nodes publish, in
    log-time order (:class:`~joint_space_control.simulation.world.LogClock`)."""
    messages: list[tuple[int, str, bytes, bool]] = [
        (log_ns, "/clock", clock_bytes(t_ns), True) for t_ns, log_ns in world.clock
    ]
    topics: dict[str, str] = {"/clock": "rosgraph_msgs/msg/Clock"}
    for arm, controlled, record, robot in zip(
        world.arms, world.controllers, world.records, world.robots, strict=True
    ):
        joints, n = robot.joints, robot.n
        roles = _topics(arm, controlled.kind.executable)
        topics.update(roles.values())
        name = {role: topic for role, (topic, _) in roles.items()}
        for log_ns, document in record.configs:
            raw = serialize_message(config_message(document))
            messages.append((log_ns, name["configs"], raw, False))
        for log_ns, names, positions, times, velocities, accelerations in record.references:
            msg = reference_message(names, positions, times, 0, velocities, accelerations)
            messages.append((log_ns, name["references"], serialize_message(msg), False))
        image = JointStateImage(joints, (n, n if robot.measure_velocity else 0, n))
        for t_ns, log_ns, q, dq, effort in record.states:
            image.position[:], image.velocity[:], image.effort[:] = q, dq, effort
            image.set_stamp(t_ns)
            messages.append((log_ns, name["states"], image.to_bytes(), True))
        true_image = JointStateImage(joints)
        for (t_ns, _, _, _, effort), (q, dq, log_ns) in zip(
            record.states, record.truth, strict=False
        ):
            true_image.position[:], true_image.velocity[:], true_image.effort[:] = q, dq, effort
            true_image.set_stamp(t_ns)
            messages.append((log_ns, name["truth"], true_image.to_bytes(), True))
        command = JointStateImage(joints, (0, 0, n), frame_id=controlled.node)
        for (t_ns, *_), (tau, _, log_ns) in zip(record.states, record.commands, strict=False):
            command.effort[:] = tau
            command.set_stamp(t_ns)
            messages.append((log_ns, name["commands"], command.to_bytes(), True))
        state = Float64ArrayImage(state_message(joints), 1 + len(STATE_FIELDS) * n)
        for t_ns, log_ns, row in record.steps:
            state.data[0] = t_ns * 1e-9
            state.data[1:] = row
            messages.append((log_ns, name["steps"], state.to_bytes(), True))
    messages.sort(key=lambda m: m[0])
    bag = BagWriter(path, "mcap", flush_period=0.0)
    try:
        handles = {topic: bag.add_topic(topic, msgtype) for topic, msgtype in topics.items()}
        for log_ns, topic, raw, exact in messages:
            bag.write(handles[topic], log_ns, raw, exact)
    finally:
        bag.close()
