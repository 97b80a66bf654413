r"""Response metrics of sampled joint signals, and the second-order theory they are checked
against (shared THEORY.md §3–4). Arrays in, numbers out: numpy only, no ROS.

Units: time in seconds, joint positions in the joint's unit (rad, or m for a prismatic
joint), torques in N·m (N for a prismatic joint), percentages in %.

- :func:`step_metrics`, :func:`step_metrics_per_joint`: rise time, settling times,
  overshoot and steady-state error of a step response (:class:`StepMetrics`);
- :func:`tracking_error`: RMS and peak of e = q_d − q;
- :func:`torque_demand`: peak |τ|, peak |τ̇|, fraction of time at the torque limit;
- :func:`period_statistics`: timing of a periodic loop from its time stamps;
- :func:`torque_chatter_rms`: RMS of the sample-to-sample change of τ;
- :func:`mean_error`: mean of e = q_d − q over a window (the static offset under a disturbance);
- :func:`position_spread`: accuracy and repeatability of repeated final positions (ISO 9283);
- :func:`sinusoid_frequency`: ω of a reference q̄ + Δ sin(ωt + φ), from its q_d and q̈_d;
- :func:`second_order_step`, :func:`second_order_prediction`: the analytic answer for the
  nominal inverse-dynamics loop ë + K_D ė + K_P e = 0, where each joint follows
  G(s) = ω_n² / (s² + 2ζω_n s + ω_n²), ω_n = √K_P, ζ = K_D / (2√K_P) (the gains ↔ (ω_n, ζ)
  conversion is :mod:`joint_space_control.laws.second_order`).

Sampled step metrics are measured on the samples themselves with linear interpolation between
two samples to place a crossing instant; they therefore cannot see an excursion that lies
entirely between two samples, and a sampled peak is lower than the true one by up to
½·|ÿ(t_peak)|·(Δt/2)².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from joint_space_control.arrays import per_joint
from joint_space_control.laws.second_order import (  # noqa: F401  (re-exported)
    RISE_HIGH,
    RISE_LOW,
    second_order_parameters,
    second_order_prediction,
    second_order_step,
)

DEFAULT_FINAL_WINDOW = 0.1
"""Default length [s] of the window at the end of a record averaged into the final value."""


# --------------------------------------------------------------------------- validation


def _time(t: ArrayLike, name: str = "t") -> np.ndarray:
    """A 1-D, non-empty, finite, non-decreasing time vector (equal stamps are allowed)."""
    arr = np.asarray(t, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"'{name}' must be 1-D, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"'{name}' is empty")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"'{name}' contains NaN or infinite values")
    if np.any(np.diff(arr) < 0):
        raise ValueError(f"'{name}' must be non-decreasing (monotonic time)")
    return arr


def _samples(values: ArrayLike, n: int, name: str) -> np.ndarray:
    """Samples (n, n_joints), finite, returned as a C-contiguous (n_joints, n) array.

    A 1-D input is one joint. Joint-major layout makes the per-joint reductions run over
    contiguous memory (several times faster than reducing axis 0 of an (n, 7) array).
    """
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"'{name}' must be 1-D or 2-D (samples, joints), got shape {arr.shape}")
    if arr.shape[0] != n:
        raise ValueError(f"'{name}' has {arr.shape[0]} samples but the time vector has {n}")
    if arr.shape[1] == 0:
        raise ValueError(f"'{name}' has no joints")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"'{name}' contains NaN or infinite values")
    return np.ascontiguousarray(arr.T)


def _step_index(t: np.ndarray, t_step: float | None) -> tuple[int, float]:
    """Index of the last sample at or before the step instant, and that instant."""
    if t_step is None:
        t_step = float(t[0])
    t_step = float(t_step)
    if not math.isfinite(t_step) or t_step < t[0] or t_step > t[-1]:
        raise ValueError(f"'t_step' = {t_step} is outside the record [{t[0]}, {t[-1]}]")
    return int(np.searchsorted(t, t_step, side="right")) - 1, t_step


# --------------------------------------------------------------------------- step response


@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics of one joint (positions in the joint's unit, times in s).

    - ``initial``: y0, the last sample at or before the step instant;
    - ``final_target``: the reference end value if one was given, else ``final_value``;
    - ``final_value``: mean of the samples in the last ``final_window`` seconds;
    - ``steady_state_error``: final_target − final_value (signed);
    - ``rise_time``: time from 10 % to 90 % of the way from y0 to ``final_value`` [s]
      (NaN if 90 % is never reached, or if final_value = y0);
    - ``settling_time_2``, ``settling_time_5``: time after the step instant from which the
      response stays within ±2 % (±5 %) of |final_target − y0| around final_target [s]:
      the interpolated last exit from the band, clamped at 0 (0 only if the response is
      inside from the first sample after the step on); NaN if it is still outside the band
      at the last sample, or if final_target = y0;
    - ``overshoot_percent``: largest excursion beyond final_target in the direction of the
      step, in % of |final_target − y0| (0 if none; NaN if final_target = y0).
    """

    initial: float
    final_target: float
    final_value: float
    steady_state_error: float
    rise_time: float
    settling_time_2: float
    settling_time_5: float
    overshoot_percent: float

    @property
    def abs_steady_state_error(self) -> float:
        """|final_target − final_value|, in the joint's unit."""
        return abs(self.steady_state_error)


