"""What a controller node does with its controller between messages, with no ROS.

The controller (:class:`~joint_space_control.control.controller.Controller`) turns one
measured state into one torque. Around it, a controller node keeps a policy: which states
it answers and how, which references it takes, how a parameter change lands. That policy is
this object; the controller nodes (:mod:`joint_space_control.nodes.controller_base`) wrap it
in ROS input and output, and the in-process closed loop (:mod:`joint_space_control.
simulation`) drives it directly, so both run the same code:

- **a state is answered once per stamp**: the same stamp again gets the same answer
  (a lockstep plant sends a state again when its answer was lost);
- **within a control period the command is held** (the controller's zero-order hold), with
  the stamp of the state it answers;
- **a non-finite torque is never a command**: the answer says why there is none;
- **the gains are designed at the first state** (and again after a restart) where they
  wait for a configuration;
- **references are taken in the order they arrived**: one built after a newer one was
  taken is superseded, one that arrived before a restart is forgotten;
- **a parameter change is validated whole and swapped whole**: an invalid value raises
  ``ValueError`` with the reason, and nothing changes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from enum import Enum
from typing import Any, NamedTuple

import numpy as np

from joint_space_control.control import parameters as params
from joint_space_control.control.configure import ControllerKind, config_document, sampling
from joint_space_control.control.controller import Controller, Step
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.trajectories.reference import Trajectory


class Kind(Enum):
    """What an answer is."""

    COMPUTED = "computed"  # a new step: a new command, and a new ~/state
    HELD = "held"  # inside a control period: the period's command, this state's stamp
    REPEATED = "repeated"  # the state answered already: the same answer again
    NONE = "none"  # no command (``reason`` says why)


class Answer(NamedTuple):
    """The policy's answer to one state: ``step`` is the step whose ``tau`` is the command
    (None when there is none: no step, or a step whose torque is not finite);
    ``designed``: the gains were designed at this state."""

    kind: Kind
    step: Step | None
    designed: bool = False
    reason: str = ""

    @property
    def tau(self) -> np.ndarray | None:
        """The law's torque, clamped [N·m] (None: nothing is sent)."""
        return None if self.step is None else self.step.tau

    @property
    def command(self) -> np.ndarray | None:
        """The command sent [N·m]: ``tau``, minus ĝ(q) to a robot that compensates gravity
        itself (None: nothing is sent)."""
        return None if self.step is None else self.step.sent


class Taken(Enum):
    """What became of a reference handed to :meth:`ControlPolicy.take_reference`."""

    TAKEN = "taken"
    REJECTED = "rejected"  # invalid (the reason was given with it)
    SUPERSEDED = "superseded"  # built after a newer one was taken
    FORGOTTEN = "forgotten"  # arrived before the controller restarted


