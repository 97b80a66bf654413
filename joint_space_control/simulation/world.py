"""The closed loop in one process: a world of robots and their controllers, in lockstep.

A :class:`World` is what ``sim_bridge`` in lockstep mode and a controller node per robot do
together, on the same objects, with no ROS graph:

- the world is sim_bridge's: one world of the ``engine`` its parameters name (PyBullet or
  MuJoCo, :mod:`sim_bridge.engines`), each robot a :class:`~sim_bridge.robot_plant.RobotPlant`
  built from the same parameter values (:mod:`sim_bridge.parameters`), measured once per
  instant, stepped by the same :meth:`~sim_bridge.torque_plant.TorqueWorld.step_torques`;
- each controller is the :class:`~joint_space_control.control.policy.ControlPolicy` its node
  wraps, answering every state (``trigger: state``): the command held inside a control
  period, the gains designed at the first state, references taken in order, a parameter
  change validated and swapped whole;
- every state, command, computed step and configuration is kept (:class:`Record`) and
  given back as a :class:`~joint_space_control.simulation.response.Response` per robot.

Time is the simulation's: the run does not depend on the machine, and gives the same numbers
bit for bit as the nodes in lockstep. Each kept item also carries the log time a recorder
on simulation time would give it (the simulated time, 1 ns after the item before at the
same instant, in the order the nodes publish), so that a run analysed from memory and one
analysed from its bag agree to the last bit.

What stops a run, with its reason (:class:`LoopError`): a controller that sends no command
(a non-finite torque, a state without the velocity it must measure: the lockstep plant
would wait for ever), and a simulation that blew up (where sim_bridge stops until reset).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from joint_space_control.control import parameters as params
from joint_space_control.control.configure import controller_kind
from joint_space_control.control.controller import state_row
from joint_space_control.control.policy import ControlPolicy, Kind
from joint_space_control.trajectories.reference import checked_trajectory, times_in_seconds
from sim_bridge.engines import open_world
from sim_bridge.parameters import PARAMETERS as PLANT_PARAMETERS
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


class LoopError(RuntimeError):
    """The run cannot go on (the reason is the message)."""


@dataclass(frozen=True)
class Arm:
    """One robot of a world: its namespace ``name`` ("" for the one robot of a world), the
    ``robot`` its nodes load (a built-in name, or robot parameters such as ``urdf_path`` and
    ``package_paths`` in ``parameters`` and ``plant``), its ``controller`` (executable name),
    the controller's parameter values and the plant's parameters for this robot."""

    name: str = ""
    robot: str = "planar_2dof"
    controller: str = "pd_gravity_controller"
    parameters: Mapping[str, Any] = field(default_factory=dict)
    plant: Mapping[str, Any] = field(default_factory=dict)


class LogClock:
    """The log times a recorder on simulation time gives what the loop publishes: the
    simulated time of each item [ns], or 1 ns after the item before at the same instant."""

    def __init__(self) -> None:
        self.ns = -1

    def __call__(self, t_ns: int) -> int:
        self.ns = max(self.ns + 1, t_ns)
        return self.ns


@dataclass
class Record:
    """What one robot's loop published, as lists (arrays once the run is over)."""

    #: Joint states: stamp [ns], log time [ns], q, q̇ (empty: not measured), τ applied.
    states: list[tuple[int, int, np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    #: The plant's true state beside an imperfect measurement: q, q̇, log time per state.
    truth: list[tuple[np.ndarray, np.ndarray, int]] = field(default_factory=list)
    #: The command answering each state: τ [N·m], the index of its computed step, log time.
    commands: list[tuple[np.ndarray, int, int]] = field(default_factory=list)
    #: Computed steps (the node's ``~/state``): stamp [ns], log time [ns], STATE_FIELDS row.
    steps: list[tuple[int, int, np.ndarray]] = field(default_factory=list)
    #: The controller's configuration documents (``~/config``): log time [ns], document.
    configs: list[tuple[int, dict]] = field(default_factory=list)
    #: The references as sent: log time, joint names, positions, times, velocities,
    #: accelerations.
    references: list[tuple[Any, ...]] = field(default_factory=list)
    #: What happened during the run (scheduled changes, the end), in order.
    events: list[dict[str, Any]] = field(default_factory=list)


class Controlled:
    """One robot's controller in the loop: its policy and its node's name."""

    def __init__(self, arm: Arm) -> None:
        self.kind = kind = controller_kind(arm.controller)
        self.node = "/" + in_namespace(arm.name, kind.executable)
        given = {"robot": arm.robot, **arm.parameters, "trigger": "state"}
        self.policy = ControlPolicy(kind, kind.values(**given), trigger="state")

    @property
    def core(self) -> Any:
        """The controller the policy steps."""
        return self.policy.core

    @property
    def joints(self) -> tuple[str, ...]:
        """The controlled joints, in the controller's order."""
        return self.policy.joints

    def config(self) -> dict[str, Any]:
        return self.policy.config_document(self.node, "state")


class World:
    """A world of robots (``arms``) with their controllers, run in lockstep in this process.

    ``plant``: the world's sim_bridge parameters (``engine``, ``physics_rate``,
    ``publish_rate``, ...; a robot's own are in its :attr:`Arm.plant`). Drive it with
    :meth:`send_reference`, :meth:`run_until`, :meth:`set_controller`, :meth:`set_plant`;
    read it with :meth:`response`; :meth:`close` it (or use it as a context manager)."""

    def __init__(self, arms: Sequence[Arm], plant: Mapping[str, Any] | None = None) -> None:
        self.arms = list(arms)
        if not self.arms:
            raise ValueError("a world needs at least one robot")
        self.names = [a.name for a in self.arms]
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"robot names must differ: {self.names}")
        plant = dict(plant or {})
        one = len(self.arms) == 1 and not self.arms[0].name
        if one:
            given = {"robot": self.arms[0].robot, **self.arms[0].plant, **plant}
        else:
            if not all(self.names):
                raise ValueError("in a world of several robots each needs a name")
            given = {
                "robots": self.names,
                **{a.name: {"robot": a.robot, **a.plant} for a in self.arms},
                **plant,
            }
        given = flat(given)
        if given.get("mode", "lockstep") != "lockstep":
            raise LoopError(
                f"the loop in process runs lockstep only, not mode {given['mode']!r} (a "
                "realtime run is judged against the wall clock: run the nodes)"
            )
        given = {**given, "mode": "lockstep", "start_paused": True}
        names = robot_names(given.get("robots", []))
        specs = PLANT_PARAMETERS + tuple(spec for name in names for spec in prefixed(name))
        self.plant_values = params.defaults(specs, **given)
        self.substeps, physics_dt_ns = lockstep_period(self.plant_values)
        self.period_ns = self.substeps * physics_dt_ns
        self.t_ns = 0
        self.warnings: list[str] = []
        self.log = LogClock()
        self.world = open_world(
            params.value(self.plant_values, "engine"),
            params.value(self.plant_values, "physics_rate"),
        )
        try:
            self.robots = [
                RobotPlant(robot_values(self.plant_values, name), self.world, self._warn(name))
                for name in names or ("",)
            ]
            self.plants = [robot.plant for robot in self.robots]
            self.controllers = [Controlled(a) for a in self.arms]
            self.records = [Record() for _ in self.arms]
            self._buffers = []
            for robot in self.robots:
                n = robot.n
                self._buffers.append(
                    (np.zeros(n), np.zeros(n if robot.measure_velocity else 0), np.zeros(n))
                )
        except BaseException:
            self.world.close()
            raise
        for controlled, record in zip(self.controllers, self.records, strict=True):
            record.configs.append((self.log(0), controlled.config()))
        self._answers: list[np.ndarray] | None = None
        #: Clock instants published: (t [ns], log time [ns]).
        self.clock: list[tuple[int, int]] = []

    def _warn(self, name: str) -> Callable[[str], None]:
        return lambda text: self.warnings.append(f"{name}: {text}" if name else text)

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"no robot {name!r} in this world: {self.names}") from None

    # -- driving -----------------------------------------------------------------------
    def send_reference(
        self,
        name: str,
        joints: Sequence[str],
        positions: Sequence[Sequence[float]],
        times: Sequence[float],
        velocities: Sequence[Sequence[float]] | None = None,
        accelerations: Sequence[Sequence[float]] | None = None,
    ) -> None:
        """The robot's reference: points (one per row, joints in the order of ``joints``)
        at ``times`` [s] after now, taken by its controller as its node takes a
        JointTrajectory (checked, ValueError with the reason: unknown or missing joints,
        non-finite values, times not increasing, positions outside the limits)."""
        index = self._index(name)
        controlled = self.controllers[index]
        policy = controlled.policy
        now = max(self.t_ns, 0) * 1e-9
        order = _order(policy.joints, joints)
        times_ns, seconds = times_in_seconds(times)
        rows = [_rows(a, len(joints)) for a in (positions, velocities, accelerations)]
        picked = [None if r is None else r[:, order] for r in rows]
        self.records[index].references.append(
            (self.log(0), tuple(joints), rows[0], np.asarray(times, float), rows[1], rows[2])
        )
        try:
            trajectory = checked_trajectory(
                now, times_ns, seconds, *picked, now, policy.model.position_limits, policy.joints
            )
        except ValueError as err:
            raise ValueError(f"{controlled.node} rejected the reference: {err}") from None
        policy.take_reference(trajectory, policy.arrive())

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
                raise LoopError(str(err)) from None
            self.t_ns += self.period_ns
            self._answers = None

    def _publish_and_answer(self) -> list[np.ndarray]:
        """Every robot's state at the current time, measured and kept, and each
        controller's answer to it (the items logged in the order the nodes publish them:
        the clock, each robot's true and measured state, then each controller's command,
        state and configuration)."""
        t_ns, log = self.t_ns, self.log
        self.clock.append((t_ns, log(t_ns)))
        measured = []
        for robot, record, (q, dq, effort) in zip(
            self.robots, self.records, self._buffers, strict=True
        ):
            robot.measure(t_ns, q, dq, effort)
            if not robot.exact:
                truth = (robot.true_position.copy(), robot.true_velocity.copy(), log(t_ns))
                record.truth.append(truth)
            state = (t_ns, log(t_ns), q.copy(), dq.copy(), effort.copy())
            record.states.append(state)
            measured.append(state)
        answers = []
        for controlled, record, state in zip(
            self.controllers, self.records, measured, strict=True
        ):
            answer = controlled.policy.answer(t_ns, state[2], state[3])
            tau = answer.command
            if tau is None:
                raise LoopError(
                    f"{controlled.node}: no command: {answer.reason} (the lockstep plant "
                    "would wait for ever)"
                )
            command_log = log(t_ns)
            if answer.kind is Kind.COMPUTED:
                record.steps.append((t_ns, log(t_ns), state_row(answer.step)))
            record.commands.append((tau, len(record.steps) - 1, command_log))
            if answer.designed:
                record.configs.append((log(t_ns), controlled.config()))
            answers.append(tau)
        return answers

    # -- reading -----------------------------------------------------------------------
    def positions(self, name: str = "") -> np.ndarray:
        """The robot's last published (measured) joint positions."""
        states = self.records[self._index(name)].states
        if not states:
            raise LoopError("no state published yet")
        return states[-1][2].copy()

    def gains(self, name: str = "") -> np.ndarray:
        """K_P in force on the robot's controller."""
        gains = self.controllers[self._index(name)].policy.core.config.gains
        if gains is None:
            raise LoopError("the gains are not designed yet (no state answered)")
        return np.array(gains.kp, dtype=float)

    def event(self, name: str, what: Mapping[str, Any]) -> None:
        """Note an event of the run for the robot (a scheduled change, the end)."""
        self.records[self._index(name)].events.append(dict(what))

    # -- runtime changes ---------------------------------------------------------------
    def set_controller(self, name: str, changes: Mapping[str, Any]) -> None:
        """A runtime update of the robot's controller parameters, checked and swapped in
        whole as its node does (ValueError naming what it refuses)."""
        if not changes:
            return
        index = self._index(name)
        controlled = self.controllers[index]
        try:
            controlled.policy.set_parameters(changes)
        except ValueError as err:
            raise ValueError(f"{controlled.node} rejected {err}") from None
        self.records[index].configs.append((self.log(0), controlled.config()))

    def set_plant(self, changes: Mapping[str, Any]) -> None:
        """A runtime update of sim_bridge's parameters (a robot's own: its plant's friction,
        payload, wrench, measurement), checked and applied as the node applies it
        (ValueError naming what it refuses)."""
        changes = {k: v for k, v in flat(changes).items() if k != "pause_at"}
        if not changes:
            return
        refused = params.refused_at_run_time(self.plant_values.specs, changes)
        if refused:
            raise ValueError("sim_bridge rejected " + "; ".join(refused))
        values = params.ParamValues(
            self.plant_values.specs.values(), {**self.plant_values, **changes}
        )
        try:
            for name in changes:
                params.value(values, name)
            by_robot = changed_by_robot(self.names, changes)
            updates = [
                robot.update(robot_values(values, name), by_robot[name])
                for name, robot in zip(self.names, self.robots, strict=True)
                if name in by_robot
            ]
        except ValueError as err:
            raise ValueError(f"sim_bridge rejected {err}") from None
        for apply in updates:
            apply()
        self.plant_values = values

    def response(self, name: str = "") -> Any:
        """What the robot's loop did so far, as arrays
        (:class:`~joint_space_control.simulation.response.Response`)."""
        from joint_space_control.simulation.response import Response

        index = self._index(name)
        controlled = self.controllers[index]
        return Response.of(
            self.records[index],
            controlled.node,
            controlled.policy,
            self.robots[index].exact,
            self.warnings,
        )

    def close(self) -> None:
        """Close the world (its engine's resources)."""
        self.world.close()


def in_namespace(namespace: str, name: str) -> str:
    """``name`` in ``namespace`` ("": the root), without a leading slash."""
    return f"{namespace}/{name}" if namespace else name


def _order(controlled: Sequence[str], given: Sequence[str]) -> list[int]:
    """For each controlled joint, its column among ``given`` (ValueError for unknown,
    duplicated or missing names, as a controller refuses them)."""
    given = list(given)
    unknown = [j for j in given if j not in controlled]
    if unknown:
        raise ValueError(f"unknown joints {unknown}; the controller's are {list(controlled)}")
    if len(set(given)) != len(given):
        raise ValueError(f"duplicated joint names in {given}")
    missing = [j for j in controlled if j not in given]
    if missing:
        raise ValueError(f"missing joints {missing}")
    return [given.index(j) for j in controlled]


def _rows(values: Any, n: int) -> np.ndarray | None:
    if values is None:
        return None
    rows = np.atleast_2d(np.asarray(values, dtype=float))
    if rows.shape[1] != n:
        raise ValueError(f"{rows.shape[1]} values per point for {n} joints")
    return rows