def _first_crossing(t: np.ndarray, s: np.ndarray, level: float) -> float:
    """First instant s reaches ``level`` (s rising), linearly interpolated; NaN if never."""
    reached = s >= level
    k = int(np.argmax(reached))
    if not reached[k]:
        return math.nan
    if k == 0:
        return float(t[0])
    frac = (level - s[k - 1]) / (s[k] - s[k - 1])
    return float(t[k - 1] + frac * (t[k] - t[k - 1]))


def _rise_time(t: np.ndarray, y: np.ndarray, y_final: float, t_step: float) -> float:
    span = y_final - y[0]
    if span == 0.0:
        return math.nan
    progress = (y - y[0]) / span  # 0 at y0, 1 at y_final, whatever the step's direction
    t_high = _first_crossing(t, progress, RISE_HIGH)
    if math.isnan(t_high):
        return math.nan
    t_low = _first_crossing(t, progress, RISE_LOW)  # reached no later than t_high
    return max(t_high, t_step) - max(t_low, t_step)


def _settling_time(
    t: np.ndarray, y: np.ndarray, target: float, band: float, t_step: float
) -> float:
    amplitude = abs(target - y[0])
    if amplitude == 0.0:
        return math.nan
    err = (y - target) / amplitude
    outside = np.abs(err) > band  # y0 itself is outside (|err| = 1): some k exists
    k = outside.size - 1 - int(np.argmax(outside[::-1]))  # last sample outside the band
    if k == outside.size - 1:
        return math.nan
    edge = band if err[k] > 0 else -band
    frac = (edge - err[k]) / (err[k + 1] - err[k])
    return max(float(t[k] + frac * (t[k + 1] - t[k])) - t_step, 0.0)


def _overshoot_percent(y: np.ndarray, target: float) -> float:
    span = target - y[0]
    if span == 0.0:
        return math.nan
    beyond = float(np.max((y - target) / span))  # > 0 past the target, in the step direction
    return 100.0 * beyond if beyond > 0.0 else 0.0


def _step_metrics(
    t: np.ndarray,
    y: np.ndarray,
    target: float | None,
    i0: int,
    t_step: float,
    final_window: float,
) -> StepMetrics:
    t, y = t[i0:], y[i0:]
    # averaged relative to y0: a signal that never moved gives exactly y0, i.e. no step
    final_value = float(y[0] + np.mean(y[t >= t[-1] - final_window] - y[0]))
    final_target = final_value if target is None else float(target)
    return StepMetrics(
        initial=float(y[0]),
        final_target=final_target,
        final_value=final_value,
        steady_state_error=final_target - final_value,
        rise_time=_rise_time(t, y, final_value, t_step),
        settling_time_2=_settling_time(t, y, final_target, 0.02, t_step),
        settling_time_5=_settling_time(t, y, final_target, 0.05, t_step),
        overshoot_percent=_overshoot_percent(y, final_target),
    )


