r"""The theory's design for a specification: the first trial of a new ``jsc tune`` study.
Pure (numpy), no ROS.

Each joint is taken as the second-order loop of its gains (THEORY.md §3: exact for nominal
inverse dynamics; for PD + g(q) with K_P,i = B̂_ii(q0)ω_n², K_D,i = 2ζB̂_ii(q0)ω_n, about q0
with the other joints at rest):

- ζ: above the ζ whose overshoot exp(−πζ/√(1−ζ²)) is the overshoot bound, by 0.1, and at
  least 0.8 (near the ζ ≈ 0.78 that settles fastest into a 2 % band);
- ω_n: the least ω_n whose settling (rise) times meet their bounds, t(ζ, ω_n) = t(ζ, 1)/ω_n,
  with a 25 % margin; at most the ω_n whose command at the step's instant,
  |g_i(q0)| + B_ii(q0) ω_n² |Δq_i|, stays under the peak-torque bound (90 % of it); where the
  two conflict, their geometric mean. Without a bound from below: 10 rad/s (the nodes'
  default), under the torque bound.

Saturation, coupling and sampling are what the study then searches around.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.analysis.spec import Spec
from joint_space_control.laws.gains import DEFAULT_OMEGA_N
from joint_space_control.tuning.space import SearchSpace

SPEED_MARGIN = 1.25
TORQUE_MARGIN = 0.9
MIN_ZETA = 0.8
_TIMES = {"settling_2pct": "settling_time_2", "settling_5pct": "settling_time_5"}


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
    ``spec``, per joint, from B_ii(q0) ``inertia``, |g(q0)| ``gravity``, the effort
    ``limits`` and the step Δq; clipped into the space's box."""
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
    omega = np.clip(omega, *space.omega_n)
    zetas = np.full(n, zeta)
    names = space.names()
    if space.gains == "omega_zeta":
        values = np.concatenate([omega, zetas])
    else:
        scale = space.scale
        values = np.concatenate([scale * omega**2, 2 * zetas * scale * omega])
    dists = space.distributions()
    return {
        name: float(np.clip(v, dists[name].low, dists[name].high))
        for name, v in zip(names, values, strict=True)
    }
