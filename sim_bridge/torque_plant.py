"""What a plant does whatever its physics engine: PyBullet's (:mod:`sim_bridge.plant`) and
MuJoCo's (:mod:`sim_bridge.mujoco_plant`) are the same torque-controlled robot.

The commanded torque, clamped to the effort limits (and approached at the torque-rate limit
if one is set), is held over every physics sub-step of a period (zero-order hold), with the
viscous friction −F q̇ of each sub-step and the external wrenches (held, and scheduled on
simulation time); the brakes hold the arm instead while no command may be applied; the
Coulomb friction's bound per joint is F_s while |q̇| < :data:`STICTION_SPEED`, F_c above.
A robot that compensates gravity itself (:meth:`TorquePlant.set_gravity_compensation`) adds
g(q) of its own model to the command at every sub-step, before the clamp: its motors apply
command + g(q), within the effort limits.
:class:`TorquePlant` does all of that once; an engine's plant gives what only the engine
can: its velocities, the torque it applies, its Coulomb friction and brakes, the wrench's Jᵀw.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from joint_space_control.arrays import nonnegative
from joint_space_control.laws.limits import limit_rate, rate_steps
from sim_bridge.wrench import WrenchSchedule, wrench_vector

GRAVITY = (0.0, 0.0, -9.81)
#: Force [N or N·m] of what holds a joint without an effort limit: the servos that lock the
#: joints that are not controlled (PyBullet), the brakes of a joint without a limit.
LOCK_FORCE = 1.0e4
#: A joint with stiction is stuck below this speed [rad/s or m/s]: the friction it can exert
#: there is the static F_s, above it the Coulomb F_c.
STICTION_SPEED = 1.0e-3


def coulomb_bounds(
    coulomb: float | Sequence[float], static: float | Sequence[float], n: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(F_c, F_s) per joint, checked: both ≥ 0, F_s = F_c where ``static`` is 0, otherwise
    F_s ≥ F_c (n: the number of joints; None: as many as given)."""
    if n is None:
        n = max(np.size(coulomb), np.size(static))
    fc = nonnegative(coulomb, n, "coulomb_friction")
    fs = nonnegative(static, n, "static_friction")
    fs = np.where(fs > 0, fs, fc)
    if np.any(fs < fc):
        raise ValueError(
            f"'static_friction' must be 0 (= coulomb_friction) or >= coulomb_friction "
            f"{fc.tolist()}, got {fs.tolist()}"
        )
    return fc, fs


@dataclass
class PlantState:
    q: np.ndarray
    dq: np.ndarray
    effort: np.ndarray  # motor torque applied during the last step [N·m]


class PlantFaultError(RuntimeError):
    """The simulation blew up (a non-finite or huge acceleration): the reason, in one line,
    is the message. The plant stays as it blew up until it is reset."""


class TorqueWorld:
    """The clock of the plants in one world: an engine's world gives :meth:`step`,
    :meth:`load` and :meth:`close`."""

    #: The engine's name (:data:`sim_bridge.engines.ENGINES`).
    engine = ""
    dt: float
    gui: bool

    def step(self) -> None:
        """One physics step of every plant of the world (PlantFaultError when the engine
        finds the simulation blown up)."""
        raise NotImplementedError

    def load(self, spec: Any, joints: Sequence[str], **kwargs: Any) -> TorquePlant:
        """A robot loaded into this world: the engine's plant, its arguments as
        :class:`sim_bridge.plant.Plant`'s (``physics_rate``, ``gui`` and ``world`` are the
        world's)."""
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def step_torques(
        self, plants: Sequence[Any], torques: Sequence[np.ndarray], substeps: int, t: float
    ) -> None:
        """One lockstep period from time ``t`` [s]: each plant's torque held over
        ``substeps`` physics steps of the whole world (with each plant's friction, rate
        limit and wrench applied before every step). sim_bridge's lockstep and the
        in-process engine both step the world through here."""
        for plant, tau in zip(plants, torques, strict=True):
            plant.begin_torque(tau)
        for k in range(substeps):
            for plant in plants:
                plant.apply_torque(k, t)
            self.step()
        for plant in plants:
            plant.end_torque()


