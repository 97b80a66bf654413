"""What every joint controller does between a measured state and a clamped torque.

    step(t, q, q̇) → new control period? (else: the held step) → velocity (measured or
                  estimated) → reference sample (q_d, q̇_d, q̈_d) at t → law → τ split
                  → non-finite gate → τ clamped to ±effort limits → law state updated
                  → command = τ (− ĝ(q) when the robot compensates gravity itself)

How it samples (:class:`~joint_space_control.control.sampling.Sampling`, swapped whole with
:meth:`Controller.set_sampling`): the velocity the law uses (the measured q̇, or an estimate
from the measured positions over the states' stamps, :mod:`joint_space_control.laws.
velocity`), whether the reference's q̇_d, q̈_d are used (else 0: the regulation form), and
the control period T_s: with T_s > 0 a torque is computed at the states on a 1/T_s grid
(:class:`~joint_space_control.control.sampling.ControlPeriod`) and the states in between are
answered with the same step (zero-order hold). Integrators and estimators see the realised
period: they are stepped at the computed states only.

References are scheduled by their start time: a trajectory that starts at or before t
replaces the active reference from its start on, continuing from the sample active then.
Before any reference, the controller holds the configuration it first measured. A restart
(time went backwards, states came back after a stop) forgets the reference, the pending
trajectories, the law's state and gains that were designed at the start configuration.

A robot that compensates gravity itself (``gravity_by_hardware``, the node's
``gravity_compensated_by_hardware``) adds g(q) to what it receives: the command is then the
law's torque, clamped to the effort limits as always, minus the model's ĝ(q) at the measured
q, so that the robot's motors see the law's torque (within the limits) once it has added its
own g(q). The step's ``tau`` and the split stay the law's (``~/state``).
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np

from joint_space_control.control.sampling import ControlPeriod, Sampling, VelocitySource
from joint_space_control.laws.split import TorqueSplit
from joint_space_control.laws.velocity import BackwardDifference, FilteredDifference
from joint_space_control.trajectories.reference import Reference, Sample, Trajectory

#: Longest time step integrated at once [s]; longer gaps (start-up, pauses) are cut.
MAX_DT = 0.1


class Step(NamedTuple):
    """One control step: the reference sample the law used, the torque split [N·m], the
    torque before and after clamping to the effort limits [N·m]; ``tau`` is None when the law
    gave a non-finite torque (NaN passes through a clamp): nothing must be sent then. ``q``
    and ``dq`` are the state the law used (``dq`` measured or estimated). ``command`` is
    what is sent [N·m]: ``tau``, or ``tau`` − ĝ(q) to a robot that adds g(q) itself (None
    as ``tau``; :attr:`sent` reads it, ``tau`` for a step built without one)."""

    ref: Sample
    split: TorqueSplit
    unclamped: np.ndarray
    tau: np.ndarray | None
    q: np.ndarray | None = None
    dq: np.ndarray | None = None
    command: np.ndarray | None = None

    @property
    def sent(self) -> np.ndarray | None:
        """The command sent to the robot [N·m] (None: nothing is sent)."""
        return self.tau if self.command is None else self.command


#: What a controller's state record holds per computed step (its node's ``~/state``), each
#: field per joint, in this order: the reference sample, the state the law used, the error
#: and its derivative, the torque split, the torque before and after clamping.
STATE_FIELDS = (
    "q_d",
    "dq_d",
    "ddq_d",
    "q",
    "dq",
    "error",
    "derror",
    "tau_feedback",
    "tau_model",
    "tau_gravity",
    "tau_unclamped",
    "tau",
)


def state_row(step: Step, out: np.ndarray | None = None) -> np.ndarray:
    """The step's :data:`STATE_FIELDS`, one after the other (into ``out`` when given)."""
    ref, split, q, dq = step.ref, step.split, step.q, step.dq
    fields = (
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
        step.unclamped,
        step.tau,
    )
    return np.concatenate(fields, out=out)