def _check_window(final_window: float) -> float:
    final_window = float(final_window)
    if not final_window >= 0.0 or math.isinf(final_window):
        raise ValueError(f"'final_window' must be finite and >= 0 s, got {final_window}")
    return final_window


def step_metrics(
    t: ArrayLike,
    y: ArrayLike,
    target: float | None = None,
    t_step: float | None = None,
    final_window: float = DEFAULT_FINAL_WINDOW,
) -> StepMetrics:
    """Rise time, settling times, overshoot and steady-state error of one step response.

    Args:
        t: sample times [s], shape (N,), non-decreasing.
        y: response samples, shape (N,), in the joint's unit.
        target: the reference's end value; ``None`` uses the measured final value.
        t_step: step instant [s] (default ``t[0]``). y0 is the last sample at or before it,
            and only that sample and later ones are analysed; metrics are relative to y0, so
            the response need not start from 0 and may step in either direction.
        final_window: the final value is the mean of the samples in the last
            ``final_window`` seconds (at least the last sample).

    Crossing instants are linearly interpolated between samples. The rise time is
    t(90 %) − t(10 %) of the way from y0 to the final value, each instant the first one at
    or after ``t_step``. A settling time is the last instant the response leaves the band
    final_target ± p·|final_target − y0| (p = 0.02 or 0.05), minus ``t_step``; see
    :class:`StepMetrics` for the NaN cases.

    Raises:
        ValueError: on empty, mismatched, non-finite or non-monotonic input.
    """
    t = _time(t)
    if np.ndim(y) != 1:
        raise ValueError(f"'y' must be 1-D (use step_metrics_per_joint), got {np.shape(y)}")
    y = _samples(y, t.size, "y")[0]
    if target is not None:
        target = float(per_joint(target, 1, "target")[0])
    i0, t_step = _step_index(t, t_step)
    return _step_metrics(t, y, target, i0, t_step, _check_window(final_window))


def step_metrics_per_joint(
    t: ArrayLike,
    Y: ArrayLike,
    targets: ArrayLike | None = None,
    t_step: float | None = None,
    final_window: float = DEFAULT_FINAL_WINDOW,
) -> list[StepMetrics]:
    """:func:`step_metrics` of every column of Y, shape (N, n_joints), sharing ``t_step``.

    ``targets`` is ``None`` (final values), one value for every joint, or n_joints values.
    """
    t = _time(t)
    Y = _samples(Y, t.size, "Y")
    n = Y.shape[0]
    goals = [None] * n if targets is None else per_joint(targets, n, "targets").tolist()
    i0, t_step = _step_index(t, t_step)
    final_window = _check_window(final_window)
    return [_step_metrics(t, Y[j], goals[j], i0, t_step, final_window) for j in range(n)]


# --------------------------------------------------------------------------- tracking, torque


def tracking_error(
    t: ArrayLike,
    q: ArrayLike,
    q_des: ArrayLike,
    t_start: float | None = None,
    t_end: float | None = None,
) -> dict[str, np.ndarray]:
    r"""Tracking error e = q_d − q per joint over the samples with t_start ≤ t ≤ t_end.

    Returns ``{"rms": ..., "max_abs": ...}``, arrays of shape (n_joints,) in the joint's unit
    (a 1-D q is one joint):

    - ``rms`` = √( ∫ e² dt / (t_last − t_first) ), the integral by the trapezoidal rule on the
      actual sample times (the plain mean of e² if the window spans no time). Over whole
      periods of a sampled sinusoid A sin ωt this is A/√2 exactly.
    - ``max_abs`` = max |e| over the window's samples.
    """
    t = _time(t)
    q = _samples(q, t.size, "q")
    q_des = _samples(q_des, t.size, "q_des")
    if q.shape != q_des.shape:
        raise ValueError(f"'q' has shape {q.shape} but 'q_des' has {q_des.shape}")
    window = _window_slice(t, t_start, t_end)
    tw = t[window]
    e2 = (q_des[:, window] - q[:, window]) ** 2
    span = tw[-1] - tw[0]
    if span > 0.0:
        dt = np.diff(tw)
        weights = 0.5 * (np.append(dt, 0.0) + np.insert(dt, 0, 0.0))  # trapezoidal rule
        mean_square = e2 @ weights / span
    else:
        mean_square = np.mean(e2, axis=1)
    return {"rms": np.sqrt(mean_square), "max_abs": np.sqrt(np.max(e2, axis=1))}


