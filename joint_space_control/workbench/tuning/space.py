r"""The search space of ``jsc tune``: per-joint ω_n and ζ, or K_P and K_D. Pure (Optuna's
distributions, numpy), no ROS.

Both controllers design their gains from ``omega_n``/``zeta`` (laws/gains.py, THEORY.md §2–3):
inverse dynamics K_P = ω_n², K_D = 2ζω_n; the PD family K_P,i = B̂_ii(q0) ω_n²,
K_D,i = 2ζ B̂_ii(q0) ω_n. So one space serves both: ω_n,i log-uniform in ``omega_n`` (rad/s;
log: a decade of stiffness weighs as much at 2 as at 20 rad/s), ζ_i uniform in ``zeta``.

With an ``inertia`` b (``jsc tune`` gives the PD family the effective inertia each joint sees
along the step, workbench/tuning/design.py), a point (ω_n,i, ζ_i) stands for K_P,i = b_i ω_n,i²,
K_D,i = 2ζ_i b_i ω_n,i and is written as ``kp``/``kd``: the nodes' own ``omega_n`` rule scales
by diag B̂(q0), which ignores the coupling.

``gains="kp_kd"`` searches the gains themselves instead, about the same second-order box:
K_P,i log-uniform in b_i [ω_lo², ω_hi²] and K_D,i log-uniform in b_i [2ζ_lo ω_lo,
2ζ_hi ω_hi], with b_i as above for the PD family and 1 for inverse dynamics (its gains are
in 1/s² and 1/s); drawn independently, their pairs reach beyond [ζ_lo, ζ_hi] at the corners.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from optuna.distributions import BaseDistribution, FloatDistribution

GAINS = ("omega_zeta", "kp_kd")
#: Default box [rad/s] and [–], about the nodes' default design (ω_n = 10 rad/s, ζ = 1):
#: 2 % settling from about 3 s down to 0.1 s; at the default 1 kHz control rate
#: ω_n T_s ≤ 0.05, far inside the sampled-data stability limit (about 2); ζ from 16 %
#: overshoot to over-damped.
OMEGA_N_RANGE = (2.0, 50.0)
ZETA_RANGE = (0.5, 1.3)


def parse_range(text: str, what: str, positive: bool = True) -> tuple[float, float]:
    """``"LO:HI"`` → (LO, HI) with 0 ≤ LO < HI (0 < LO with ``positive``). ValueError."""
    try:
        lo, hi = (float(x) for x in str(text).split(":"))
    except ValueError:
        raise ValueError(f"{what} must be LO:HI (two numbers), got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi and lo >= 0):
        raise ValueError(f"{what} must be LO:HI with 0 <= LO < HI, got {text!r}")
    if positive and lo <= 0:
        raise ValueError(f"{what} must be LO:HI with 0 < LO < HI, got {text!r}")
    return lo, hi


@dataclass(frozen=True)
class SearchSpace:
    joints: tuple[str, ...]
    gains: str = "omega_zeta"
    omega_n: tuple[float, float] = OMEGA_N_RANGE
    zeta: tuple[float, float] = ZETA_RANGE
    inertia: tuple[float, ...] = ()
    """b_i of K_P,i = b_i ω_n,i², K_D,i = 2ζ_i b_i ω_n,i (empty: 1 on every joint, and an
    ``omega_zeta`` point is written as the nodes' ``omega_n``/``zeta``)."""

    def __post_init__(self) -> None:
        if self.gains not in GAINS:
            raise ValueError(f"gains must be one of {', '.join(GAINS)}, got {self.gains!r}")
        if self.inertia and len(self.inertia) != len(self.joints):
            raise ValueError("one inertia per joint")

    @property
    def scale(self) -> np.ndarray:
        return np.asarray(self.inertia or [1.0] * len(self.joints), dtype=float)

    def names(self) -> list[str]:
        """Optuna's parameter names: ``omega_n.<joint>``, ``zeta.<joint>`` (or kp, kd)."""
        first, second = ("omega_n", "zeta") if self.gains == "omega_zeta" else ("kp", "kd")
        return [f"{first}.{j}" for j in self.joints] + [f"{second}.{j}" for j in self.joints]

    def distributions(self) -> dict[str, BaseDistribution]:
        """What ``study.ask(fixed_distributions=...)`` samples."""
        n = len(self.joints)
        w_lo, w_hi = self.omega_n
        z_lo, z_hi = self.zeta
        if self.gains == "omega_zeta":
            boxes = [(w_lo, w_hi, True)] * n + [(z_lo, z_hi, False)] * n
        else:
            b = self.scale
            boxes = [(bi * w_lo**2, bi * w_hi**2, True) for bi in b]
            boxes += [(bi * 2 * max(z_lo, 0.01) * w_lo, bi * 2 * z_hi * w_hi, True) for bi in b]
        return {
            name: FloatDistribution(float(lo), float(hi), log=log)
            for name, (lo, hi, log) in zip(self.names(), boxes, strict=True)
        }

    def _pair(self, params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        names = self.names()
        n = len(self.joints)
        return (
            np.array([params[k] for k in names[:n]], dtype=float),
            np.array([params[k] for k in names[n:]], dtype=float),
        )

    def point(self, omega_n: np.ndarray, zeta: np.ndarray) -> dict[str, float]:
        """The point (Optuna parameter names) of per-joint ω_n, ζ (through b_i for
        ``kp_kd``: K_P = b ω_n², K_D = 2ζ b ω_n), clipped into the box."""
        omega = np.broadcast_to(np.asarray(omega_n, dtype=float), (len(self.joints),))
        zetas = np.broadcast_to(np.asarray(zeta, dtype=float), (len(self.joints),))
        if self.gains == "omega_zeta":
            values = np.concatenate([omega, zetas])
        else:
            values = np.concatenate([self.scale * omega**2, 2 * zetas * self.scale * omega])
        dists = self.distributions()
        return {
            name: float(np.clip(v, dists[name].low, dists[name].high))
            for name, v in zip(self.names(), values, strict=True)
        }

    def time_scaled(self, params: dict[str, float], alpha: float) -> dict[str, float]:
        """The point whose loop is ``params``' run α times faster: ω_n,i → α ω_n,i with ζ_i
        kept (K_P → α² K_P, K_D → α K_D), clipped into the box."""
        omega, zeta = self.second_order(params)
        return self.point(alpha * omega, zeta)

    def node_gains(self, params: dict[str, float]) -> dict[str, Any]:
        """The controller parameters of a point: ``omega_n``/``zeta`` with kp = kd = 0, or
        ``kp``/``kd`` with omega_n = 0 (laws/gains.py: omega_n > 0 wins over kp); with an
        ``inertia``, always ``kp``/``kd`` (K_P = b ω_n², K_D = 2ζ b ω_n)."""
        a, b = self._pair(params)
        if self.gains == "omega_zeta" and not self.inertia:
            return {"omega_n": a.tolist(), "zeta": b.tolist(), "kp": 0.0, "kd": 0.0}
        kp, kd = self.kp_kd(params)
        return {"kp": kp.tolist(), "kd": kd.tolist(), "omega_n": 0.0}

    def second_order(self, params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(ω_n, ζ) per joint of a point (of K_P, K_D through b_i for ``kp_kd``)."""
        a, b = self._pair(params)
        if self.gains == "omega_zeta":
            return a, b
        omega = np.sqrt(a / self.scale)
        return omega, b / (2 * self.scale * omega)

    def kp_kd(self, params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(K_P, K_D) per joint of a point: b_i ω_n², 2ζ b_i ω_n (b_i as above)."""
        if self.gains == "kp_kd":
            return self._pair(params)
        omega, zeta = self._pair(params)
        return self.scale * omega**2, 2 * zeta * self.scale * omega

    def describe(self) -> str:
        """The space in one line (help, report)."""
        inertia = ", b = " + ", ".join(f"{x:.4g}" for x in self.scale)
        if self.gains == "omega_zeta":
            return (
                f"per joint ω_n log-uniform in [{self.omega_n[0]:g}, {self.omega_n[1]:g}] rad/s,"
                f" ζ uniform in [{self.zeta[0]:g}, {self.zeta[1]:g}]"
                + (f" (K_P = b ω_n², K_D = 2ζ b ω_n{inertia})" if self.inertia else "")
            )
        return (
            "per joint K_P log-uniform in b_i·[ω_lo², ω_hi²], K_D log-uniform in "
            f"b_i·[2ζ_lo ω_lo, 2ζ_hi ω_hi], ω in [{self.omega_n[0]:g}, {self.omega_n[1]:g}] "
            f"rad/s, ζ in [{self.zeta[0]:g}, {self.zeta[1]:g}]{inertia}"
        )
