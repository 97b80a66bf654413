r"""Theory boundaries drawn on the heat maps of a grid (THEORY.md §2–§3, §5), no ROS.

A boundary is a curve in the plane of a grid's first two axes (rows, columns) where the
theory says the behaviour changes. Each is registered by name in :data:`BOUNDARIES` (a
scenario names one in ``variants.boundary``) and is *one number of a run's settings*: the
value of its own axis (``parameters.kp``, ``parameters.omega_n``) at which the change
happens, computed from the scenario with the other axis's value applied (robot, plant,
controller parameters, reference), so that it moves with whatever the other axis sweeps:

- ``kp_alpha`` (own axis ``parameters.kp``): K_P = α. Constant gravity compensation
  τ = g(q_d) + K_P q̃ − K_D q̇ is globally asymptotically stable if every K_P,i > α with
  ‖∂g/∂q‖₂ ≤ α for all q (§2). α is that of the *plant*: with ``plant.payload_mass`` the
  point mass at the centre of mass of the last controlled joint's child link, where
  sim_bridge's plant puts it and :class:`~joint_space_control.model.dynamics.ModelPerturbation`
  models it, so that ``plant.payload_mass`` on the other axis moves the line.
- ``saturation_onset`` (own axis ``parameters.omega_n``): inverse dynamics (eq. 15) on a step
  Δ = q_d − q0 from rest at q0 (``plant.initial_positions``). At t = 0, q̇ = q̇_d = q̈_d = 0
  and K_P = ω_n² I, so the first command is

      τ(0) = B̂(q0) K_P Δ + ĝ(q0) = ω_n² b + ĝ(q0),    b = B̂(q0) Δ   [N·m]

  with the controller's model B̂, ĝ (``model_mass_scale`` scales the mass and rotational
  inertia of every link, hence B̂ and ĝ; ``model_payload_mass``, ``model_gravity`` as the
  node applies them). Per joint, |τ_i(0)| = τ_max,i is a quadratic in ω_n (linear in ω_n²):
  ω_n² = (sign(b_i) τ_max,i − ĝ_i) / b_i; the boundary is the smallest over joints (0 if
  gravity alone is at a limit, ∞ if b = 0). It is a statement about t = 0 only: later in the
  response the torque can peak elsewhere (a mismatched model, Coriolis terms), which is why
  the check that uses it (``saturation_boundary``) keeps a margin.

Pinocchio (``joint_space_control.model``) is imported when a boundary is computed, not when
a scenario is loaded.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from joint_space_control.arrays import per_joint

if TYPE_CHECKING:
    from joint_space_control.model.dynamics import RobotModel
    from joint_space_control.workbench.experiments.scenarios.format import Axis, Scenario


class Settings(Protocol):
    """What a boundary reads of a run: a
    :class:`~joint_space_control.workbench.experiments.scenarios.format.Scenario`, or a check's
    :class:`~joint_space_control.workbench.experiments.judging.outcome.RunView`."""

    robot: str
    plant: dict[str, Any]
    parameters: dict[str, Any]
    reference: dict[str, Any]
    # and the controller's executable: a Scenario's ``controller``, a RunView's ``executable``


#: Samples of the other axis per grid cell when a boundary curve is drawn across it.
SAMPLES_PER_CELL = 4


@dataclass(frozen=True)
class Curve:
    """A boundary in axis coordinates: ``coords[key]`` the values along the axis of ``key``
    (one sequence per axis of the plane, of equal length; NaN where undefined), placed on a
    heat map by :meth:`~joint_space_control.workbench.experiments.scenarios.format.
    Axis.positions`."""

    label: str
    coords: dict[str, Any]


@dataclass(frozen=True)
class Boundary:
    """A registered boundary: ``value(scenario)`` is where its own axis (``key``) crosses
    it for that scenario's settings; ``check(data)`` refuses a scenario it cannot apply to
    (``data``: the scenario's raw mapping) with one line."""

    name: str
    key: str
    label: str
    value: Callable[[Settings], float]
    check: Callable[[Mapping[str, Any]], None]


# --------------------------------------------------------------------------- models
def _model(robot: str, **perturbation: Any) -> RobotModel:
    from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
    from joint_space_control.model.robots import resolve_robot

    return RobotModel(resolve_robot(robot), perturbation=ModelPerturbation(**perturbation))


def gravity_jacobian(m: RobotModel, q: np.ndarray) -> np.ndarray:
    """∂g/∂q at q [N·m/rad] (Pinocchio's analytic derivative)."""
    import pinocchio as pin

    return np.asarray(
        pin.computeGeneralizedGravityDerivatives(m.model, m.data, m.configuration(q)),
        dtype=float,
    )


@functools.lru_cache(maxsize=256)
def gravity_bound(
    robot: str, payload_mass: float = 0.0, samples: int = 4000, seed: int = 0
) -> float:
    """α ≈ max over q of ‖∂g/∂q‖₂ (spectral norm) [N·m/rad] of ``robot`` carrying
    ``payload_mass`` [kg] (the plant's payload), by Pinocchio's analytic derivative of the
    generalized gravity at ``samples`` random configurations within the joint limits (a lower
    estimate of the supremum; dense enough for these arms)."""
    model = _model(robot, payload_mass=float(payload_mass))
    lo, hi = model.position_limits
    lo, hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)
    rng = np.random.default_rng(seed)
    best = 0.0
    for q in rng.uniform(lo, hi, size=(samples, model.n)):
        best = max(best, float(np.linalg.norm(gravity_jacobian(model, q), 2)))
    return best


