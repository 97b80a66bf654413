"""What one robot's closed loop did, as arrays: the result of :func:`~joint_space_control.
simulation.simulate` and of a :class:`~joint_space_control.simulation.world.World`.

Two time grids:

- the **states** the plant published, one per period of the loop (``t``, ``q``, ``dq``,
  ``tau_applied``) and the command that answered each (``tau``), with the controller's step
  in force then (``q_d``, ``tau_feedback``, ...: a step is held over the states of its
  control period, as the plant receives it);
- the **computed steps** (:attr:`Response.steps`), one per control period, exactly as the
  node's ``~/state`` records them: what the analysis measures (:meth:`Response.metrics`,
  :meth:`Response.step_info`), as ``jsc analyze`` measures a bag.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from joint_space_control.analysis.bag import ControllerState
from joint_space_control.analysis.figures import controller_figures
from joint_space_control.analysis.run_metrics import (
    controller_analysis,
    step_response,
    step_segments,
)
from joint_space_control.control.controller import STATE_FIELDS

if TYPE_CHECKING:
    from joint_space_control.control.policy import ControlPolicy
    from joint_space_control.simulation.world import Record

#: The step metrics :meth:`Response.step_info` gives per moving joint.
STEP_INFO = (
    "initial",
    "target",
    "step",
    "rise_time",
    "settling_time_2",
    "settling_time_5",
    "overshoot_percent",
    "final_value",
    "steady_state_error",
)


@dataclass(frozen=True)
class Response:
    """One robot's run. Arrays are (N,) over the published states or (N, n) with a column
    per joint in the order of ``joints``; units: rad (m for a prismatic joint), rad/s,
    N·m (N), s."""

    node: str
    """The controller's node name (``/pd_gravity_controller``, ``/<robot>/...``)."""
    robot: str
    law: str
    joints: tuple[str, ...]
    t: np.ndarray
    """Stamps of the published states [s]."""
    q: np.ndarray
    """Measured positions."""
    dq: np.ndarray
    """Measured velocities (NaN when the plant does not measure them)."""
    tau_applied: np.ndarray
    """The torque the plant applied over the period before each state (after its effort
    limits and torque-rate limit)."""
    tau: np.ndarray
    """The command answering each state (clamped to the effort limits)."""
    steps: ControllerState
    """The computed steps, one per control period (the node's ``~/state``)."""
    step_index: np.ndarray
    """For each state, the row of :attr:`steps` whose command answered it."""
    configs: list[tuple[int, dict]] = field(default_factory=list)
    """The controller's configurations (log time [ns], ``~/config`` document), in order."""
    events: list[dict[str, Any]] = field(default_factory=list)
    """Scheduled changes and the end, as :meth:`World.event` noted them."""
    q_true: np.ndarray | None = None
    """The true positions beside an imperfect measurement (None: the measurement is exact)."""
    dq_true: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    """What the plant could not give as asked (clipped initial positions, ...)."""
    log_times: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    """Log times [ns] of the states and commands as a recorder on simulation time logs them."""
    references: list[tuple[Any, ...]] = field(default_factory=list, repr=False)

    @classmethod
    def of(
        cls,
        record: Record,
        node: str,
        policy: ControlPolicy,
        exact: bool,
        warnings: list[str],
    ) -> Response:
        """The arrays of a world's record of one robot."""
        joints = tuple(policy.joints)
        n = len(joints)
        states = record.states
        t = np.array([s[0] for s in states], dtype=float) * 1e-9
        q = _stack([s[2] for s in states], n)
        dq = _stack([s[3] if s[3].size else np.full(n, np.nan) for s in states], n)
        applied = _stack([s[4] for s in states], n)
        tau = _stack([c[0] for c in record.commands], n)
        index = np.array([c[1] for c in record.commands], dtype=int)
        rows = np.array([s[2] for s in record.steps]).reshape(len(record.steps), -1)
        steps = ControllerState(
            topic=node.rstrip("/") + "/state",
            joints=joints,
            fields=STATE_FIELDS,
            stamp=np.array([s[0] for s in record.steps], dtype=float) * 1e-9,
            log_time=np.array([s[1] for s in record.steps], dtype=np.int64),
            rows={name: rows[:, k * n : (k + 1) * n] for k, name in enumerate(STATE_FIELDS)},
        )
        truth = record.truth if not exact else []
        law = record.configs[-1][1]["law"] if record.configs else ""
        return cls(
            node=node,
            robot=policy.model.spec.name,
            law=law,
            joints=joints,
            t=t,
            q=q,
            dq=dq,
            tau_applied=applied,
            tau=tau,
            steps=steps,
            step_index=index,
            configs=list(record.configs),
            events=list(record.events),
            q_true=_stack([x[0] for x in truth], n) if truth else None,
            dq_true=_stack([x[1] for x in truth], n) if truth else None,
            warnings=list(warnings),
            log_times={
                "states": np.array([s[1] for s in states], dtype=np.int64),
                "commands": np.array([c[2] for c in record.commands], dtype=np.int64),
            },
            references=list(record.references),
        )

    # -- the controller's step at each state -------------------------------------------
    def _held(self, name: str) -> np.ndarray:
        return self.steps.rows[name][self.step_index]

    @property
    def q_d(self) -> np.ndarray:
        """The reference position in force at each state."""
        return self._held("q_d")

    @property
    def dq_d(self) -> np.ndarray:
        return self._held("dq_d")

    @property
    def ddq_d(self) -> np.ndarray:
        return self._held("ddq_d")

    @property
    def error(self) -> np.ndarray:
        """e = q_d − q at each state (the measured q)."""
        return self.q_d - self.q

    @property
    def tau_feedback(self) -> np.ndarray:
        """The feedback part of the torque split (PD, PID)."""
        return self._held("tau_feedback")

    @property
    def tau_model(self) -> np.ndarray:
        """The model part (inverse dynamics, feedforward; 0 for the PD family)."""
        return self._held("tau_model")

    @property
    def tau_gravity(self) -> np.ndarray:
        """The gravity part (ĝ(q), ĝ(q_d), 0)."""
        return self._held("tau_gravity")

    @property
    def tau_unclamped(self) -> np.ndarray:
        """The law's torque before clamping to the effort limits."""
        return self._held("tau_unclamped")

    @property
    def config(self) -> dict:
        """The controller's configuration in force at the end (gains, limits, parameters)."""
        return self.configs[-1][1] if self.configs else {}

    # -- measured ----------------------------------------------------------------------
    def metrics(self) -> dict:
        """Every metric ``jsc analyze`` gives this controller: final error, step response
        per step, tracking error, torque demand, static offset, second-order prediction
        (:func:`~joint_space_control.analysis.run_metrics.controller_metrics`)."""
        analysis = controller_analysis(self.steps, self.configs)
        if analysis is None:
            raise ValueError(f"{self.node}: no computed step with finite values")
        return analysis.metrics

    def step_info(self, step: int = 0) -> dict[str, dict[str, float]]:
        """The step response of each joint the ``step``-th step of q_d moves (0: the first,
        -1: the last): rise time (10-90 %), settling times to 2 % and 5 %, overshoot [%],
        final value and steady-state error, measured as :meth:`metrics` measures them."""
        rows = self.steps.rows
        segments = step_segments(self.steps.stamp, rows["q_d"], rows["q"], rows.get("dq_d"))
        if not segments:
            raise ValueError("the reference has no step to measure")
        joints = step_response(self.steps, segments[step], self.configs, [], predict=False)
        return {
            name: {k: entry[k] for k in STEP_INFO if k in entry}
            for name, entry in joints["joints"].items()
            if entry["moving"]
        }

    def plot(self, out_dir: str | Path | None = None) -> dict[str, Path]:
        """The four figures of ``jsc analyze`` (positions, error, torques, torque split) as
        PNG files in ``out_dir`` (default: a new temporary folder); name → path (in a
        notebook: ``IPython.display.Image(path)``)."""
        import tempfile

        folder = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="jsc-"))
        return controller_figures(self.steps, self.metrics(), folder)


def _stack(rows: list[np.ndarray], n: int) -> np.ndarray:
    return np.array(rows, dtype=float).reshape(len(rows), n)
