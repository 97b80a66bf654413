"""The in-process engine: a lockstep run's world, controllers and bag in this process.

The ROS engine (:class:`~joint_space_control.experiments.harness.loop.ClosedLoop`) starts
``sim_bridge``, a controller per robot and the recorder as processes and lets them talk over
DDS. This engine runs the same objects on the same numbers without a ROS graph:

- the world is sim_bridge's: one world of the ``engine`` its parameters name (PyBullet or
  MuJoCo, :mod:`sim_bridge.engines`), each robot a :class:`~sim_bridge.robot_plant.RobotPlant`
  built from the same parameter values (:mod:`sim_bridge.parameters`), measured once per
  instant, stepped by the same :meth:`~sim_bridge.torque_plant.TorqueWorld.step_torques`;
- each controller is the object its node steps, built from the node's parameter values by
  :mod:`joint_space_control.control.configure`, answering every state as the node does with
  ``trigger: state`` (a held command inside a control period, the gains designed at the
  first state, a runtime change of parameters validated and swapped whole);
- references are the experiments' ``JointTrajectory`` messages, serialized and read by the
  controller's own reader, taken before the first state as the node takes them;
- the run is recorded as the recorder records it: a rosbag2 bag (MCAP) with the same
  topics and the same serialized messages (``joint_states``, ``effort_command``,
  ``reference``, each controller's ``~/state`` and ``~/config``, the plant's true state
  beside an imperfect measurement, ``/clock``), so the analysis, the checks and the figures
  read it as they read the ROS engine's. What differs: a bag's log times are the recorder's
  receive times (wall clock) on ROS and here the simulated time of each message (plus
  1 ns per message at one instant, to keep their order), so metrics of receive times
  (``receive_period_ms``) differ; ``/parameter_events`` and ``/diagnostics`` (wall-time
  timers) are not recorded.

What cannot run here, and is refused in one line: the realtime mode (it is a run against the
wall clock; use the ROS engine), and a run where the lockstep plant would wait for ever (a
controller that sends no command: a non-finite torque, a state without the velocity it
must measure) ends with that reason instead, as does a simulation that blew up (the plant's
fault, where sim_bridge stops until ``~/reset``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.serialization import serialize_message

from joint_space_control.control import parameters as params
from joint_space_control.control.configure import (
    config_document,
    controller_kind,
)
from joint_space_control.control.controller import Step
from joint_space_control.control.sampling import VelocitySource
from joint_space_control.experiments.harness.probe import in_namespace
from joint_space_control.experiments.scenarios.format import RobotSetup
from joint_space_control.recording.bag_writer import BagWriter
from joint_space_control.ros.messages import (
    STATE_FIELDS,
    JointOrder,
    config_message,
    reference_message,
    state_message,
    trajectory_from_bytes,
)
from joint_space_control.ros.wire import (
    Float64ArrayImage,
    JointStateImage,
    clock_bytes,
    fill_images,
)
from sim_bridge.engines import open_world
from sim_bridge.parameters import (
    PARAMETERS as PLANT_PARAMETERS,
)
from sim_bridge.parameters import (
    changed_by_robot,
    flat,
    lockstep_period,
    prefixed,
    robot_names,
    robot_values,
)
from sim_bridge.robot_plant import RobotPlant
from sim_bridge.torque_plant import PlantFaultError

JOINT_STATE = "sensor_msgs/msg/JointState"
STATE = "std_msgs/msg/Float64MultiArray"
CONFIG = "std_msgs/msg/String"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


class EngineError(RuntimeError):
    """The run cannot go on in this engine (the reason is the message)."""


class Recording:
    """The bag of a run (None: no bag), with its log times: the simulated time of each
    message, 1 ns later than the one before at the same instant (their order is the order
    they happened)."""

    def __init__(self, bag: BagWriter | None) -> None:
        self.bag = bag
        self.on = bag is not None
        self.ns = -1

    def topic(self, name: str, msgtype: str) -> Any:
        return self.bag.add_topic(name, msgtype) if self.bag is not None else None

    def write(self, topic: Any, t_ns: int, raw: bytes, exact: bool = False) -> None:
        """``raw`` at ``t_ns`` (or just after the message before it); ``exact``: the bytes
        of a wire image (:meth:`BagWriter.write`)."""
        self.ns = max(self.ns + 1, t_ns)
        if self.bag is not None:
            self.bag.write(topic, self.ns, raw, exact)


class InProcessController:
    """A controller node's part of the loop, in process: its parameter values, its core,
    its command and state images (the bytes its node would publish)."""

    def __init__(self, setup: RobotSetup, recording: Recording) -> None:
        self.kind = kind = controller_kind(setup.controller)
        self.node = "/" + in_namespace(setup.name, kind.executable)
        # what the ROS engine gives its node (loop.ClosedLoop): the robot, the scenario's
        # parameters, answering every state
        self.values = kind.values(**{"robot": setup.robot, **setup.parameters, "trigger": "state"})
        self.model = kind.model(self.values)
        self.rate = params.value(self.values, "rate")
        self.core = kind.controller(self.values, self.model, trigger="state")
        self.joints = self.model.joint_names
        self.order = JointOrder(self.joints)
        n = self.n = len(self.joints)
        self.command = JointStateImage(self.joints, (0, 0, n), frame_id=self.node)
        self.state = Float64ArrayImage(state_message(self.joints), 1 + len(STATE_FIELDS) * n)
        self._rec = recording
        self._topics = {
            name: recording.topic("/" + in_namespace(setup.name, name), msgtype)
            for name, msgtype in (
                ("effort_command", JOINT_STATE),
                ("reference", TRAJECTORY),
                (f"{kind.executable}/state", STATE),
                (f"{kind.executable}/config", CONFIG),
            )
        }
        self._state_topic = self._topics[f"{kind.executable}/state"]
        self._config_topic = self._topics[f"{kind.executable}/config"]
        self._command_topic = self._topics["effort_command"]
        self._last_step: Step | None = None
        self._answered_ns = -1
        self._tau: np.ndarray | None = None
        self.publish_config()

    def publish_config(self) -> None:
        document = config_document(
            self.kind,
            self.core,
            self.model,
            self.values,
            node=self.node,
            rate=self.rate,
            trigger="state",
            trigger_parameter="state",
        )
        if self._rec.on:
            self._rec.write(self._config_topic, 0, serialize_message(config_message(document)))

    def take_reference(self, msg: Any, now: float) -> None:
        """A reference message, read as the node reads it, before the first state."""
        raw = serialize_message(msg)
        self._rec.write(self._topics["reference"], 0, raw)
        trajectory = trajectory_from_bytes(raw, self.order, now, 0, self.model.position_limits)
        self.core.add_trajectory(trajectory)

    def answer(self, stamp_ns: int, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The command for the state (q, q̇) stamped ``stamp_ns``, as the node answers it
        with ``trigger: state`` (the same state again: the same answer)."""
        if stamp_ns == self._answered_ns:
            return self._tau
        if not dq.size and self.core.sampling.velocity is VelocitySource.MEASURED:
            raise EngineError(
                f"{self.node} rejects the joint states: no velocity, and velocity_source is "
                "'measured' (the lockstep plant would wait for ever)"
            )
        t = stamp_ns * 1e-9
        designing = self.core.gains_pending
        held = self._last_step
        try:
            step = self.core.step(t, q, dq, t)
        except ValueError as err:
            raise EngineError(f"{self.node}: no command: {err}") from None
        if step is not held:
            self._last_step = step
            if step.tau is None:
                raise EngineError(
                    f"{self.node}: non-finite torque {step.unclamped} at t={t:.4f} s: no "
                    "command (the lockstep plant would wait for ever)"
                )
            fill_images(self.command, self.state if self._rec.on else None, stamp_ns, step)
        else:
            self.command.set_stamp(stamp_ns)
        if self._rec.on:
            self._rec.write(self._command_topic, stamp_ns, self.command.to_bytes(), exact=True)
            if step is not held:
                self._rec.write(self._state_topic, stamp_ns, self.state.to_bytes(), exact=True)
        self._answered_ns = stamp_ns
        self._tau = self.command.effort.copy()
        if designing:
            self.publish_config()
        return self._tau

    def set_parameters(self, changes: Mapping[str, Any]) -> None:
        """A runtime update as the node takes it: every value checked, the configuration
        and the sampling swapped whole, ``~/config`` published again (EngineError naming
        what the node refuses)."""
        specs = {spec.name: spec for spec in self.kind.parameters}
        refused = params.refused_at_run_time(specs, changes)
        if refused:
            raise EngineError(f"{self.node} rejected " + "; ".join(refused))
        values = params.ParamValues(self.kind.parameters, {**self.values, **changes})
        try:
            model, config, new_sampling = self.kind.reconfigure(values, self.model, "state")
            for name in changes:
                params.value(values, name)
        except ValueError as err:
            raise EngineError(f"{self.node} rejected {err}") from None
        self.core.set_config(config)
        self.core.set_sampling(new_sampling)
        self.model, self.values = model, values
        self.publish_config()


