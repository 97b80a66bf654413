r"""The sampled inverse-dynamics loop: one joint, perfect model, torque held over T_s.

With a perfect model, inverse dynamics makes each joint the double integrator q̈ = y
(THEORY.md §3). The controller computes y = K_P (q_d − q_k) − K_D q̇_k from the state sampled
at the start of each control period T_s (for a step q̇_d = q̈_d = 0) and the plant holds it
over the whole period: exactly the lockstep exchange of ``sim_bridge`` and a controller.
With p = q − q_d and x = (p, q̇) the loop is x_{k+1} = A x_k, A = Φ − Γ K, K = (K_P, K_D),
Φ = [[1, T], [0, 1]] and Γ = (c T², T), where c depends on how the plant integrates:

- ``physics_dt=None``: the continuous double integrator under a zero-order hold (the exact
  ZOH discretisation), c = 1/2; between two samples q(t_k + τ) = q_k + q̇_k τ + y_k τ²/2 is a
  parabola, so the true peak may lie between samples;
- ``physics_dt=h``: the plant ``sim_bridge`` runs, m = T_s/h semi-implicit Euler sub-steps
  (v ← v + h y, then q ← q + h v, m times) with y held; summing them gives
  q_m = q + T v + T² y (m + 1)/(2m), so c = (m + 1)/(2m) = 1/2 + h/(2T). This is the exact
  discrete model of what PyBullet does for a decoupled joint (docs/plant.md checks one plant
  step against a semi-implicit Euler step of the Pinocchio model), and the one an experiment
  on ``sim_bridge`` should be compared with.

Characteristic polynomial of A: z² − tr(A) z + det(A) with
tr A = 2 − c K_P T² − K_D T and det A = 1 − K_D T + (1 − c) K_P T². The Jury conditions
(both roots strictly inside the unit circle) are, writing c T² = T²/2 + hT/2 (h = 0 for ZOH):

- 1 − tr + det = K_P T² > 0: always true;
- 1 + tr + det = 4 − 2 K_D T − K_P h T > 0  ⇔  T < 4 / (2 K_D + K_P h);
- det < 1  ⇔  T < h + 2 K_D / K_P;
- det > −1 ⇔  K_P T²/2 − (K_D + K_P h/2) T + 2 > 0, which fails between the roots of that
  quadratic when they are real (never before the first bound for h = 0).

For the exact ZOH and K_P = ω_n², K_D = 2ζω_n this gives T_s* = min(1/(ζω_n), 4ζ/ω_n): the
loop leaves the unit circle at z = −1 for ζ > 1/2 and with a complex pair for ζ < 1/2.

Numpy only; scalar gains (one joint). Times in s, K_P in 1/s², K_D in 1/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PERIOD_RTOL = 1e-9
"""Relative tolerance on T_s / h being a whole number of physics steps."""
SETTLE_MARGIN = 1e-3
"""The default duration lets the slowest mode decay to this fraction of the 2 % band."""
MAX_DEFAULT_PERIODS = 200_000
"""Cap on the number of control periods of the default duration."""


def _gains(kp: float, kd: float) -> tuple[float, float]:
    kp, kd = float(kp), float(kd)
    if not (math.isfinite(kp) and math.isfinite(kd)) or kp <= 0.0 or kd < 0.0:
        raise ValueError(f"need finite kp > 0 and kd >= 0, got kp={kp}, kd={kd}")
    return kp, kd


def _positive(value: float, name: str) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"'{name}' must be finite and > 0, got {value}")
    return value


def substeps(period: float, dt: float) -> int:
    """m = T_s / dt, the whole number of steps dt in one control period (ValueError if the
    ratio is not whole to :data:`PERIOD_RTOL`)."""
    period, dt = _positive(period, "period"), _positive(dt, "dt")
    m = round(period / dt)
    if m < 1 or abs(m * dt - period) > PERIOD_RTOL * period:
        raise ValueError(f"the period {period} s is not a whole number of steps of {dt} s")
    return m


def hold_coefficient(period: float, physics_dt: float | None = None) -> float:
    """c in Γ = (c T², T): 1/2 for the exact ZOH (``physics_dt=None``), (m + 1)/(2m) for m
    semi-implicit Euler sub-steps of ``physics_dt`` per period."""
    if physics_dt is None:
        _positive(period, "period")
        return 0.5
    m = substeps(period, physics_dt)
    return (m + 1) / (2 * m)


def sampled_loop_matrices(
    kp: float, kd: float, period: float, physics_dt: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""(Φ, Γ, A) of the sampled loop x_{k+1} = Φ x_k + Γ y_k, y_k = −K x_k, A = Φ − Γ K.

    x = (q − q_d, q̇) [rad, rad/s]; Φ = [[1, T], [0, 1]], Γ = (c T², T) (shape (2,)) with c
    from :func:`hold_coefficient`; K = (K_P, K_D).
    """
    kp, kd = _gains(kp, kd)
    c = hold_coefficient(period, physics_dt)
    T = float(period)
    phi = np.array([[1.0, T], [0.0, 1.0]])
    gamma = np.array([c * T * T, T])
    return phi, gamma, phi - np.outer(gamma, [kp, kd])