def torque_demand(
    t: ArrayLike,
    tau: ArrayLike,
    limits: ArrayLike | None = None,
    saturation_tol: float = 1e-9,
) -> dict[str, np.ndarray]:
    r"""Peak torque, peak torque rate and time spent saturated, per joint.

    Args:
        t: sample times [s], shape (N,), non-decreasing.
        tau: torques [N·m], shape (N,) or (N, n_joints).
        limits: effort limits [N·m] (> 0), one for all joints or one per joint.
        saturation_tol: a sample is saturated when |τ| ≥ limit − saturation_tol [N·m].

    Returns arrays of shape (n_joints,):

    - ``peak_abs``: max |τ| [N·m];
    - ``peak_rate``: max |τ̇| [N·m/s], from finite differences (τ_{k+1} − τ_k)/(t_{k+1} − t_k)
      on the actual sample times. Repeated time stamps are skipped (no zero division): of
      samples sharing a stamp only the last one is used. NaN if the record spans no time.
    - ``saturated_fraction``: time-weighted fraction of the record at the limit, each sample
      holding until the next one (weight t_{k+1} − t_k; the last sample has none); the plain
      sample fraction if the record spans no time; NaN when no ``limits`` are given.
    """
    t = _time(t)
    tau = _samples(tau, t.size, "tau")
    n = tau.shape[0]
    if not float(saturation_tol) >= 0.0:
        raise ValueError(f"'saturation_tol' must be >= 0 N·m, got {saturation_tol}")
    dt = np.diff(t)
    if np.all(dt > 0.0):
        tk, tauk = t, tau
    else:
        last_of_stamp = np.append(dt > 0.0, True)
        tk, tauk = t[last_of_stamp], tau[:, last_of_stamp]
    if tk.size >= 2:
        peak_rate = np.max(np.abs(np.diff(tauk, axis=1) / np.diff(tk)), axis=1)
    else:
        peak_rate = np.full(n, math.nan)
    if limits is None:
        fraction = np.full(n, math.nan)
    else:
        lim = per_joint(limits, n, "limits")
        if np.any(lim <= 0.0):
            raise ValueError(f"'limits' must be > 0, got {lim.tolist()}")
        saturated = (np.abs(tau) >= (lim - float(saturation_tol))[:, None]).astype(float)
        total = t[-1] - t[0]
        if total > 0.0:
            fraction = saturated[:, :-1] @ dt / total
        else:
            fraction = np.mean(saturated, axis=1)
    return {
        "peak_abs": np.max(np.abs(tau), axis=1),
        "peak_rate": peak_rate,
        "saturated_fraction": fraction,
    }


