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

A transport delay δ (the command computed at t_k reaches the plant at t_k + δ, as in
realtime) is an option of every function: :func:`delayed_loop_matrix`.

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


def _delay_split(period: float, delay: float) -> tuple[int, float]:
    """δ = d·T + r, 0 ≤ r < T: (d, r)."""
    delay = float(delay)
    if not (math.isfinite(delay) and delay >= 0.0):
        raise ValueError(f"'delay' must be finite and >= 0 s, got {delay}")
    d = math.floor(delay / period * (1.0 + 1e-12))
    return d, max(delay - d * period, 0.0)


def _advance(p, v, u, s: float, h: float):
    """State after a time s with input u held: exact for h = 0, s/h semi-implicit Euler steps
    of h otherwise (p + v s + u s(s + h)/2, v + u s; any arrays broadcasting)."""
    return p + v * s + u * (0.5 * s * (s + h)), v + u * s


def _delayed_map(kp: float, kd: float, T: float, h: float, delay: float) -> np.ndarray:
    """The one-period map of z = (p, q̇, y_{k−1}, …, y_{k−d−1}) (see :func:`delayed_loop_matrix`),
    without the checks on whole physics steps (the stability search varies T continuously)."""
    d, r = _delay_split(T, delay)
    n = 3 + d
    out = np.empty((n, n))
    for i, z in enumerate(np.eye(n)):
        y = -(kp * z[0] + kd * z[1])
        new = y if d == 0 else z[1 + d]  # y_{k−d}
        old = z[2 + d]  # y_{k−d−1}
        p, v = _advance(z[0], z[1], old, r, h)
        p, v = _advance(p, v, new, T - r, h)
        out[:, i] = np.concatenate(([p, v, y], z[2 : 2 + d]))
    return out


def delayed_loop_matrix(
    kp: float, kd: float, period: float, physics_dt: float | None = None, delay: float = 0.0
) -> np.ndarray:
    r"""One-period map z_{k+1} = M z_k of the sampled loop with a transport delay δ [s].

    The y_k computed from the sample at t_k reaches the plant at t_k + δ, δ = d·T_s + r,
    0 ≤ r < T_s: over [t_k, t_k + r) the plant holds y_{k−d−1}, over [t_k + r, t_{k+1}) it
    holds y_{k−d}. z = (q − q_d, q̇, y_{k−1}, …, y_{k−d−1}), size 3 + d; the inputs before
    the first sample are 0 (at rest). δ = 0 gives the 2×2 A of
    :func:`sampled_loop_matrices` in the top-left block and zeros elsewhere (an extra
    eigenvalue 0). With ``physics_dt`` r must be a whole number of physics steps (the
    plant applies a new command at a step boundary).
    """
    kp, kd = _gains(kp, kd)
    T = _positive(period, "period")
    h = 0.0
    if physics_dt is not None:
        substeps(T, physics_dt)
        h = float(physics_dt)
        _, r = _delay_split(T, delay)
        if r > PERIOD_RTOL * T:
            substeps(r, h)
    return _delayed_map(kp, kd, T, h, delay)


def sampled_spectral_radius(
    kp: float, kd: float, period: float, physics_dt: float | None = None, delay: float = 0.0
) -> float:
    """max |z| over the eigenvalues of the loop's one-period map (:func:`sampled_loop_matrices`,
    or :func:`delayed_loop_matrix` with a ``delay`` [s]): < 1 ⇔ stable."""
    if delay:
        m = delayed_loop_matrix(kp, kd, period, physics_dt, delay)
    else:
        m = sampled_loop_matrices(kp, kd, period, physics_dt)[2]
    return float(np.max(np.abs(np.linalg.eigvals(m))))


DELAY_SCAN_POINTS = 4000
"""Periods tried, evenly up to 1.5 × the undelayed limit, to bracket the delayed limit."""
MAX_DELAY_PERIODS = 50
"""The delayed limit is searched among periods T_s ≥ δ / MAX_DELAY_PERIODS."""