def sampled_spectral_radius(
    kp: float, kd: float, period: float, physics_dt: float | None = None
) -> float:
    """max |z| over the eigenvalues of A (:func:`sampled_loop_matrices`): < 1 ⇔ stable."""
    return float(
        np.max(np.abs(np.linalg.eigvals(sampled_loop_matrices(kp, kd, period, physics_dt)[2])))
    )


def sampled_stability_limit(kp: float, kd: float, physics_dt: float | None = None) -> float:
    r"""T_s* [s]: the loop is stable for every T_s < T_s* and not at T_s* (Jury conditions).

    T_s* = min(4/(2K_D + K_P h), h + 2K_D/K_P, T₁), T₁ the smaller root of
    K_P T²/2 − (K_D + K_P h/2) T + 2 when it is real (h = ``physics_dt``, 0 for the exact
    ZOH). With the exact ZOH, T_s* = min(2/K_D, 2K_D/K_P) = min(1/(ζω_n), 4ζ/ω_n); 0 for
    K_D = 0. With sub-steps the formula treats T_s as continuous; a real period is a whole
    number of steps h, so the longest usable one is the largest multiple of h below T_s*
    (and none when T_s* ≤ h).
    """
    kp, kd = _gains(kp, kd)
    h = 0.0 if physics_dt is None else _positive(physics_dt, "physics_dt")
    bounds = [4.0 / (2.0 * kd + kp * h) if (2.0 * kd + kp * h) > 0.0 else math.inf]
    bounds.append(h + 2.0 * kd / kp)
    b = kd + 0.5 * kp * h
    disc = b * b - 4.0 * kp
    if disc >= 0.0:
        bounds.append(4.0 / (b + math.sqrt(disc)))  # (b − √disc)/K_P, written without cancellation
    return float(min(bounds))


