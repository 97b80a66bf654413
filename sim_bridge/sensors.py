r"""What the plant's joint sensors report: encoder quantization and Gaussian noise, no ROS.

For joint i with true position q_i and velocity q̇_i, the published measurement is

    y_q,i = Δ_i ⌊(q_i + σ_q,i ν_q,i) / Δ_i + ½⌋,    Δ_i = 2π / N_i     (N_i > 0 counts per rev)
    y_v,i = q̇_i + σ_v,i ν_v,i

with ν independent standard normal draws: the analog noise comes before the encoder (noise,
then quantization; the rounding is to the nearest count, so the quantization error is
uniform in [−Δ/2, Δ/2), zero mean, RMS Δ/√12; a real counter truncates, which adds the
constant offset −Δ/2 a calibration removes). N_i = 0 means no quantization. For a prismatic
joint N_i counts per metre would be the natural unit; the same formula is used, Δ_i = 2π/N_i
metres, so give N_i = 2π / resolution. Velocities are not quantized (a drive's velocity is
a filtered difference of counts, not a count).

The draws come from ``numpy.random.default_rng(seed)``: per measurement, n draws for the
positions when any σ_q > 0, then n for the velocities when any σ_v > 0 and velocities are
measured. The same seed and the same sequence of measurements give the same numbers, so a
lockstep run stays reproducible. With everything off nothing is drawn and the values pass
through unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from joint_space_control.arrays import nonnegative


class Encoder:
    """The measurement model of n joints (positions quantized and noisy, velocities noisy)."""

    def __init__(
        self,
        n: int,
        counts: float | Sequence[float] = 0.0,
        position_noise: float | Sequence[float] = 0.0,
        velocity_noise: float | Sequence[float] = 0.0,
        seed: int = 0,
    ) -> None:
        self.n = n
        self.configure(counts, position_noise, velocity_noise)
        self.reseed(seed)

    def configure(
        self,
        counts: float | Sequence[float],
        position_noise: float | Sequence[float],
        velocity_noise: float | Sequence[float],
    ) -> None:
        """Set N [counts/rev], σ_q [rad] and σ_v [rad/s] (one value or one per joint, ≥ 0);
        the generator goes on where it was."""
        counts = nonnegative(counts, self.n, "encoder_counts")
        sigma_q = nonnegative(position_noise, self.n, "position_noise")
        sigma_v = nonnegative(velocity_noise, self.n, "velocity_noise")
        self.counts = counts
        self.quantum = np.where(counts > 0, 2.0 * np.pi / np.where(counts > 0, counts, 1.0), 0.0)
        self._quantized = counts > 0
        self._any_quantized = bool(np.any(self._quantized))
        self.position_noise, self.velocity_noise = sigma_q, sigma_v
        self._noisy_q = bool(np.any(sigma_q))
        self._noisy_v = bool(np.any(sigma_v))

    def reseed(self, seed: int) -> None:
        """Restart the noise from ``seed`` (an integer ≥ 0)."""
        if isinstance(seed, bool) or int(seed) != seed or seed < 0:
            raise ValueError(f"'noise_seed' must be an integer >= 0, got {seed!r}")
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)

    @property
    def exact(self) -> bool:
        """True when the measurement is the true state (nothing quantized, no noise)."""
        return not (self._any_quantized or self._noisy_q or self._noisy_v)

    def measure(self, q: np.ndarray, dq: np.ndarray, y_q: np.ndarray, y_v: np.ndarray) -> None:
        """Write the measurement of (q, q̇) into ``y_q`` and ``y_v`` (``y_v`` empty: velocity
        not measured, nothing drawn for it). ``y_q`` may be ``q`` itself."""
        y_q[:] = q
        if self._noisy_q:
            y_q += self.position_noise * self._rng.standard_normal(self.n)
        if self._any_quantized:
            delta = self.quantum[self._quantized]
            y_q[self._quantized] = delta * np.floor(y_q[self._quantized] / delta + 0.5)
        if y_v.size:
            y_v[:] = dq
            if self._noisy_v:
                y_v += self.velocity_noise * self._rng.standard_normal(self.n)
