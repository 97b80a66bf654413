r"""Joint velocity from measured positions, when the plant does not measure it (or badly).

Both estimators take the time step from the states' stamps, T_k = t_k − t_{k−1} [s], so a
period that varies (a held control period, a late state) is differenced over its real length.

- **Backward difference** (:class:`BackwardDifference`)

      q̇_k = (q_k − q_{k−1}) / T_k

  With a constant T it is D(z) = (1 − z⁻¹)/T. At a frequency ω [rad/s], z = e^{jωT}:

      D(e^{jωT}) = jω · sinc(ωT/2) · e^{−jωT/2},    sinc(x) = sin(x)/x

  an amplitude ratio sinc(ωT/2) to the true derivative and a phase lag of exactly ωT/2
  (half a period: the difference is the slope at the middle of the last period). A ramp is
  differentiated exactly; white position noise of variance σ² becomes 2σ²/T².

- **Filtered difference** (:class:`FilteredDifference`): the difference through a first-order
  low-pass of cutoff f_c [Hz], discretised with the exact pole of a continuous first order
  (step invariant), α_k = exp(−2π f_c T_k):

      q̇_k = α_k q̇_{k−1} + (1 − α_k)(q_k − q_{k−1}) / T_k

  With a constant T, F(z) = D(z) H(z), H(z) = (1 − α)/(1 − α z⁻¹), unit gain at DC, and

      |H(e^{jωT})| = (1 − α) / √(1 − 2α cos ωT + α²)
      ∠lag_H(ω)    = atan(α sin ωT / (1 − α cos ωT))

  so the estimate lags the true velocity by ωT/2 + atan(α sin ωT / (1 − α cos ωT)). For
  ωT ≪ 1 and ω_c T ≪ 1 (ω_c = 2π f_c) this tends to atan(ω/ω_c), the continuous first
  order's lag: the discrete pole leads its continuous model by half a period
  (α/(1 − α) ≈ 1/(ω_c T) − 1/2), which cancels the difference's ωT/2 to first order in ωT
  (within 1 % up to ω = 2 ω_c at T = 1 ms, f_c = 50 Hz). White position noise
  of variance σ² gives (1 − α)²/(1 + α) times the backward difference's variance (the
  impulse response of (1 − z⁻¹)/(1 − αz⁻¹) has energy 2/(1 + α)).

Start and restart: the first sample has no predecessor, its estimate is 0. The filter
starts from the first difference (q̇_1 = (q_1 − q_0)/T_1, its steady state for a ramp), so a
start or a switch of estimator while moving has no transient from 0, and a ramp is exact
from the second sample on with either estimator. A sample with the same or an earlier stamp
than the previous one carries no new information: the previous estimate is returned (the
owner restarts the estimator when time goes backwards). ``reset`` forgets everything.
"""

from __future__ import annotations

import math

import numpy as np


class BackwardDifference:
    """q̇_k = (q_k − q_{k−1}) / T_k, 0 for the first sample (module docstring)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self._zero = np.zeros(n)
        self._zero.setflags(write=False)
        self.reset()

    def reset(self) -> None:
        """Forget the previous sample and the estimate."""
        self._t: float | None = None
        self._q: np.ndarray | None = None
        self.estimate: np.ndarray = self._zero

    @property
    def previous(self) -> tuple[float, np.ndarray] | None:
        """The last sample (t [s], q), None before the first."""
        return None if self._t is None else (self._t, self._q)

    def observe(self, t: float, q: np.ndarray) -> None:
        """Remember (t, q) as the previous sample without estimating (while the measured
        velocity is used): a later switch to this estimator has a predecessor at once."""
        if self._t is None or t > self._t:
            self._t, self._q = t, q
            self._cold()

    def _cold(self) -> None:
        """The estimator was not updated at the last sample (see :meth:`observe`)."""

    def update(self, t: float, q: np.ndarray) -> np.ndarray:
        """The estimate at the sample (t [s], q); a new array, never changed afterwards."""
        t_prev = self._t
        if t_prev is None:
            self._t, self._q = t, q
            self.estimate = self._zero
            return self.estimate
        period = t - t_prev
        if period <= 0.0:
            return self.estimate
        difference = (q - self._q) / period
        self._t, self._q = t, q
        self.estimate = self._filter(difference, period)
        return self.estimate

    def _filter(self, difference: np.ndarray, period: float) -> np.ndarray:
        return difference


class FilteredDifference(BackwardDifference):
    """q̇_k = α_k q̇_{k−1} + (1 − α_k)(q_k − q_{k−1})/T_k, α_k = exp(−2π f_c T_k)
    (module docstring). ``cutoff`` f_c [Hz] > 0 may be changed between samples."""

    def __init__(self, n: int, cutoff: float) -> None:
        self.cutoff = cutoff
        self._alpha_key = (math.nan, math.nan)  # (cutoff, period) of the cached α
        self._alpha = 0.0
        super().__init__(n)

    def reset(self) -> None:
        super().reset()
        self._warm = False  # False: the next difference starts the filter

    def _cold(self) -> None:
        self._warm = False

    def alpha(self, period: float) -> float:
        """α = exp(−2π f_c T) for a period T [s] (cached: the period rarely changes)."""
        key = (self.cutoff, period)
        if key != self._alpha_key:
            self._alpha, self._alpha_key = math.exp(-2.0 * math.pi * self.cutoff * period), key
        return self._alpha

    def _filter(self, difference: np.ndarray, period: float) -> np.ndarray:
        if not self._warm:
            self._warm = True
            return difference
        alpha = self.alpha(period)
        return alpha * self.estimate + (1.0 - alpha) * difference


def difference_response(omega: np.ndarray, period: float) -> np.ndarray:
    """D(e^{jωT}) / (jω): the backward difference relative to the true derivative, complex,
    at ω [rad/s] for a constant period T [s]: sinc(ωT/2) e^{−jωT/2}."""
    omega = np.asarray(omega, dtype=float)
    z = np.exp(1j * omega * period)
    return (1.0 - 1.0 / z) / period / (1j * omega)


def filtered_difference_response(omega: np.ndarray, period: float, cutoff: float) -> np.ndarray:
    """D(e^{jωT}) H(e^{jωT}) / (jω): the filtered difference relative to the true derivative
    at ω [rad/s], H(z) = (1 − α)/(1 − αz⁻¹), α = exp(−2π f_c T)."""
    omega = np.asarray(omega, dtype=float)
    alpha = math.exp(-2.0 * math.pi * cutoff * period)
    z = np.exp(1j * omega * period)
    return difference_response(omega, period) * (1.0 - alpha) / (1.0 - alpha / z)


def phase_lag(omega: np.ndarray, period: float, cutoff: float | None = None) -> np.ndarray:
    """The estimate's phase lag behind the true velocity [rad] at ω [rad/s]: ωT/2 for the
    backward difference, + atan(α sin ωT / (1 − α cos ωT)) with the filter (``cutoff`` [Hz])."""
    omega = np.asarray(omega, dtype=float)
    lag = omega * period / 2.0
    if cutoff is None:
        return lag
    alpha = math.exp(-2.0 * math.pi * cutoff * period)
    wt = omega * period
    return lag + np.arctan2(alpha * np.sin(wt), 1.0 - alpha * np.cos(wt))


def noise_variance_ratio(period: float, cutoff: float) -> float:
    """Variance of the filtered difference over that of the backward difference for white
    position noise: (1 − α)²/(1 + α), α = exp(−2π f_c T)."""
    alpha = math.exp(-2.0 * math.pi * cutoff * period)
    return (1.0 - alpha) ** 2 / (1.0 + alpha)