class TorquePlant:
    """One robot under torque control, whatever its engine.

    The engine's plant sets, before :meth:`_start`: ``spec``, ``joint_names``, ``n``,
    ``world`` (a :class:`TorqueWorld`), ``dt``, ``effort_limits``, ``link_names`` (the
    engine's index of each moving link → its name) and ``_last_link`` (the index of the
    child link of the last controlled joint); and it implements the hooks :meth:`_velocities`,
    :meth:`_command`, :meth:`_set_coulomb`, :meth:`_coulomb_changed`, :meth:`_apply_wrench`,
    :meth:`begin_brake`, :meth:`end_brake`, :meth:`read_state`, :meth:`reset` and
    :meth:`set_payload`."""

    spec: Any
    joint_names: tuple[str, ...]
    n: int
    world: TorqueWorld
    dt: float
    effort_limits: np.ndarray
    link_names: dict[int, str]
    _last_link: int

    def _start(self, friction: float | Sequence[float]) -> None:
        """What every plant starts with: no rate limit, the viscous friction given, no
        Coulomb friction, no wrench, no torque applied yet."""
        self._lowest_effort = -self.effort_limits
        self._max_step: np.ndarray | None = None  # torque-rate limit per physics step [N·m]
        self.friction = np.zeros(self.n)
        self.set_friction(friction)
        self.coulomb = self.static = np.zeros(self.n)
        self._coulomb_on = self._stiction = False
        self._held: tuple[int, np.ndarray, np.ndarray] | None = None  # (link, f, μ)
        self._schedule: tuple[int, WrenchSchedule] | None = None
        self._effort = np.zeros(self.n)
        self._target = self._tau = np.zeros(self.n)  # the clamped command of the step
        self._gravity: Callable[[np.ndarray], np.ndarray] | None = None
        self._received = np.zeros(self.n)  # the command as received (gravity added to it)
        self._q_now, self._dq_now, self._effort_now = (np.zeros(self.n) for _ in range(3))

    # -- the engine's part -------------------------------------------------------------
    def _velocities(self) -> np.ndarray:
        raise NotImplementedError

    def _command(self, applied: np.ndarray) -> None:
        """Apply the joint torques ``applied`` over the next physics step."""
        raise NotImplementedError

    def _set_coulomb(self, bounds: np.ndarray) -> None:
        """The Coulomb friction's bound per joint from now on (0: none)."""
        raise NotImplementedError

    def _coulomb_changed(self, was_on: bool) -> None:
        """The Coulomb friction was set (``was_on``: whether there was one before)."""
        raise NotImplementedError

    def _apply_wrench(self, t: float) -> None:
        """The held and the scheduled wrench at time t, for the next physics step."""
        raise NotImplementedError

    def begin_brake(self) -> None:
        raise NotImplementedError

    def end_brake(self) -> None:
        raise NotImplementedError

    def read_state(self, q: np.ndarray, dq: np.ndarray, effort: np.ndarray) -> None:
        raise NotImplementedError

    # -- perturbations -----------------------------------------------------------------
    def set_friction(self, friction: float | Sequence[float]) -> None:
        self.friction = nonnegative(friction, self.n, "viscous_friction")
        self._has_friction = bool(np.any(self.friction))

    def set_coulomb_friction(
        self, coulomb: float | Sequence[float], static: float | Sequence[float] = 0.0
    ) -> None:
        """Coulomb friction F_c [N·m or N] and stiction F_s (0: same as F_c), per joint: a
        constraint the engine solves with the dynamics, so a joint whose net torque stays
        within the bound is held at rest (no chattering around q̇ = 0) and a sliding one
        feels −F_c sign(q̇). With stiction the bound is F_s while |q̇| <
        :data:`STICTION_SPEED`, F_c above it (re-chosen at every physics sub-step)."""
        fc, fs = coulomb_bounds(coulomb, static, self.n)
        was_on = self._coulomb_on
        self.coulomb, self.static = fc, fs
        self._coulomb_on = bool(np.any(fs))
        self._stiction = bool(np.any(fs != fc))
        self._coulomb_changed(was_on)

    def _coulomb_at(self, dq: np.ndarray) -> np.ndarray:
        """Each joint's Coulomb bound at the velocities ``dq`` (F_s while stuck)."""
        if self._stiction:
            return np.where(np.abs(dq) < STICTION_SPEED, self.static, self.coulomb)
        return self.coulomb

    def link_index(self, link: str) -> int:
        """The engine's index of the link named ``link`` ("": the child link of the last
        controlled joint); ValueError for the fixed base or an unknown name."""
        if not link:
            return self._last_link
        for j, name in self.link_names.items():
            if name == link:
                return j
        known = ", ".join(self.link_names.values())
        raise ValueError(f"no moving link '{link}' in {self.spec.name} (links: {known})")

    def hold_wrench(self, link: str, force: Sequence[float], torque: Sequence[float]) -> None:
        """Apply the wrench (force [N], torque [N·m], world frame, at the origin of the link
        frame; applied *to* the robot) from now on, instead of the one held before; a zero
        wrench removes it."""
        j = self.link_index(link)
        f, mu = wrench_vector(force, "force"), wrench_vector(torque, "torque")
        self._held = (j, f, mu) if (np.any(f) or np.any(mu)) else None

    def set_wrench_schedule(self, schedule: WrenchSchedule | None) -> None:
        """A wrench w(t) on simulation time (None or an inactive schedule: off); adds to the
        held one."""
        if schedule is None or not schedule.active:
            self._schedule = None
        else:
            self._schedule = (self.link_index(schedule.link), schedule)

    @property
    def has_wrench(self) -> bool:
        return self._held is not None or self._schedule is not None

    def set_gravity_compensation(self, gravity: Callable[[np.ndarray], np.ndarray] | None) -> None:
        """A robot that adds ``gravity(q)`` [N·m] (its own model's g at the joint positions)
        to every command, as torque-controlled arms with gravity compensation in their
        drives do (None: it does not)."""
        self._gravity = gravity

    def _compensated(self) -> np.ndarray:
        """The received command plus g(q) at the current positions, clamped."""
        self.read_state(self._q_now, self._dq_now, self._effort_now)
        tau = self._received + self._gravity(self._q_now)
        return np.clip(tau, self._lowest_effort, self.effort_limits)

    def set_torque_rate_limit(self, max_rate: float | Sequence[float]) -> None:
        """Limit the change of the applied torque to ``max_rate`` [N·m/s] per joint (0: no
        limit), from whatever was applied last, braking included."""
        rates = np.broadcast_to(np.asarray(max_rate, dtype=float), (self.n,))
        steps = rate_steps(rates, self.dt)
        self._max_step = None if np.all(np.isinf(steps)) else steps

    # -- simulation --------------------------------------------------------------------
    def state(self) -> PlantState:
        q, dq, effort = np.empty(self.n), np.empty(self.n), np.empty(self.n)
        self.read_state(q, dq, effort)
        return PlantState(q, dq, effort)

    def step(self, tau: np.ndarray, substeps: int = 1, t: float = 0.0) -> None:
        """Hold the motor torque tau (clamped to the effort limits, and approached at the
        torque-rate limit if one is set) over ``substeps`` physics steps, adding the viscous
        friction −F q̇ evaluated at each sub-step, the Coulomb friction and the external
        wrench (scheduled ones evaluated at t + k dt for sub-step k; t [s] is the
        simulation time at the start). Steps this plant's world: in a shared world, step
        every plant together with :meth:`begin_torque`/:meth:`apply_torque` (or the brake
        equivalents) and the world's ``step``."""
        self.begin_torque(tau)
        for k in range(substeps):
            self.apply_torque(k, t)
            self.world.step()
        self.end_torque()

    def begin_torque(self, tau: np.ndarray) -> None:
        """Start a step under torque control: the command (plus g(q) where the robot
        compensates gravity), clamped to the effort limits."""
        if self._gravity is not None:
            self._received = np.asarray(tau, dtype=float)
            self._target = self._compensated()
        else:
            self._target = np.clip(tau, self._lowest_effort, self.effort_limits)
        self._tau = self._target

    def apply_torque(self, k: int, t: float) -> None:
        """The motor torques (rate limit, friction) and the wrench for sub-step k, before
        the world steps."""
        if self._gravity is not None and k:  # g(q) where the arm is at this sub-step
            self._target = self._compensated()
            if self._max_step is None:
                self._tau = self._target
        tau = self._tau
        if self._max_step is not None:
            tau = limit_rate(self._target, self._effort, self._max_step)
            self._effort = self._tau = tau
        if self._has_friction or self._stiction:
            dq = self._velocities()
            applied = tau - self.friction * dq if self._has_friction else tau
            if self._stiction:
                self._set_coulomb(self._coulomb_at(dq))
        else:
            applied = tau
        self._command(applied)
        if self._held is not None or self._schedule is not None:
            self._apply_wrench(t + k * self.dt)

    def end_torque(self) -> None:
        self._effort = self._tau

    def brake(self, substeps: int = 1, t: float = 0.0) -> None:
        """Safe fallback: engage the brakes, at most the effort limit on every joint, so the
        arm stops and holds wherever it is (the external wrench still acts, at t + k dt);
        afterwards the Coulomb friction is as before. Steps this plant's world (see
        :meth:`step`)."""
        self.begin_brake()
        for k in range(substeps):
            self.apply_brake(k, t)
            self.world.step()
        self.end_brake()

    def apply_brake(self, k: int, t: float) -> None:
        if self._held is not None or self._schedule is not None:
            self._apply_wrench(t + k * self.dt)
