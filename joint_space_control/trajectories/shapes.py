r"""Reference shapes for the ``trajectory_generator`` node (pure numpy, no ROS).

Every function returns a :class:`~joint_space_control.trajectories.reference.Trajectory`
with times relative to its start (``start`` = 0: the publisher stamps the real start) and
(m, n) arrays for n joints, or raises ``ValueError`` with a reason. Per-joint arguments take
one value per joint or one value for all; ``n`` (the number of joints) is then checked, or
taken from the longest argument when not given.

- :func:`step`: one point at time 0, a set-point: q_d jumps to it, q̇_d = q̈_d = 0.
- :func:`sinusoid`: q_d(t) = q̄ + Δ sin(ωt + φ) (THEORY.md §5, experiment 4), sampled every
  ``sample_period`` h with the exact q, q̇, q̈ at every sample, so that the controllers'
  quintic Hermite interpolation between samples is exact to Δω⁶h⁶/46080 in q, Δω⁶h⁵/13400
  in q̇ and Δω⁶h⁴/1920 in q̈ (the Hermite remainder f⁽⁶⁾(ξ)((t − a)(t − b))³/6! and its
  derivatives), e.g. 1.3e-12·Δ rad, 4.6e-10·Δ rad/s, 3.2e-7·Δ rad/s² at ω = 2π rad/s,
  h = 10 ms.
  Its start is generally *not* at rest: q̇_d(0) = Δω cos φ and q̈_d(0) = −Δω² sin φ, so the
  controller's reference jumps in velocity (and acceleration) at the start, from whatever it
  was tracking, and in position by q̄ + Δ sin φ − q_tracked. That is the theory's
  experiment-4 setting (φ = 0: starts at q̄ with q̇_d = Δω) and is deliberately left
  visible. φ = ±π/2 starts at rest at q̄ ± Δ (q̈_d(0) = ∓Δω² still jumps). Likewise, after
  ``duration`` the controller holds the last sample with q̇_d = q̈_d = 0, a jump unless the
  sinusoid ends at an extremum (ω·duration + φ = π/2 + kπ).
- :func:`quintic`: rest-to-rest point-to-point move, the minimum-jerk profile
  q_0 + (q_1 − q_0)(10x³ − 15x⁴ + 6x⁵), x = t/T, given as its two end points with zero
  velocity and acceleration (a quintic Hermite segment *is* that polynomial). Without a
  start it is one point at T with zero velocity and acceleration: the controller moves from
  the sample it tracks (the same profile when that sample is at rest), without any jump.
- :func:`waypoints`: the given points; without velocities the controllers interpolate them
  with a C² spline that comes to rest at the last point (see ``reference.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from joint_space_control.arrays import per_joint
from joint_space_control.trajectories.reference import Trajectory

#: Default sampling of the sinusoid [s].
DEFAULT_SAMPLE_PERIOD = 0.01
#: Most points in one trajectory: a point is 3n doubles plus ~32 bytes in the message, so this
#: keeps a 7-joint reference under ~4 MB (200 s of sinusoid at the default sampling).
MAX_POINTS = 20_001

Values = float | Sequence[float] | np.ndarray


def _size(value: Values, name: str) -> int:
    try:
        size = np.asarray(value, dtype=float).size
    except (TypeError, ValueError) as err:
        raise ValueError(f"'{name}' must be numbers, got {value!r}") from err
    if size == 0:
        raise ValueError(f"'{name}' is empty")
    return size


def _joints(n: int | None, **values: Values) -> int:
    """The number of joints: ``n`` when given, else the longest per-joint argument."""
    sizes = {name: _size(value, name) for name, value in values.items()}
    if n is None:
        n = max(sizes.values())
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"the number of joints must be an integer >= 1, got {n!r}")
    for name, size in sizes.items():
        if size not in (1, n):
            raise ValueError(f"'{name}' needs 1 or {n} values (one per joint), got {size}")
    return n


def _positive(value: float, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise ValueError(f"'{name}' must be a number, got {value!r}")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"'{name}' must be finite and > 0, got {value!r}")
    return float(value)


def step(target: Values, n: int | None = None) -> Trajectory:
    """A set-point: one point at time 0 (positions only)."""
    n = _joints(n, target=target)
    return Trajectory.build(0.0, [0.0], per_joint(target, n, "target")[None, :])


def sample_times(duration: float, sample_period: float) -> np.ndarray:
    """0, h, 2h, …, duration: the last interval is between 1e-6 h (merged) and ~h long."""
    duration = _positive(duration, "duration")
    sample_period = _positive(sample_period, "sample_period")
    intervals = max(1, math.ceil(duration / sample_period - 1e-6))
    if intervals + 1 > MAX_POINTS:
        raise ValueError(
            f"{intervals + 1} samples (duration {duration} s every {sample_period} s); at most "
            f"{MAX_POINTS}: increase 'sample_period' or shorten 'duration'"
        )
    return np.append(np.arange(intervals) * sample_period, duration)


def sinusoid(
    center: Values,
    amplitude: Values,
    omega: Values,
    phase: Values,
    duration: float,
    sample_period: float = DEFAULT_SAMPLE_PERIOD,
    n: int | None = None,
) -> Trajectory:
    """q_d(t) = q̄ + Δ sin(ωt + φ) for 0 ≤ t ≤ ``duration`` [s], per joint.

    ``center`` q̄ [rad], ``amplitude`` Δ [rad], ``omega`` ω [rad/s] (≥ 0), ``phase`` φ [rad]:
    one value per joint or one for all. Sampled every ``sample_period`` [s] with exact
    q, q̇ = Δω cos(ωt + φ), q̈ = −Δω² sin(ωt + φ). Starts with q̇_d(0) = Δω cos φ, in
    general not at rest (module docstring).
    """
    n = _joints(n, center=center, amplitude=amplitude, omega=omega, phase=phase)
    q_bar = per_joint(center, n, "center")
    delta = per_joint(amplitude, n, "amplitude")
    w = per_joint(omega, n, "omega")
    phi = per_joint(phase, n, "phase")
    if np.any(w < 0):
        raise ValueError(f"'omega' must be >= 0 [rad/s], got {w.tolist()}")
    t = sample_times(duration, sample_period)
    angle = w[None, :] * t[:, None] + phi[None, :]
    return Trajectory.build(
        0.0,
        t,
        q_bar + delta * np.sin(angle),
        delta * w * np.cos(angle),
        -delta * w**2 * np.sin(angle),
    )


def quintic(
    start: Values | None, goal: Values, duration: float, n: int | None = None
) -> Trajectory:
    """Rest-to-rest minimum-jerk move from ``start`` to ``goal`` [rad] in ``duration`` [s].

    Two points (0 and ``duration``) with zero velocities and accelerations; with ``start``
    None, only the goal at ``duration``: the controller starts from the sample it tracks.
    """
    duration = _positive(duration, "duration")
    if start is None:
        n = _joints(n, goal=goal)
        points = per_joint(goal, n, "goal")[None, :]
        times = [duration]
    else:
        n = _joints(n, start=start, goal=goal)
        points = np.vstack((per_joint(start, n, "start"), per_joint(goal, n, "goal")))
        times = [0.0, duration]
    zeros = np.zeros_like(points)
    return Trajectory.build(0.0, times, points, zeros, zeros)


def waypoints(
    positions: Sequence[Sequence[float]] | np.ndarray,
    times: Sequence[float] | np.ndarray,
    velocities: Sequence[Sequence[float]] | np.ndarray | None = None,
    n: int | None = None,
) -> Trajectory:
    """Points ``positions`` (m × n) [rad] at ``times`` [s] (≥ 0, strictly increasing),
    optionally with ``velocities`` (m × n) [rad/s]; no accelerations (the controllers make
    the curve C², see ``reference.py``)."""
    try:
        p = np.array(positions, dtype=float)
        t = np.array(times, dtype=float)
        v = None if velocities is None else np.array(velocities, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"waypoints must be numbers: {err}") from err
    if p.ndim != 2 or p.shape[0] == 0:
        raise ValueError(f"'positions' must be a non-empty m × n array, got shape {p.shape}")
    m, cols = p.shape
    if n is not None and cols != n:
        raise ValueError(f"'positions' have {cols} columns for {n} joints")
    if t.ndim != 1 or t.size != m:
        raise ValueError(f"{t.size} times for {m} waypoints")
    if v is not None and v.shape != p.shape:
        raise ValueError(f"'velocities' have shape {v.shape}, positions {p.shape}")
    for name, arr in (("positions", p), ("times", t), ("velocities", v)):
        if arr is not None and not np.all(np.isfinite(arr)):
            raise ValueError(f"non-finite waypoint {name}")
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise ValueError(f"waypoint times must be >= 0 and strictly increasing, got {t.tolist()}")
    if m > MAX_POINTS:
        raise ValueError(f"{m} waypoints; at most {MAX_POINTS}")
    return Trajectory.build(0.0, t, p, v)
