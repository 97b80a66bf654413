r"""The theory's design for a specification: the first trial of a new ``jsc tune`` study.
Pure (numpy), no ROS.

Each joint is taken as the second-order loop of its gains (THEORY.md §3: exact for nominal
inverse dynamics; for PD + g(q), K_P,i = b_i ω_n², K_D,i = 2ζ b_i ω_n with the effective
inertia b_i of :func:`effective_inertia`, exact about q0 along the step's direction when no
joint's coupling opposes its step):

- ζ: above the ζ whose overshoot exp(−πζ/√(1−ζ²)) is the overshoot bound, by 0.1, and at
  least 0.8 (near the ζ ≈ 0.78 that settles fastest into a 2 % band);
- ω_n: the least ω_n whose settling (rise) times meet their bounds, t(ζ, ω_n) = t(ζ, 1)/ω_n,
  with a 25 % margin; at most the ω_n whose command at the step's instant,
  |g_i(q0)| + B_ii(q0) ω_n² |Δq_i|, stays under the peak-torque bound (90 % of it); where the
  two conflict, their geometric mean. Without a bound from below: 10 rad/s (the nodes'
  default), under the torque bound.

Saturation, coupling and sampling are what the study then searches around, starting with a
small shared stage on the design's own gain ratios (:func:`zeta_ladder`,
:func:`time_scale`): under PD + g(q) (and nominal inverse dynamics) ω_n sets only the time
scale of the response, so one run tells the factor its settling needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.analysis.spec import Spec
from joint_space_control.laws.gains import DEFAULT_OMEGA_N
from joint_space_control.workbench.tuning.space import SearchSpace

SPEED_MARGIN = 1.25
TORQUE_MARGIN = 0.9
MIN_ZETA = 0.8
_TIMES = {"settling_2pct": "settling_time_2", "settling_5pct": "settling_time_5"}
#: The shared stage: the design's ζ raised by these on every joint, its ω_n and b kept.
ZETA_LADDER = (0.1, 0.2, 0.3)
#: A time-scaled trial aims at its time bounds divided by this.
SCALE_MARGIN = 1.1
#: The clauses whose value a time scaling by α divides by α.
TIME_METRICS = ("settling_2pct", "settling_5pct", "rise_time")


def effective_inertia(
    inertia_matrix: Sequence[Sequence[float]], step: Sequence[float]
) -> np.ndarray:
    r"""The inertia b_i [kg·m² or kg] each joint's PD gains are scaled by, from B(q0) and the
    step Δq:

        b_i = B_ii + |c_i|,        c_i = Σ_{j≠i} B_ij Δq_j / Δq_i

    (b_i = B_ii for a joint the step does not move). c_i is the coupling joint i feels along
    the step: with K_P = ω_n² diag(B Δq / Δq) and K_D = (2ζ/ω_n) K_P the linearised loop
    B ë + K_D ė + K_P e = 0 keeps e(t) = s(t) Δq with s̈ + 2ζω_n ṡ + ω_n² s = 0 (K_P Δq =
    ω_n² B Δq): every joint moves as one second order. Where c_i ≥ 0 that is b_i. Where the
    coupling opposes the step (c_i < 0: the others' acceleration drives joint i towards its
    target, or past it, B_ii + c_i ≤ B_ii, down to 0 or below) no positive gain keeps the
    direction, and b_i = B_ii + |c_i| makes the joint as much stiffer than its own inertia
    asks as the coupling torque it has to reject. Diagonal B (one joint, or decoupled
    joints): b = diag B, the decentralised design of laws/gains.py."""
    b = np.asarray(inertia_matrix, dtype=float)
    dq = np.asarray(step, dtype=float).reshape(-1)
    if b.shape != (dq.size, dq.size):
        raise ValueError(f"B must be {dq.size}×{dq.size}, got {b.shape}")
    diag = np.diag(b).copy()
    moved = np.abs(dq) > 0
    coupling = np.zeros_like(diag)
    coupling[moved] = (b @ dq - diag * dq)[moved] / dq[moved]
    return diag + np.abs(coupling)


def zeta_for_overshoot(percent: float) -> float:
    """ζ whose step overshoot is ``percent`` % (1 at 0 %, the inverse of
    exp(−πζ/√(1−ζ²)))."""
    if percent <= 0.0:
        return 1.0
    if percent >= 100.0:
        return 0.0
    log = math.log(percent / 100.0)
    return -log / math.sqrt(math.pi**2 + log**2)


def theory_design(
    spec: Spec,
    space: SearchSpace,
    inertia: Sequence[float],
    gravity: Sequence[float],
    limits: Sequence[float],
    step: Sequence[float],
) -> dict[str, float]:
    """The point of ``space`` (Optuna parameter names) the second-order theory picks for
    ``spec``, per joint, from the ``inertia`` its gains scale by (B_ii(q0) for inverse
    dynamics' torque, :func:`effective_inertia` for PD + g(q)), |g(q0)| ``gravity``, the
    effort ``limits`` and the step Δq; clipped into the space's box."""
    n = len(space.joints)
    b = np.asarray(inertia, dtype=float)
    g = np.abs(np.asarray(gravity, dtype=float))
    lim = np.asarray(limits, dtype=float)
    dq = np.maximum(np.abs(np.asarray(step, dtype=float)), 1e-9)
    bounds = {(c.metric, c.op): c.bound for c in spec.clauses}
    zeta_min = zeta_for_overshoot(bounds.get(("overshoot", "<="), 100.0))
    zeta = min(max(zeta_min + 0.1, MIN_ZETA), space.zeta[1])
    unit = second_order_prediction(1.0, zeta)  # times at ω_n = 1 rad/s
    need = 0.0
    for metric, key in (*_TIMES.items(), ("rise_time", "rise_time")):
        bound = bounds.get((metric, "<="))
        if bound is not None and bound > 0:
            need = max(need, SPEED_MARGIN * float(unit[key][0]) / bound)
    ratio = bounds.get(("peak_torque_ratio", "<="))
    if ratio is None and ("saturated_fraction", "<=") in bounds:
        ratio = 1.0  # no time at the limit: stay under it at the step
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(np.isfinite(lim), TORQUE_MARGIN * (ratio or math.inf) * lim - g, np.inf)
        cap = np.where(room > 0, np.sqrt(room / (b * dq)), 0.0) if ratio else np.full(n, np.inf)
    cap = np.where(np.isfinite(cap) & (b > 0), cap, np.inf)
    if need > 0:
        omega = np.where(need <= cap, need, np.sqrt(need * np.maximum(cap, 1e-9)))
    else:
        omega = np.minimum(DEFAULT_OMEGA_N, cap)
    return space.point(np.clip(omega, *space.omega_n), np.full(n, zeta))


def zeta_ladder(point: dict[str, float], space: SearchSpace) -> list[dict[str, float]]:
    """The shared stage's other points: ``point`` with ζ_i + Δζ on every joint, Δζ in
    :data:`ZETA_LADDER` (ω_n and b kept, inside the box; repeats left out). Under PD + g(q)
    the overshoot of a step does not depend on ω_n (:func:`time_scale`), so these try the
    damping the coupled loop needs."""
    omega, zeta = space.second_order(point)
    out: list[dict[str, float]] = []
    for dz in ZETA_LADDER:
        candidate = space.point(omega, zeta + dz)
        if candidate != point and candidate not in out:
            out.append(candidate)
    return out


def time_scale(spec: Spec, values: Sequence[Any], duration: float) -> float | None:
    r"""The factor α > 1 by which ω_n must grow (ζ and the gain ratios kept) for a run with
    the clause ``values`` of ``spec`` to meet its time bounds with a margin, or None (met
    with the margin already, or a miss the scaling cannot fix).

    Time scaling: if q(t) solves B(q)q̈ + C(q, q̇)q̇ = K_P(q_d − q) − K_D q̇ (PD + g(q) with
    g cancelled, or nominal inverse dynamics with B = I, C = 0), q(αt) solves it with α²K_P,
    αK_D; ω_n → αω_n at fixed ζ divides every settling and rise time by α and keeps the
    overshoot. So α = :data:`SCALE_MARGIN` · max_k t_k / t̄_k over the time clauses
    t_k ≤ t̄_k (a response that never settles counts as settling at ``duration``). None
    when the overshoot is missed (α does not change it). A ``>=`` time bound caps α at
    t_k / t̄_k, a peak-torque bound r̄ at √(r̄/r) (the feedback torque grows as α²: this
    holds where gravity is small); None when the cap is below the α needed. Friction,
    saturation and sampling break the scaling a little."""
    alpha, cap = 1.0, math.inf
    for clause, value in zip(spec.clauses, values, strict=True):
        v = math.inf if value is None else float(value)
        if math.isnan(v):
            continue
        if clause.metric == "overshoot" and clause.op == "<=" and v > clause.bound:
            return None
        if clause.metric in TIME_METRICS and clause.op == ">=":
            cap = min(cap, v / clause.bound if clause.bound > 0 else math.inf)
        elif clause.metric in TIME_METRICS and clause.bound > 0:
            alpha = max(alpha, SCALE_MARGIN * min(v, duration) / clause.bound)
        elif clause.metric == "peak_torque_ratio" and clause.op == "<=" and v > 0:
            cap = min(cap, math.sqrt(clause.bound / v))
    return alpha if 1.0 < alpha <= cap else None