class Controller:
    """Base of the controllers: a configuration (immutable, swapped whole) with at least
    ``gains`` (None while they wait to be designed) and ``choice`` (the gain parameters,
    :class:`~joint_space_control.laws.gains.GainChoice`), and the effort limits."""

    #: True when gains designed from ω_n, ζ depend on the configuration (:meth:`design_gains`).
    GAINS_NEED_CONFIGURATION = False

    def __init__(
        self,
        config: Any,
        effort_limits: np.ndarray,
        sampling: Sampling | None = None,
        gravity_by_hardware: bool = False,
    ) -> None:
        self.effort_limits = np.asarray(effort_limits, dtype=float)
        #: The robot adds g(q) to the command itself (the command leaves ĝ(q) out).
        self.gravity_by_hardware = bool(gravity_by_hardware)
        self._lowest_effort = -self.effort_limits
        self.n = self.effort_limits.size
        self.q0: np.ndarray | None = None  # configuration measured at (re)start
        self.config = config
        self._t_last: float | None = None
        self._reference: Reference | None = None
        self._reference_end = np.inf  # time of its last knot after its start [s]
        self._held: Sample | None = None  # its sample from then on
        self._pending: list[Trajectory] = []
        self.sampling = Sampling()
        self.control_period = ControlPeriod()
        self._estimator: BackwardDifference | None = None
        #: The velocity the last computed step used (a VelocitySource, never AUTO).
        self.velocity_used: VelocitySource | None = None
        self._held_step: Step | None = None
        self._zero = np.zeros(self.n)
        self._zero.setflags(write=False)
        self.set_sampling(sampling or Sampling())
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

    def set_sampling(self, sampling: Sampling) -> None:
        """Swap the sampling settings whole. A new estimator starts from the last sample it
        observed; a new control period starts at the next state."""
        old, self.sampling = self.sampling, sampling
        if sampling.period != self.control_period.period:
            self.control_period.period = sampling.period
            self.control_period.reset()
            self._held_step = None
        kind = (
            BackwardDifference
            if sampling.velocity is VelocitySource.BACKWARD_DIFFERENCE
            else FilteredDifference
        )
        estimator = self._estimator
        if estimator is None or type(estimator) is not kind:
            new = kind(self.n) if kind is BackwardDifference else kind(self.n, sampling.cutoff)
            if estimator is not None and estimator.previous is not None:
                new.observe(*estimator.previous)
            self._estimator = new
        elif isinstance(estimator, FilteredDifference) and sampling.cutoff != old.cutoff:
            estimator.cutoff = sampling.cutoff

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
        self._estimator.reset()
        self.control_period.reset()
        self._held_step = None
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
    def step(
        self, t: float, q: np.ndarray, dq: np.ndarray, state_time: float | None = None
    ) -> Step:
        """The torque for the state (q, q̇) measured at ``state_time`` (default ``t``) [s],
        at the controller's time t [s] (``tau`` None when the law gave a non-finite torque:
        nothing is integrated across that gap). ``dq`` may be empty (no measured velocity)
        unless the velocity source is ``measured`` (then ValueError). Between two control
        periods (:class:`~joint_space_control.control.sampling.ControlPeriod`) it returns the
        step of the period, the same object."""
        periodic = self.control_period.period > 0.0
        if periodic and not self.control_period.due(t) and self._held_step is not None:
            return self._held_step
        if self.config.gains is None:
            self.design_at(q)
        dq = self._velocity(t if state_time is None else state_time, q, dq)
        if periodic:  # a period starts here (not when the velocity was refused)
            self.control_period.computed(t)
        dt = 0.0 if self._t_last is None else min(max(t - self._t_last, 0.0), MAX_DT)
        self._t_last = t
        ref = self.sample(t, q)
        if not self.sampling.reference_derivatives:
            ref = Sample(ref.q, self._zero, self._zero)
        split = self.compute(q, dq, ref, dt)
        unclamped = split.total
        if not np.isfinite(unclamped).all():
            self._t_last = None
            self._held_step = None  # the next state is computed again
            return Step(ref, split, unclamped, None, q, dq)
        tau = np.clip(unclamped, self._lowest_effort, self.effort_limits)
        self.after_step(ref, q, unclamped, dt)
        command = tau - self.config.model.gravity(q) if self.gravity_by_hardware else tau
        step = Step(ref, split, unclamped, tau, q, dq, command)
        if periodic:
            self._held_step = step
        return step

    def holding_torque(self, q: np.ndarray) -> np.ndarray:
        """The command that holds the arm at rest at ``q`` once the controller stops
        commanding a robot that holds its last command: ĝ(q) clamped to the effort limits
        [N·m], or zeros to a robot that compensates gravity itself."""
        if self.gravity_by_hardware:
            return np.zeros(self.n)
        gravity = self.config.model.gravity(np.asarray(q, dtype=float))
        return np.clip(gravity, self._lowest_effort, self.effort_limits)

    def _velocity(self, t: float, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The q̇ the law uses: measured, or estimated from the positions (sampling)."""
        source = self.sampling.velocity
        if source is VelocitySource.AUTO:
            source = VelocitySource.MEASURED if dq.size else VelocitySource.FILTERED_DIFFERENCE
        self.velocity_used = source
        if source is VelocitySource.MEASURED:
            if dq.size != self.n:
                raise ValueError("velocity_source is 'measured' but the state has no velocity")
            self._estimator.observe(t, q)
            return dq
        return self._estimator.update(t, q)