def controller_model(settings: Settings) -> RobotModel:
    """The controller's own model B̂, ĝ of a run, as its node builds it from its parameters
    (:func:`~joint_space_control.workbench.experiments.execution.values.controller_model`)."""
    from joint_space_control.workbench.experiments.execution import values

    executable = getattr(settings, "executable", "") or settings.controller
    given = getattr(settings, "given", settings.parameters)  # a RunView's own, or a Scenario's
    return values.controller_model(executable, settings.robot, given)


# --------------------------------------------------------------------------- saturation
def step_torque_at_rest(model: RobotModel, q0: np.ndarray, delta: np.ndarray, omega_n: Any):
    """τ(0) = B̂(q0) K_P Δ + ĝ(q0) [N·m], K_P = diag(ω_n²): the inverse-dynamics command
    (eq. 15) at the instant of a step Δ from rest at q0."""
    kp = per_joint(omega_n, model.n, "omega_n") ** 2
    return model.inertia(q0) @ (kp * delta) + model.gravity(q0)


def saturation_onset_omega(model: RobotModel, q0: np.ndarray, delta: np.ndarray) -> float:
    """The smallest ω_n [rad/s] (the same on every joint) at which some |τ_i(0)| of
    :func:`step_torque_at_rest` reaches its effort limit τ_max,i: per joint
    ω_n² = (sign(b_i) τ_max,i − ĝ_i)/b_i with b = B̂(q0)Δ, the least over joints; 0 when
    |ĝ_i(q0)| ≥ τ_max,i already, ∞ when no joint ever reaches its limit."""
    b = model.inertia(q0) @ np.asarray(delta, dtype=float)
    g = model.gravity(q0)
    limits = model.effort_limits
    best = math.inf
    for b_i, g_i, lim in zip(b, g, limits, strict=True):
        if not math.isfinite(lim):
            continue
        if abs(g_i) >= lim:
            return 0.0
        if b_i == 0.0:
            continue
        best = min(best, (math.copysign(lim, b_i) - g_i) / b_i)
    return math.sqrt(best)


def step_of(scenario: Settings) -> tuple[np.ndarray, np.ndarray]:
    """(q0, Δ) of a step scenario: the plant's initial positions (clipped into the joint
    limits, as the plant does) and the step to the reference's target [rad]."""
    if scenario.reference.get("shape") != "step":
        raise ValueError(f"needs a step reference, got {scenario.reference.get('shape')!r}")
    from joint_space_control.workbench.experiments.execution import values

    model = controller_model(scenario)
    q0 = per_joint(
        values.plant_values(scenario.robot, scenario.plant)["initial_positions"],
        model.n,
        "initial_positions",
    )
    q0, _ = model.clip_into_limits(q0)
    target = per_joint(scenario.reference["target"], model.n, "target")
    return q0, target - q0


