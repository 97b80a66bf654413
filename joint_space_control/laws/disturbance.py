r"""Where the regulators come to rest under a constant disturbance or Coulomb friction.

The plant with an external wrench and friction (THEORY.md §1):

    B(q) q̈ + C(q, q̇) q̇ + F q̇ + f_c + g(q) = τ + τ_ext,    τ_ext = J(q)ᵀ w = −J(q)ᵀ h_e

w is the wrench the environment applies to the robot (h_e = −w the one the robot applies to
the environment, the theory's sign) and τ_ext its generalized torque; f_c the Coulomb
friction, |f_c,i| ≤ F_c,i at rest. The functions take τ_ext itself (evaluated by the caller,
e.g. with Pinocchio's J at the rest configuration), so they need no robot model. e = q_d − q
[rad], torques in N·m, K_P in N·m/rad for PD + g and 1/s² for inverse dynamics.

At rest (q̇ = q̈ = 0, constant q_d):

- PD + g, τ = ĝ(q) + K_P e: K_P e = −τ_ext + (g − ĝ)(q), i.e. K_P e = Jᵀ h_e with an exact
  gravity model;
- inverse dynamics, τ = B̂(q)(K_P e) + n̂(q, 0): B̂ K_P e = −τ_ext + (g − ĝ)(q), i.e.
  K_P e = B̂⁻¹ Jᵀ h_e with an exact gravity model (the offset is shaped by the model's inertia:
  a light link is pushed further than under PD + g with the same K_P numbers in N·m/rad);
- PID: e = 0 (the integral takes up τ_ext) whenever it comes to rest;
- PD + g with Coulomb friction and no disturbance: the joint can rest wherever friction holds
  the spring, |K_P,i e_i| ≤ F_c,i (F_s,i with stiction F_s ≥ F_c): the dead band.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _vector(x: ArrayLike, name: str) -> np.ndarray:
    x = np.atleast_1d(np.asarray(x, dtype=float))
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise ValueError(f"'{name}' must be a finite vector, got shape {x.shape}")
    return x


def _kp(kp: ArrayLike, n: int) -> np.ndarray:
    kp = _vector(kp, "kp")
    if kp.size == 1:
        kp = np.full(n, kp[0])
    if kp.size != n or np.any(kp <= 0.0):
        raise ValueError(f"'kp' needs 1 or {n} values > 0, got {kp.tolist()}")
    return kp


def _rhs(tau_ext: ArrayLike, gravity_error: ArrayLike | None) -> np.ndarray:
    rhs = -_vector(tau_ext, "tau_ext")
    if gravity_error is not None:
        g = _vector(gravity_error, "gravity_error")
        if g.size != rhs.size:
            raise ValueError(f"'gravity_error' has {g.size} values for {rhs.size} joints")
        rhs = rhs + g
    return rhs


def pd_gravity_static_offset(
    kp: ArrayLike, tau_ext: ArrayLike, gravity_error: ArrayLike | None = None
) -> np.ndarray:
    r"""e = q_d − q [rad] at rest under PD + g: K_P e = −τ_ext + (g − ĝ).

    ``kp`` [N·m/rad]: the diagonal of K_P (one value for all joints, or one per joint);
    ``tau_ext`` [N·m]: Jᵀ w, the generalized torque of the wrench w applied to the robot
    (= −Jᵀ h_e); ``gravity_error`` [N·m]: g(q) − ĝ(q) at the rest position (default 0).
    """
    rhs = _rhs(tau_ext, gravity_error)
    return rhs / _kp(kp, rhs.size)


def inverse_dynamics_static_offset(
    kp: ArrayLike,
    inertia_model: ArrayLike,
    tau_ext: ArrayLike,
    gravity_error: ArrayLike | None = None,
) -> np.ndarray:
    r"""e = q_d − q [rad] at rest under inverse dynamics: B̂ K_P e = −τ_ext + (g − ĝ).

    ``kp`` [1/s²]: the diagonal of K_P; ``inertia_model`` B̂(q) [kg·m²], (n, n) symmetric
    positive definite, at the rest position (≈ q_d for a small offset); ``tau_ext`` and
    ``gravity_error`` as in :func:`pd_gravity_static_offset`. So K_P e = B̂⁻¹ Jᵀ h_e with an
    exact gravity model.
    """
    rhs = _rhs(tau_ext, gravity_error)
    b = np.atleast_2d(np.asarray(inertia_model, dtype=float))
    if b.shape != (rhs.size, rhs.size) or not np.all(np.isfinite(b)):
        raise ValueError(f"'inertia_model' must be finite ({rhs.size}, {rhs.size}), got {b.shape}")
    return np.linalg.solve(b, rhs) / _kp(kp, rhs.size)


def coulomb_dead_band(
    kp: ArrayLike, coulomb: ArrayLike, stiction: ArrayLike | None = None
) -> np.ndarray:
    r"""Half-width [rad] of the band of rest positions of PD + g with Coulomb friction:
    |e_i| ≤ max(F_c,i, F_s,i) / K_P,i.

    ``kp`` [N·m/rad] > 0, ``coulomb`` F_c [N·m] ≥ 0 and ``stiction`` F_s [N·m] ≥ 0 (default
    none), one value or one per joint (broadcast). At rest the friction torque balances the
    spring, f_i = K_P,i e_i, and friction can hold up to F_s,i (F_c,i without stiction), so
    every e in the band is a rest position and none outside it is. Where in the band the joint
    stops depends on how it arrives (e.g. from rest on a step: within the band, on the side
    it came from unless it overshoots).
    """
    kp = _vector(kp, "kp")
    fc = _vector(coulomb, "coulomb")
    fs = fc if stiction is None else _vector(stiction, "stiction")
    if np.any(kp <= 0.0) or np.any(fc < 0.0) or np.any(fs < 0.0):
        raise ValueError("need kp > 0, coulomb >= 0 and stiction >= 0")
    return np.maximum(fc, fs) / kp