@dataclass(frozen=True)
class SampledResponse:
    """A step response of the sampled loop.

    ``t``, ``q``, ``dq``: every step of the output grid (the plant's physics steps, or the
    ``dt`` grid of the exact ZOH), from 0 to the end; ``t_samples``, ``q_samples``,
    ``dq_samples``: the states the controller samples, at k·T_s (every m-th grid point);
    ``y``: the held accelerations y_k [rad/s²], one per period (the last one unused).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    t_samples: np.ndarray
    q_samples: np.ndarray
    dq_samples: np.ndarray
    y: np.ndarray


def sampled_step_response(
    kp: float,
    kd: float,
    period: float,
    duration: float,
    physics_dt: float | None = 1e-3,
    dt: float | None = None,
    y0: float = 0.0,
    y1: float = 1.0,
) -> SampledResponse:
    r"""Step response from rest at y0 to the set-point y1 (step at t = 0, first sample at 0).

    Over period k the acceleration y_k = K_P (y1 − q_k) − K_D q̇_k is held; within it,
    at τ = j·dt:

    - ``physics_dt=h`` (the plant): dt = h and q = q_k + q̇_k τ + y_k τ(τ + h)/2,
      q̇ = q̇_k + y_k τ, i.e. exactly j semi-implicit Euler steps;
    - ``physics_dt=None`` (exact ZOH of the continuous plant): q = q_k + q̇_k τ + y_k τ²/2 on
      a grid of ``dt`` (default T_s/100).

    The grid spacing must divide ``period``; the record covers ⌈duration/T_s⌉ periods.
    """
    kp, kd = _gains(kp, kd)
    duration = _positive(duration, "duration")
    if physics_dt is not None:
        if dt is not None and dt != physics_dt:
            raise ValueError("with physics_dt the output grid is the physics steps: omit 'dt'")
        dt = physics_dt
    elif dt is None:
        dt = float(period) / 100.0
    m = substeps(period, dt)
    T = float(period)
    h = 0.0 if physics_dt is None else float(physics_dt)
    n_periods = max(1, math.ceil(duration / T - PERIOD_RTOL))
    _, _, a = sampled_loop_matrices(kp, kd, T, physics_dt)
    x = np.empty((n_periods + 1, 2))
    x[0] = (float(y0) - float(y1), 0.0)
    for k in range(n_periods):
        x[k + 1] = a @ x[k]
    y = -(kp * x[:, 0] + kd * x[:, 1])
    tau = np.arange(m) * dt
    p = x[:-1, 0:1] + x[:-1, 1:2] * tau + y[:-1, None] * (0.5 * tau * (tau + h))
    v = x[:-1, 1:2] + y[:-1, None] * tau
    t_samples = np.arange(n_periods + 1) * T
    t = (t_samples[:-1, None] + tau).reshape(-1)
    return SampledResponse(
        t=np.append(t, t_samples[-1]),
        q=np.append(p.reshape(-1), x[-1, 0]) + float(y1),
        dq=np.append(v.reshape(-1), x[-1, 1]),
        t_samples=t_samples,
        q_samples=x[:, 0] + float(y1),
        dq_samples=x[:, 1].copy(),
        y=y,
    )


def _settling(t: np.ndarray, err: np.ndarray, band: float) -> float:
    """Last instant |err| leaves the band (linear interpolation), NaN if still outside."""
    outside = np.abs(err) > band
    k = outside.size - 1 - int(np.argmax(outside[::-1]))
    if outside[-1]:
        return math.nan
    if not outside[k]:
        return 0.0
    edge = band if err[k] > 0 else -band
    frac = (edge - err[k]) / (err[k + 1] - err[k])
    return float(t[k] + frac * (t[k + 1] - t[k]))


def _default_duration(kp: float, kd: float, period: float, physics_dt: float | None) -> float:
    rho = sampled_spectral_radius(kp, kd, period, physics_dt)
    if not rho < 1.0:
        return 200.0 * period
    periods = math.ceil(math.log(SETTLE_MARGIN * 0.02) / math.log(max(rho, 1e-300))) + 10
    return min(max(periods, 20), MAX_DEFAULT_PERIODS) * period


def sampled_step_prediction(
    kp: float,
    kd: float,
    period: float,
    physics_dt: float | None = 1e-3,
    dt: float | None = None,
    duration: float | None = None,
) -> dict[str, float | bool]:
    r"""What the sampled loop predicts for a unit step (figures relative to the step size).

    Returns, times in s and percentages of the step:

    - ``period``, ``physics_dt`` (None for the exact ZOH), ``spectral_radius``, ``stable``
      (ρ < 1), ``stability_limit`` (:func:`sampled_stability_limit`);
    - ``overshoot_percent``: the peak of the plant's motion: on every physics step for the
      semi-implicit plant; for the exact ZOH the true continuous peak (the vertex of each
      period's parabola, q̇ = 0 at τ = −q̇_k/y_k, is included besides the ``dt`` grid);
    - ``overshoot_percent_sampled``: the peak of the samples at k·T_s only (what a record of
      the controller's state, one sample per period, can show);
    - ``settling_time_2``, ``settling_time_2_sampled``: last exit from the ±2 % band on the
      fine grid and on the samples (linear interpolation between points); NaN if the
      response has not settled by ``duration`` (default: until the slowest mode is below
      :data:`SETTLE_MARGIN` of the band, at most :data:`MAX_DEFAULT_PERIODS` periods).

    An unstable loop (ρ ≥ 1) gives NaN overshoot and settling times.
    """
    kp, kd = _gains(kp, kd)
    rho = sampled_spectral_radius(kp, kd, period, physics_dt)
    out: dict[str, float | bool] = {
        "period": float(period),
        "physics_dt": None if physics_dt is None else float(physics_dt),
        "spectral_radius": rho,
        "stable": bool(rho < 1.0),
        "stability_limit": sampled_stability_limit(kp, kd, physics_dt),
    }
    if not rho < 1.0:
        out.update(
            overshoot_percent=math.nan,
            overshoot_percent_sampled=math.nan,
            settling_time_2=math.nan,
            settling_time_2_sampled=math.nan,
        )
        return out
    if duration is None:
        duration = _default_duration(kp, kd, period, physics_dt)
    r = sampled_step_response(kp, kd, period, duration, physics_dt, dt, 0.0, 1.0)
    peak = float(np.max(r.q))
    if physics_dt is None:
        y, v, p = r.y[:-1], r.dq_samples[:-1], r.q_samples[:-1] - 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            tau = -v / y
            vertex = p - 0.5 * v * v / y
        inside = (y != 0.0) & (tau > 0.0) & (tau < float(period))
        if np.any(inside):
            peak = max(peak, 1.0 + float(np.max(vertex[inside])))
    out.update(
        overshoot_percent=100.0 * max(peak - 1.0, 0.0),
        overshoot_percent_sampled=100.0 * max(float(np.max(r.q_samples)) - 1.0, 0.0),
        settling_time_2=_settling(r.t, r.q - 1.0, 0.02),
        settling_time_2_sampled=_settling(r.t_samples, r.q_samples - 1.0, 0.02),
    )
    return out