def saturation_onset(scenario: Settings) -> float:
    """:func:`saturation_onset_omega` of a run's settings (controller model, q0, target)."""
    q0, delta = step_of(scenario)
    return saturation_onset_omega(controller_model(scenario), q0, delta)


def _check_saturation(data: Mapping[str, Any]) -> None:
    if data.get("controller") != "inverse_dynamics_controller" or (
        (data.get("parameters") or {}).get("law", "inverse_dynamics") != "inverse_dynamics"
    ):
        raise ValueError(
            "boundary saturation_onset: needs inverse_dynamics_controller, law inverse_dynamics"
        )
    if (data.get("reference") or {}).get("shape") != "step":
        raise ValueError("boundary saturation_onset: needs a step reference")


def alpha_of(scenario: Settings) -> float:
    """α of a run's plant (:func:`gravity_bound` with ``plant.payload_mass``)."""
    from joint_space_control.workbench.experiments.execution import values

    plant = values.plant_values(scenario.robot, scenario.plant)
    return gravity_bound(scenario.robot, float(plant["payload_mass"]))


def _check_alpha(data: Mapping[str, Any]) -> None:
    if data.get("controller") != "pd_gravity_controller":
        raise ValueError("boundary kp_alpha: needs pd_gravity_controller (K_P as a torque gain)")


BOUNDARIES: dict[str, Boundary] = {
    b.name: b
    for b in (
        Boundary(
            "kp_alpha",
            "parameters.kp",
            "theory: K_P = α (larger K_P converges: sufficient condition)",
            alpha_of,
            _check_alpha,
        ),
        Boundary(
            "saturation_onset",
            "parameters.omega_n",
            "theory: saturation onset, |τ_i(0)| = τ_max,i at the step (larger ω_n saturates)",
            saturation_onset,
            _check_saturation,
        ),
    )
}


# --------------------------------------------------------------------------- on a grid
def validate(name: str, axes: Sequence[Axis], data: Mapping[str, Any]) -> None:
    """Refuse a boundary that is unknown, or whose own axis is not one of the first two
    (numeric, one number per value), or that does not apply to the scenario."""
    if name not in BOUNDARIES:
        raise ValueError(f"'variants.boundary' must be one of {sorted(BOUNDARIES)}, got {name!r}")
    b = BOUNDARIES[name]
    own = [a for a in axes[:2] if b.key in a.keys]
    if not own:
        raise ValueError(
            f"boundary {name}: one of the first two grid axes must sweep {b.key} (it is drawn "
            "in their plane)"
        )
    if not own[0].numeric:
        raise ValueError(f"boundary {name}: the {b.key} axis needs one number per value, in order")
    b.check(data)


def curve(name: str, scenario: Scenario, axes: Sequence[Axis]) -> Curve:
    """The boundary ``name`` in the plane of ``axes`` (rows, columns) of ``scenario`` (any
    further axis already applied): its own axis's value at each value of the other axis,
    :data:`SAMPLES_PER_CELL` per cell across the drawn width on a numeric axis, else at the
    grid values; NaN where the other axis's value is not a valid setting (a negative
    payload beyond the drawn edge, say)."""
    b = BOUNDARIES[name]
    own, other = axes if b.key in axes[0].keys else axes[::-1]
    n = len(other.values)
    if other.numeric and n > 1:
        at = other.values_at(np.linspace(-0.5, n - 0.5, SAMPLES_PER_CELL * n + 1))
        values: list[Any] = [float(v) for v in at]
    else:
        values = list(other.values)
    found = []
    for v in values:
        try:
            found.append(b.value(scenario.with_settings("boundary", other.settings(v))))
        except ValueError:
            found.append(math.nan)
    return Curve(b.label, {own.key: np.array(found, dtype=float), other.key: values})