def sampled_stability_limit(
    kp: float, kd: float, physics_dt: float | None = None, delay: float = 0.0
) -> float:
    r"""T_s* [s]: the loop is stable for every T_s < T_s* and not at T_s*.

    Without delay, from the Jury conditions: T_s* = min(4/(2K_D + K_P h), h + 2K_D/K_P, T₁),
    T₁ the smaller root of K_P T²/2 − (K_D + K_P h/2) T + 2 when it is real
    (h = ``physics_dt``, 0 for the exact ZOH). With the exact ZOH,
    T_s* = min(2/K_D, 2K_D/K_P) = min(1/(ζω_n), 4ζ/ω_n); 0 for K_D = 0. With sub-steps the
    formula treats T_s as continuous; a real period is a whole number of steps h, so the
    longest usable one is the largest multiple of h below T_s* (none when T_s* ≤ h).

    With a transport ``delay`` δ > 0 [s] (:func:`delayed_loop_matrix`, T_s continuous as
    above): the first T_s at which the spectral radius reaches 1 among
    :data:`DELAY_SCAN_POINTS` periods evenly spaced from max(δ/:data:`MAX_DELAY_PERIODS`,
    the spacing) to 1.5 × the undelayed limit, refined by bisection to a relative 1e-12 (a
    stable or unstable interval narrower than the scan spacing could be missed). NaN if the
    shortest period tried is already unstable (the delay alone destabilises the loop) or
    none is. A delay short against T_s can raise the limit (for ζ = 0.7, ω_n = 20 the exact
    ZOH limit goes from 71.4 ms to 77.6 ms with δ = 2 ms): the late part of the period
    still holds the previous input, which softens the alternation at z = −1.
    """
    kp, kd = _gains(kp, kd)
    h = 0.0 if physics_dt is None else _positive(physics_dt, "physics_dt")
    bounds = [4.0 / (2.0 * kd + kp * h) if (2.0 * kd + kp * h) > 0.0 else math.inf]
    bounds.append(h + 2.0 * kd / kp)
    b = kd + 0.5 * kp * h
    disc = b * b - 4.0 * kp
    if disc >= 0.0:
        bounds.append(4.0 / (b + math.sqrt(disc)))  # (b − √disc)/K_P, written without cancellation
    undelayed = float(min(bounds))
    if not delay:
        return undelayed
    _delay_split(1.0, delay)  # checks it

    def unstable(T: float) -> bool:
        m = _delayed_map(kp, kd, T, h, delay)
        return bool(np.max(np.abs(np.linalg.eigvals(m))) >= 1.0)

    top = 1.5 * (undelayed if undelayed > 0.0 else 4.0 / max(kd, math.sqrt(kp)))
    shortest = max(top / DELAY_SCAN_POINTS, delay / MAX_DELAY_PERIODS)
    grid = np.linspace(shortest, max(top, 2.0 * shortest), DELAY_SCAN_POINTS)
    if unstable(float(grid[0])):
        return math.nan
    lo = float(grid[0])
    for T in grid[1:]:
        if unstable(float(T)):
            hi = float(T)
            break
        lo = float(T)
    else:
        return math.nan
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            hi = mid
        else:
            lo = mid
    return hi


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
    delay: float = 0.0,
) -> SampledResponse:
    r"""Step response from rest at y0 to the set-point y1 (step at t = 0, first sample at 0).

    Over period k the acceleration y_k = K_P (y1 − q_k) − K_D q̇_k is held; within it,
    at τ = j·dt:

    - ``physics_dt=h`` (the plant): dt = h and q = q_k + q̇_k τ + y_k τ(τ + h)/2,
      q̇ = q̇_k + y_k τ, i.e. exactly j semi-implicit Euler steps;
    - ``physics_dt=None`` (exact ZOH of the continuous plant): q = q_k + q̇_k τ + y_k τ²/2 on
      a grid of ``dt`` (default T_s/100).

    With a transport ``delay`` δ [s] the input changes within a period as in
    :func:`delayed_loop_matrix` (δ a whole number of grid steps past a whole number of
    periods). The grid spacing must divide ``period``; the record covers ⌈duration/T_s⌉
    periods.
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
    d, r = _delay_split(T, delay)
    j_r = 0 if r <= PERIOD_RTOL * T else substeps(r, dt)  # grid steps before the change
    a = delayed_loop_matrix(kp, kd, T, physics_dt, delay)
    z = np.zeros((n_periods + 1, a.shape[0]))
    z[0, 0] = float(y0) - float(y1)
    for k in range(n_periods):
        z[k + 1] = a @ z[k]
    x = z[:, :2]
    y = -(kp * x[:, 0] + kd * x[:, 1])
    new = (y if d == 0 else z[:, 1 + d])[:-1, None]  # held from r to T
    old = z[:-1, 2 + d, None]  # held from 0 to r
    tau = np.arange(m) * dt
    first = tau < (j_r - 0.5) * dt
    pr, vr = _advance(x[:-1, 0:1], x[:-1, 1:2], old, j_r * dt, h)
    p0, v0 = _advance(x[:-1, 0:1], x[:-1, 1:2], old, tau, h)
    p1, v1 = _advance(pr, vr, new, tau - j_r * dt, h)
    p = np.where(first, p0, p1)
    v = np.where(first, v0, v1)
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


def _default_duration(
    kp: float, kd: float, period: float, physics_dt: float | None, delay: float
) -> float:
    rho = sampled_spectral_radius(kp, kd, period, physics_dt, delay)
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
    delay: float = 0.0,
) -> dict[str, float | bool]:
    r"""What the sampled loop predicts for a unit step (figures relative to the step size).

    Returns, times in s and percentages of the step:

    - ``period``, ``physics_dt`` (None for the exact ZOH), ``delay``, ``spectral_radius``,
      ``stable`` (ρ < 1), ``stability_limit`` (:func:`sampled_stability_limit`, same delay);
    - ``overshoot_percent``: the peak of the plant's motion: on every physics step for the
      semi-implicit plant; for the exact ZOH the true continuous peak (the input is constant
      between two points of the ``dt`` grid, so the vertex of each piece of parabola, where
      q̇ = 0, is included besides the grid points);
    - ``overshoot_percent_sampled``: the peak of the samples at k·T_s only (what a record of
      the controller's state, one sample per period, can show);
    - ``settling_time_2``, ``settling_time_2_sampled``: last exit from the ±2 % band on the
      fine grid and on the samples (linear interpolation between points); NaN if the
      response has not settled by ``duration`` (default: until the slowest mode is below
      :data:`SETTLE_MARGIN` of the band, at most :data:`MAX_DEFAULT_PERIODS` periods).

    An unstable loop (ρ ≥ 1) gives NaN overshoot and settling times.
    """
    kp, kd = _gains(kp, kd)
    rho = sampled_spectral_radius(kp, kd, period, physics_dt, delay)
    out: dict[str, float | bool] = {
        "period": float(period),
        "physics_dt": None if physics_dt is None else float(physics_dt),
        "delay": float(delay),
        "spectral_radius": rho,
        "stable": bool(rho < 1.0),
        "stability_limit": sampled_stability_limit(kp, kd, physics_dt, delay),
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
        duration = _default_duration(kp, kd, period, physics_dt, delay)
    r = sampled_step_response(kp, kd, period, duration, physics_dt, dt, 0.0, 1.0, delay)
    peak = float(np.max(r.q))
    if physics_dt is None:
        step = np.diff(r.t)
        u = np.diff(r.dq) / step  # the input held over each grid interval
        v, p = r.dq[:-1], r.q[:-1] - 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            tau = -v / u
            vertex = p - 0.5 * v * v / u
        inside = (u != 0.0) & (tau > 0.0) & (tau < step)
        if np.any(inside):
            peak = max(peak, 1.0 + float(np.max(vertex[inside])))
    out.update(
        overshoot_percent=100.0 * max(peak - 1.0, 0.0),
        overshoot_percent_sampled=100.0 * max(float(np.max(r.q_samples)) - 1.0, 0.0),
        settling_time_2=_settling(r.t, r.q - 1.0, 0.02),
        settling_time_2_sampled=_settling(r.t_samples, r.q_samples - 1.0, 0.02),
    )
    return out