class ControlPolicy:
    """A controller node's controller, its parameter values and its policy.

    ``kind`` names the controller (:data:`~joint_space_control.control.configure.
    CONTROLLERS`), ``values`` its parameter values (:meth:`ControllerKind.values`), ``model``
    the controller's model (default: built from ``values``), ``trigger`` the trigger in force
    (``state``: every state answered, the command held over the states of a control period;
    ``timer``: every call computes)."""

    def __init__(
        self,
        kind: ControllerKind,
        values: params.ParamValues,
        model: RobotModel | None = None,
        trigger: str = "state",
    ) -> None:
        self.kind = kind
        self.values = values
        self.model = kind.model(values) if model is None else model
        self.rate: float = params.value(values, "rate")
        self.trigger = trigger
        self.core: Controller = kind.controller(values, self.model, trigger)
        self.state_timeout: float = params.value(values, "state_timeout")
        self.reject_factor: float = params.value(values, "reject_factor")
        self._answered_ns = -1  # the stamp of the state last answered
        self._last: Step | None = None  # the step of the control period in force
        # references are numbered as they arrive (arrive()); they take effect in that order
        self._arrivals = 0
        self._taken = 0  # the newest taken
        self._forgotten = 0  # the newest when the controller last restarted

    @property
    def joints(self) -> tuple[str, ...]:
        return tuple(self.model.joint_names)

    @property
    def answered_ns(self) -> int:
        """The stamp [ns] of the state last answered (-1: none yet)."""
        return self._answered_ns

    # -- states ------------------------------------------------------------------------
    def answer(self, stamp_ns: int, q: np.ndarray, dq: np.ndarray) -> Answer:
        """The answer to the state (q, q̇) stamped ``stamp_ns`` at the controller time of its
        stamp (``trigger: state``); the same stamp again: the same answer."""
        if stamp_ns == self._answered_ns and self._last is not None:
            return Answer(Kind.REPEATED, self._last)
        return self.step(stamp_ns * 1e-9, q, dq, stamp_ns)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, stamp_ns: int) -> Answer:
        """The command at the controller time ``t`` [s] for the state (q, q̇) stamped
        ``stamp_ns``: computed, or held inside a control period; none (with the reason)
        when the state lacks the velocity the law must measure or the law gives a
        non-finite torque."""
        core = self.core
        designing = core.gains_pending
        held = self._last
        try:
            step = core.step(t, q, dq, stamp_ns * 1e-9)
        except ValueError as err:  # velocity_source measured, this state has none
            return Answer(Kind.NONE, None, reason=str(err))
        if step is held:
            self._answered_ns = stamp_ns
            return Answer(Kind.HELD, step)
        self._last = step
        if step.tau is None:
            return Answer(
                Kind.NONE,
                step,
                reason=f"non-finite torque {step.unclamped} at t={t:.4f} s (q={q}, q̇={dq})",
            )
        self._answered_ns = stamp_ns
        return Answer(Kind.COMPUTED, step, designing)

    def restart(self) -> None:
        """Start over from the next state: the controller forgets its reference, its law's
        state and gains designed at the start; references that arrived before are dropped."""
        self._forgotten = self._arrivals
        self._last = None
        self.core.restart()

    def set_trigger(self, trigger: str) -> None:
        """Another trigger in force (its sampling swapped whole)."""
        self.trigger = trigger
        self.core.set_sampling(sampling(self.values, trigger, self.rate))

    # -- references --------------------------------------------------------------------
    def arrive(self) -> int:
        """Number the reference arriving now (they take effect in this order)."""
        self._arrivals += 1
        return self._arrivals

    def take_reference(
        self, result: Trajectory | str, arrived: int, start: float | None = None
    ) -> Taken:
        """Schedule the built trajectory ``result`` (a string: why it was rejected) that
        arrived as number ``arrived`` (:meth:`arrive`); ``start`` [s], if given, replaces
        its start (one built off the control path from a zero stamp starts when taken)."""
        if arrived <= self._forgotten:
            return Taken.FORGOTTEN
        if isinstance(result, str):
            return Taken.REJECTED
        if arrived < self._taken:
            return Taken.SUPERSEDED
        self._taken = arrived
        if start is not None:
            result = dataclasses.replace(result, start=start)
        self.core.add_trajectory(result)
        return Taken.TAKEN

    # -- parameters --------------------------------------------------------------------
    def prepare(self, values: params.ParamValues) -> Callable[[], None]:
        """Check the parameter values ``values`` (ValueError with the reason) and build
        what they swap in: the model's perturbation, the configuration, the sampling, the
        timeouts. Returns the function that swaps them in whole (cheap: a node calls it
        between two steps; nothing changes until it is called)."""
        model, config, new_sampling = self.kind.reconfigure(values, self.model, self.trigger)
        timeout = params.value(values, "state_timeout")
        reject_factor = params.value(values, "reject_factor")

        def apply() -> None:
            self.core.set_config(config)  # swapped whole; a step reads it once
            self.core.set_sampling(new_sampling)
            self.model, self.values = model, values
            self.state_timeout, self.reject_factor = timeout, reject_factor

        return apply

    def update(self, values: params.ParamValues) -> None:
        """Swap in the parameter values ``values`` whole (:meth:`prepare`, then apply)."""
        self.prepare(values)()

    def set_parameters(self, changes: Mapping[str, Any]) -> None:
        """A runtime update by name, checked as the node's parameter services check it
        (read-only, type and range, then :meth:`update`; ValueError naming what is
        refused)."""
        specs = {spec.name: spec for spec in self.kind.parameters}
        refused = params.refused_at_run_time(specs, changes)
        if refused:
            raise ValueError("; ".join(refused))
        values = params.ParamValues(self.kind.parameters, {**self.values, **changes})
        for name in changes:
            params.value(values, name)
        self.update(values)

    def config_document(self, node: str, trigger_parameter: str) -> dict[str, Any]:
        """What the node's ``~/config`` says now (:func:`~joint_space_control.control.
        configure.config_document`)."""
        return config_document(
            self.kind,
            self.core,
            self.model,
            self.values,
            node=node,
            rate=self.rate,
            trigger=self.trigger,
            trigger_parameter=trigger_parameter,
        )
