"""What every joint controller does between a measured state and a clamped torque.

    step(t, q, q̇) → reference sample (q_d, q̇_d, q̈_d) at t → law → τ split
                  → non-finite gate → τ clamped to ±effort limits → law state updated

References are scheduled by their start time: a trajectory that starts at or before t
replaces the active reference from its start on, continuing from the sample active then.
Before any reference, the controller holds the configuration it first measured. A restart
(time went backwards, states came back after a stop) forgets the reference, the pending
trajectories, the law's state and gains that were designed at the start configuration.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np

from joint_space_control.laws.split import TorqueSplit
from joint_space_control.trajectories.reference import Reference, Sample, Trajectory

#: Longest time step integrated at once [s]; longer gaps (start-up, pauses) are cut.
MAX_DT = 0.1


class Step(NamedTuple):
    """One control step: the reference sample, the torque split [N·m], the torque before and
    after clamping to the effort limits [N·m]; ``tau`` is None when the law gave a non-finite
    torque (NaN passes through a clamp): nothing must be sent then."""

    ref: Sample
    split: TorqueSplit
    unclamped: np.ndarray
    tau: np.ndarray | None


class Controller:
    """Base of the controllers: a configuration (immutable, swapped whole) with at least
    ``gains`` (None while they wait to be designed) and ``choice`` (the gain parameters,
    :class:`~joint_space_control.laws.gains.GainChoice`), and the effort limits."""

    #: True when gains designed from ω_n, ζ depend on the configuration (:meth:`design_gains`).
    GAINS_NEED_CONFIGURATION = False

    def __init__(self, config: Any, effort_limits: np.ndarray) -> None:
        self.effort_limits = np.asarray(effort_limits, dtype=float)
        self._lowest_effort = -self.effort_limits
        self.n = self.effort_limits.size
        self.q0: np.ndarray | None = None  # configuration measured at (re)start
        self.config = config
        self._t_last: float | None = None
        self._reference: Reference | None = None
        self._reference_end = np.inf  # time of its last knot after its start [s]
        self._held: Sample | None = None  # its sample from then on
        self._pending: list[Trajectory] = []
        self.reset_state()

    # -- to be provided by the concrete controller -----------------------------------
    def compute(self, q: np.ndarray, dq: np.ndarray, ref: Sample, dt: float) -> TorqueSplit:
        raise NotImplementedError

    def after_step(self, ref: Sample, q: np.ndarray, unclamped: np.ndarray, dt: float) -> None:
        """Update the law's state (integrators) once the torque is known."""

    def reset_state(self) -> None:
        """Forget the law's state (integrators, caches): bumpless start after a restart."""

    def design_gains(self, config: Any, q0: np.ndarray) -> Any:
        """``config`` with gains designed at the configuration ``q0`` (when ``config.gains``
        is None: ``GAINS_NEED_CONFIGURATION``)."""
        raise NotImplementedError

    # -- configuration ---------------------------------------------------------------
    def set_config(self, config: Any) -> None:
        """Swap the configuration whole; gains that wait for a configuration are designed at
        the start configuration when it is known."""
        if config.gains is None and self.q0 is not None:
            config = self.design_gains(config, self.q0)
        self.config = config

    @property
    def gains_pending(self) -> bool:
        """True until the gains are designed at the first measured configuration."""
        return self.config.gains is None

    def design_at(self, q: np.ndarray) -> None:
        """Design the pending gains at ``q``, which becomes the start configuration."""
        self.q0 = np.array(q, dtype=float)
        self.config = self.design_gains(self.config, self.q0)

    # -- references ------------------------------------------------------------------
    def add_trajectory(self, trajectory: Trajectory) -> None:
        """Schedule a validated trajectory; it replaces the ones that start after it."""
        self._pending = [p for p in self._pending if p.start < trajectory.start] + [trajectory]

    def restart(self) -> None:
        """Forget the reference, the pending trajectories, the law's state and gains designed
        at the start configuration: the next step starts over from its measured state."""
        self._reference, self._held, self._reference_end = None, None, np.inf
        self._pending = []
        self._t_last = None
        self.reset_state()
        self.q0 = None
        if self.GAINS_NEED_CONFIGURATION and self.config.choice.designed:
            self.config = dataclasses.replace(self.config, gains=None)

    def sample(self, t: float, q: np.ndarray) -> Sample:
        """The reference at t (holding ``q`` when there is none yet)."""
        if self._reference is None:
            self._set_reference(Reference.hold(q, t))
        while self._pending and self._pending[0].start <= t:
            traj = self._pending.pop(0)
            self._set_reference(Reference(traj, self._reference.sample(traj.start)))
        # past the last knot: the same sample every step
        if t - self._reference.trajectory.start >= self._reference_end:
            if self._held is None:
                self._held = self._reference.sample(t)
            return self._held
        return self._reference.sample(t)

    def _set_reference(self, reference: Reference) -> None:
        self._reference, self._held = reference, None
        self._reference_end = reference.end

    # -- the step --------------------------------------------------------------------
    def step(self, t: float, q: np.ndarray, dq: np.ndarray) -> Step:
        """The torque for the state (q, q̇) measured at t [s] (``tau`` None when the law gave
        a non-finite torque: nothing is integrated across that gap)."""
        if self.config.gains is None:
            self.design_at(q)
        dt = 0.0 if self._t_last is None else min(max(t - self._t_last, 0.0), MAX_DT)
        self._t_last = t
        ref = self.sample(t, q)
        split = self.compute(q, dq, ref, dt)
        unclamped = split.total
        if not np.isfinite(unclamped).all():
            self._t_last = None
            return Step(ref, split, unclamped, None)
        tau = np.clip(unclamped, self._lowest_effort, self.effort_limits)
        self.after_step(ref, q, unclamped, dt)
        return Step(ref, split, unclamped, tau)
