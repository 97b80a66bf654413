r"""Joint-space references: what the controllers sample each tick as (q_d, q̇_d, q̈_d).

A reference is a validated, immutable sequence of points at times relative to its start
time (seconds in the controller's clock). Between points the reference is interpolated by
quintic Hermite segments, continuous in position, velocity and acceleration where the
points give them (velocities and accelerations that are not given are taken as zero).
From its start time the reference moves from the sample the controller was tracking
at that instant (a new trajectory replaces the old one from its start time); after the
last point it holds the last point.
A single point with ``time_from_start`` 0 is a set-point (a step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Sample:
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray


@dataclass(frozen=True)
class Trajectory:
    """Points (rows) at ``times`` [s] after ``start`` [s]; arrays of shape (m, n)."""

    start: float
    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray

    @classmethod
    def build(
        cls,
        start: float,
        times: np.ndarray,
        positions: np.ndarray,
        velocities: np.ndarray | None = None,
        accelerations: np.ndarray | None = None,
    ) -> Trajectory:
        """Validate and build: finite values, matching shapes, times ≥ 0 strictly increasing."""
        # Copies: the trajectory is frozen and must not share memory with the caller.
        times = np.array(times, dtype=float).reshape(-1)
        positions = np.atleast_2d(np.array(positions, dtype=float))
        m, n = positions.shape
        if m == 0 or times.size != m:
            raise ValueError(f"{times.size} times for {m} points")
        zeros = np.zeros((m, n))
        vel = zeros if velocities is None else np.atleast_2d(np.array(velocities, float))
        acc = zeros if accelerations is None else np.atleast_2d(np.array(accelerations, float))
        for name, arr in (("velocities", vel), ("accelerations", acc)):
            if arr.shape != positions.shape:
                raise ValueError(f"{name} have shape {arr.shape}, positions {positions.shape}")
        for name, arr in (
            ("times", times),
            ("positions", positions),
            ("velocities", vel),
            ("accelerations", acc),
        ):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"non-finite {name}")
        if not np.isfinite(start):
            raise ValueError("non-finite start time")
        if times[0] < 0 or np.any(np.diff(times) <= 0):
            raise ValueError(f"time_from_start must be >= 0 and strictly increasing: {times}")
        for arr in (times, positions, vel, acc):
            arr.setflags(write=False)
        return cls(float(start), times, positions, vel, acc)

    @property
    def end(self) -> float:
        return self.start + float(self.times[-1])


class Reference:
    """Samples a trajectory, starting from the sample that was active when it was set."""

    def __init__(self, trajectory: Trajectory, initial: Sample) -> None:
        self.trajectory = trajectory
        tr = trajectory
        if tr.times[0] > 0:  # a leading segment from the state held when it arrived
            self._t = np.concatenate(([0.0], tr.times))
            self._p = np.vstack((initial.q, tr.positions))
            self._v = np.vstack((initial.dq, tr.velocities))
            self._a = np.vstack((initial.ddq, tr.accelerations))
        else:
            self._t, self._p, self._v, self._a = (
                tr.times,
                tr.positions,
                tr.velocities,
                tr.accelerations,
            )
        self._initial = initial

    @classmethod
    def hold(cls, q: np.ndarray, start: float = 0.0) -> Reference:
        """A set-point at q from ``start`` on."""
        q = np.array(q, dtype=float)  # a copy: the held set-point must not change
        zero = np.zeros_like(q)
        return cls(Trajectory.build(start, [0.0], q[None, :]), Sample(q, zero, zero))

    def sample(self, t: float) -> Sample:
        """(q_d, q̇_d, q̈_d) at time t [s] in the same clock as the trajectory's start."""
        s = t - self.trajectory.start
        if s < self._t[0]:
            return self._initial
        if s >= self._t[-1]:
            return Sample(self._p[-1], np.zeros_like(self._p[-1]), np.zeros_like(self._p[-1]))
        k = int(np.searchsorted(self._t, s, side="right")) - 1
        return _quintic(
            self._t[k],
            self._t[k + 1],
            self._p[k : k + 2],
            self._v[k : k + 2],
            self._a[k : k + 2],
            s,
        )


def _quintic(
    t0: float, t1: float, p: np.ndarray, v: np.ndarray, a: np.ndarray, t: float
) -> Sample:
    """Quintic Hermite segment matching position, velocity, acceleration at both ends."""
    h = t1 - t0
    x = (t - t0) / h
    p0, p1, v0, v1, a0, a1 = p[0], p[1], v[0] * h, v[1] * h, a[0] * h * h, a[1] * h * h
    # Coefficients of p(x) = Σ c_k x^k on x ∈ [0, 1].
    c0, c1, c2 = p0, v0, 0.5 * a0
    c3 = 10 * (p1 - p0) - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
    c4 = -15 * (p1 - p0) + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
    c5 = 6 * (p1 - p0) - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
    q = c0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * c5))))
    dq = c1 + x * (2 * c2 + x * (3 * c3 + x * (4 * c4 + x * 5 * c5)))
    ddq = 2 * c2 + x * (6 * c3 + x * (12 * c4 + x * 20 * c5))
    return Sample(q, dq / h, ddq / (h * h))