def period_statistics(stamps: ArrayLike) -> dict[str, float]:
    r"""Timing of a periodic loop from its time stamps (periods Tₖ = stamp_{k+1} − stamp_k).

    Returns, in the unit of the stamps: ``mean``, ``std`` (population, ddof = 0), ``min``,
    ``p50`` (median, taken as the nominal period), ``p99`` (linear interpolation), ``max``,
    ``max_jitter`` = maxₖ |Tₖ − median|, and ``count``, the number of stamps (one more than
    the number of periods).

    Integer stamps (e.g. nanoseconds) are differenced as integers before conversion, so stamps
    of epoch size lose no resolution; float epoch seconds carry only ~0.2 µs of resolution.
    """
    arr = np.asarray(stamps)
    if arr.ndim != 1:
        raise ValueError(f"'stamps' must be 1-D, got shape {arr.shape}")
    if arr.size < 2:
        raise ValueError(f"'stamps' needs at least 2 stamps, got {arr.size}")
    if np.issubdtype(arr.dtype, np.integer):
        periods = np.diff(arr.astype(np.int64)).astype(float)
    else:
        periods = np.diff(_time(arr, "stamps"))
    if np.any(periods < 0):
        raise ValueError("'stamps' must be non-decreasing (monotonic time)")
    median = float(np.median(periods))
    return {
        "mean": float(np.mean(periods)),
        "std": float(np.std(periods)),
        "min": float(np.min(periods)),
        "p50": median,
        "p99": float(np.percentile(periods, 99.0)),
        "max": float(np.max(periods)),
        "max_jitter": float(np.max(np.abs(periods - median))),
        "count": int(arr.size),
    }


# --------------------------------------------------------------------------- windows, chatter


def _window_slice(t: np.ndarray, t_start: float | None, t_end: float | None) -> slice:
    lo = -math.inf if t_start is None else float(t_start)
    hi = math.inf if t_end is None else float(t_end)
    if math.isnan(lo) or math.isnan(hi) or lo > hi:
        raise ValueError(f"bad time window [{t_start}, {t_end}]")
    first = int(np.searchsorted(t, lo, side="left"))
    stop = int(np.searchsorted(t, hi, side="right"))
    if stop <= first:
        raise ValueError(f"no sample in the time window [{t_start}, {t_end}]")
    return slice(first, stop)


def torque_chatter_rms(
    t: ArrayLike, tau: ArrayLike, t_start: float | None = None, t_end: float | None = None
) -> np.ndarray:
    r"""Torque chatter: RMS of the sample-to-sample change Δτ_k = τ_{k+1} − τ_k [N·m].

    Over the samples with t_start ≤ t ≤ t_end (both samples of a difference inside), per
    joint, shape (n_joints,): √(mean_k Δτ_k²); NaN with fewer than 2 samples. Samples
    sharing a stamp count once (the last one). It is a property of the sampled command:
    a smooth torque contributes |τ̇|·T_s (T_s the sample period), an alternating component
    ±a contributes 2a; so compare runs at the same control rate. Measurement noise of σ on q
    through K_P gives about √2·K_P·σ (white noise: consecutive samples independent).
    """
    t = _time(t)
    tau = _samples(tau, t.size, "tau")
    window = _window_slice(t, t_start, t_end)
    tw, tauw = t[window], tau[:, window]
    last_of_stamp = np.append(np.diff(tw) > 0.0, True)
    tauw = tauw[:, last_of_stamp]
    if tauw.shape[1] < 2:
        return np.full(tau.shape[0], math.nan)
    return np.sqrt(np.mean(np.diff(tauw, axis=1) ** 2, axis=1))


def mean_error(
    t: ArrayLike,
    q: ArrayLike,
    q_des: ArrayLike,
    t_start: float | None = None,
    t_end: float | None = None,
) -> np.ndarray:
    r"""Mean of e = q_d − q per joint over the samples with t_start ≤ t ≤ t_end [joint unit].

    The plain mean of the samples (a controller's state comes at a fixed period). Over the
    last part of a run that has come to rest it is the static offset, e.g. under a constant
    disturbance (PD + g: K_P e = Jᵀh_e), averaged over noise and any residual hunting.
    """
    t = _time(t)
    q = _samples(q, t.size, "q")
    q_des = _samples(q_des, t.size, "q_des")
    if q.shape != q_des.shape:
        raise ValueError(f"'q' has shape {q.shape} but 'q_des' has {q_des.shape}")
    window = _window_slice(t, t_start, t_end)
    return np.mean(q_des[:, window] - q[:, window], axis=1)