class InProcessLoop:
    """A world of robots (one robot: its setup's name is "") with their controllers, run
    in lockstep in this process and recorded to the bag ``record``.

    ``sim_params``: the world's sim_bridge parameters (with a robot's own under its name's
    ``plant`` in its setup; one robot: its ``plant`` is among them, as the ROS engine gives
    them). Drive it with :meth:`send_reference`, :meth:`run_until`, :meth:`set_parameters`
    and close it (the bag is complete once closed)."""

    def __init__(
        self,
        setups: Sequence[RobotSetup],
        sim_params: Mapping[str, Any],
        record: Path | None = None,
    ) -> None:
        self.setups = list(setups)
        self._names = [s.name for s in self.setups]  # the robots' namespaces, in order
        one = len(self.setups) == 1 and not self.setups[0].name
        if one:
            given = {"robot": self.setups[0].robot, **sim_params}
        else:
            given = {
                "robots": self._names,
                **{s.name: {"robot": s.robot, **s.plant} for s in self.setups},
                **sim_params,
            }
        given = flat(given)
        if given.get("mode", "lockstep") != "lockstep":
            raise EngineError(
                f"the in-process engine runs lockstep only, not mode {given['mode']!r} "
                "(a realtime run is judged against the wall clock: use the ROS engine)"
            )
        given = {**given, "mode": "lockstep", "start_paused": True}
        names = robot_names(given.get("robots", []))
        specs = PLANT_PARAMETERS + tuple(spec for name in names for spec in prefixed(name))
        self.plant_values = params.defaults(specs, **given)
        self.substeps, physics_dt_ns = lockstep_period(self.plant_values)
        self.period_ns = self.substeps * physics_dt_ns
        self.t_ns = 0
        self.warnings: list[str] = []
        self.world = open_world(
            params.value(self.plant_values, "engine"),
            params.value(self.plant_values, "physics_rate"),
        )
        self.bag: BagWriter | None = None
        #: Every robot's published states, by namespace: (stamp [ns], q, q̇, τ measured).
        self.states: dict[str, list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]] = {
            s.name: [] for s in self.setups
        }
        try:
            self.robots = [
                RobotPlant(robot_values(self.plant_values, name), self.world, self._warn(name))
                for name in names or ("",)
            ]
            self.plants = [robot.plant for robot in self.robots]
            if record is not None:
                self.bag = BagWriter(record, "mcap", flush_period=0.0)
            self._rec = rec = Recording(self.bag)
            self._clock_topic = rec.topic("/clock", "rosgraph_msgs/msg/Clock")
            self.controllers = [InProcessController(s, rec) for s in self.setups]
            self._images, self._truths = [], []
            for setup, robot in zip(self.setups, self.robots, strict=True):
                n = robot.n
                image = JointStateImage(robot.joints, (n, n if robot.measure_velocity else 0, n))
                # the topic as the recorder finds it (sim_bridge's publisher is always
                # there), written only beside an imperfect measurement
                topic = "/" + in_namespace(setup.name, "sim_bridge/true_joint_states")
                true_topic = rec.topic(topic, JOINT_STATE)
                truth = None if robot.exact else (JointStateImage(robot.joints), true_topic)
                states = rec.topic("/" + in_namespace(setup.name, "joint_states"), JOINT_STATE)
                self._images.append((image, states))
                self._truths.append(truth)
        except BaseException:
            self.close()
            raise
        self._answers: list[np.ndarray] | None = None

    def _warn(self, name: str):
        return lambda text: self.warnings.append(f"{name}: {text}" if name else text)

    # -- driving -----------------------------------------------------------------------
    def send_reference(
        self,
        namespace: str,
        joints: Sequence[str],
        positions: Sequence[Sequence[float]],
        times: Sequence[float],
        velocities: Sequence[Sequence[float]] | None = None,
        accelerations: Sequence[Sequence[float]] | None = None,
    ) -> None:
        """The robot's reference, taken by its controller now (before the first state:
        it starts at t = 0, as the ROS engine's does)."""
        msg = reference_message(joints, positions, times, 0, velocities, accelerations)
        controller = self.controllers[self._names.index(namespace)]
        controller.take_reference(msg, max(self.t_ns, 0) * 1e-9)

    def run_until(self, t: float) -> None:
        """Step until the state at ``t`` [s] is published and answered (not stepped: a
        change made now applies from the next step, as when sim_bridge holds there)."""
        target = round(t * 1e9)
        while True:
            if self._answers is None:
                self._answers = self._publish_and_answer()
            if self.t_ns >= target:
                return
            try:
                self.world.step_torques(
                    self.plants, self._answers, self.substeps, self.t_ns * 1e-9
                )
            except PlantFaultError as err:
                raise EngineError(str(err)) from None
            self.t_ns += self.period_ns
            self._answers = None

    def _publish_and_answer(self) -> list[np.ndarray]:
        """Every robot's state at the current time, measured and recorded, and each
        controller's answer to it."""
        t_ns, rec = self.t_ns, self._rec
        if rec.on:
            rec.write(self._clock_topic, t_ns, clock_bytes(t_ns), exact=True)
        for setup, robot, (image, topic), truth in zip(
            self.setups, self.robots, self._images, self._truths, strict=True
        ):
            robot.measure(t_ns, image.position, image.velocity, image.effort)
            image.set_stamp(t_ns)
            if truth is not None and rec.on:
                true_image, true_topic = truth
                true_image.position[:] = robot.true_position
                true_image.velocity[:] = robot.true_velocity
                true_image.effort[:] = image.effort
                true_image.set_stamp(t_ns)
                rec.write(true_topic, t_ns, true_image.to_bytes(), exact=True)
            if rec.on:
                rec.write(topic, t_ns, image.to_bytes(), exact=True)
            self.states[setup.name].append(
                (t_ns, image.position.copy(), image.velocity.copy(), image.effort.copy())
            )
        return [
            controller.answer(t_ns, image.position.copy(), image.velocity.copy())
            for controller, (image, _) in zip(self.controllers, self._images, strict=True)
        ]

    def arrays(self, namespace: str = "") -> tuple[np.ndarray, ...]:
        """The robot's published states: t [s], q, q̇, τ (the motor torque of the step
        before), one row per state."""
        states = self.states[namespace]
        t = np.array([s[0] for s in states], dtype=float) * 1e-9
        return (t, *(np.array([s[k] for s in states]) for k in (1, 2, 3)))

    def positions(self, namespace: str = "") -> np.ndarray:
        """The robot's last published (measured) joint positions."""
        index = self._names.index(namespace)
        return self._images[index][0].position.copy()

    def gains(self, namespace: str = "") -> np.ndarray:
        """K_P in force on the robot's controller (as its ``~/config`` says)."""
        index = self._names.index(namespace)
        gains = self.controllers[index].core.config.gains
        if gains is None:
            raise EngineError("the gains are not designed yet (no state answered)")
        return np.array(gains.kp, dtype=float)

    def set_controller(self, namespace: str, changes: Mapping[str, Any]) -> None:
        if changes:
            index = self._names.index(namespace)
            self.controllers[index].set_parameters(changes)

    def set_plant(self, changes: Mapping[str, Any]) -> None:
        """A runtime update of sim_bridge's parameters (a robot's own: its plant's friction,
        payload, wrench, measurement), checked and applied as the node applies it."""
        changes = {k: v for k, v in flat(changes).items() if k != "pause_at"}
        if not changes:
            return
        refused = params.refused_at_run_time(self.plant_values.specs, changes)
        if refused:
            raise EngineError("sim_bridge rejected " + "; ".join(refused))
        values = params.ParamValues(
            self.plant_values.specs.values(), {**self.plant_values, **changes}
        )
        try:
            for name in changes:
                params.value(values, name)
            by_robot = changed_by_robot(self._names, changes)
            updates = [
                robot.update(robot_values(values, name), by_robot[name])
                for name, robot in zip(self._names, self.robots, strict=True)
                if name in by_robot
            ]
        except ValueError as err:
            raise EngineError(f"sim_bridge rejected {err}") from None
        for apply in updates:
            apply()
        self.plant_values = values

    def close(self) -> None:
        """Close the bag (complete from then on) and the world."""
        try:
            if self.bag is not None:
                self.bag.close()
        finally:
            self.world.close()