def position_spread(finals: ArrayLike, target: ArrayLike) -> dict[str, np.ndarray | float]:
    r"""Accuracy and repeatability of N repeated final positions, in the spirit of ISO 9283.

    ``finals`` (N_runs, n) are the positions reached by N attempts at the same ``target``
    (n,) (joint positions, or any coordinates, e.g. Cartesian ones); N ≥ 2. With the
    barycentre x̄ = mean of the runs and l_i = ‖x_i − x̄‖:

    - ``mean`` (n,): x̄;
    - ``offset`` (n,): x̄ − target, the accuracy as a vector (signed, per coordinate);
    - ``accuracy``: ‖x̄ − target‖ (ISO 9283 AP);
    - ``repeatability``: l̄ + 3 S_l, S_l the sample standard deviation (ddof = 1) of the l_i
      (ISO 9283 RP, the radius of a sphere around x̄ holding the runs);
    - ``max_distance``: max l_i, the radius around x̄ holding every run;
    - ``three_sigma`` (n,): 3 × the sample standard deviation (ddof = 1) of each coordinate.
    """
    x = np.asarray(finals, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    target = np.asarray(target, dtype=float).reshape(-1)
    if x.ndim != 2 or x.shape[0] < 2:
        raise ValueError(f"'finals' must be (N_runs >= 2, n), got shape {x.shape}")
    if target.size != x.shape[1]:
        raise ValueError(f"'target' has {target.size} values for {x.shape[1]} coordinates")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(target))):
        raise ValueError("'finals' and 'target' must be finite")
    mean = np.mean(x, axis=0)
    dist = np.linalg.norm(x - mean, axis=1)
    return {
        "runs": int(x.shape[0]),
        "mean": mean,
        "offset": mean - target,
        "accuracy": float(np.linalg.norm(mean - target)),
        "repeatability": float(np.mean(dist) + 3.0 * np.std(dist, ddof=1)),
        "max_distance": float(np.max(dist)),
        "three_sigma": 3.0 * np.std(x, axis=0, ddof=1),
    }


SINUSOID_RTOL = 1e-4
"""Relative RMS residual under which q̈_d = −ω²(q_d − q̄) holds: the reference is a sinusoid."""


def sinusoid_frequency(
    q_des: ArrayLike, ddq_des: ArrayLike, rtol: float = SINUSOID_RTOL
) -> np.ndarray:
    r"""ω [rad/s] of each joint whose reference is q̄ + Δ sin(ωt + φ), else NaN.

    A sinusoid satisfies q̈_d = −ω² (q_d − q̄): the least-squares line of q̈_d against q_d
    has slope −ω² and (relative to the RMS of q̈_d) a residual below ``rtol``. A joint whose
    q_d does not move, or whose fit leaves more, or gives a slope ≥ 0, gets NaN. Needs only
    the samples (not the time stamps); shapes (N,) or (N, n_joints).
    """
    q_des = np.asarray(q_des, dtype=float)
    ddq_des = np.asarray(ddq_des, dtype=float)
    if q_des.ndim == 1:
        q_des, ddq_des = q_des[:, None], ddq_des[:, None]
    if q_des.shape != ddq_des.shape or q_des.ndim != 2:
        raise ValueError(f"'q_des' {q_des.shape} and 'ddq_des' {ddq_des.shape} differ")
    out = np.full(q_des.shape[1], math.nan)
    if q_des.shape[0] < 3:
        return out
    x = q_des - np.mean(q_des, axis=0)
    a = ddq_des - np.mean(ddq_des, axis=0)
    for j in range(q_des.shape[1]):
        sxx = float(x[:, j] @ x[:, j])
        saa = float(a[:, j] @ a[:, j])
        if sxx <= 0.0 or saa <= 0.0:
            continue
        slope = float(x[:, j] @ a[:, j]) / sxx
        residual = a[:, j] - slope * x[:, j]
        if slope < 0.0 and float(residual @ residual) <= (rtol**2) * saa:
            out[j] = math.sqrt(-slope)
    return out
