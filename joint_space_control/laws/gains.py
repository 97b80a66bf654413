"""Validated, immutable gain sets (a runtime update builds a new object and swaps it whole),
and the gain design from a natural frequency and a damping ratio (numpy only, no ROS)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from joint_space_control.arrays import nonnegative
from joint_space_control.laws.second_order import second_order_to_gains


@dataclass(frozen=True)
class PDGains:
    """Diagonal gains: K_P [N·m/rad], K_D [N·m·s/rad], K_I [N·m/(rad·s)]."""

    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray

    @classmethod
    def build(
        cls,
        n: int,
        kp: float | Sequence[float],
        kd: float | Sequence[float],
        ki: float | Sequence[float] = 0.0,
    ) -> PDGains:
        gains = cls(nonnegative(kp, n, "kp"), nonnegative(kd, n, "kd"), nonnegative(ki, n, "ki"))
        if np.any(gains.kp <= 0):
            raise ValueError(f"'kp' must be > 0 on every joint (K_P ≻ 0), got {gains.kp.tolist()}")
        return gains


# --------------------------------------------------------------------------- gain design

#: Natural frequency [rad/s] and damping ratio of the gains a controller uses when none are
#: given. The design below is scale-free in inertia: each joint behaves (about its start
#: configuration, other joints at rest) like ë + 2ζω_n ė + ω_n² e = 0, whatever its inertia.
#: At the default 1 kHz control rate ω_n T_s = 0.01 and K_D T_s / B_ii = 2ζω_n T_s = 0.02, far
#: inside the sampled-data stability limits (about 2), on any arm; the 2 % settling time is
#: about 5.8/ω_n ≈ 0.6 s, critically damped (no overshoot).
DEFAULT_OMEGA_N = 10.0
DEFAULT_ZETA = 1.0

#: Where the gains in force come from (``GainChoice.source``).
FROM_OMEGA_N = "omega_n"  # omega_n given (> 0): ω_n, ζ
FROM_KP = "kp"  # kp given (> 0), no omega_n: kp, kd as they are
FROM_DEFAULT = "default"  # nothing given: DEFAULT_OMEGA_N, ζ


@dataclass(frozen=True)
class GainChoice:
    """The gains asked for, validated: either ``kp``/``kd`` as given, or a second-order
    design ``omega_n``/``zeta`` (per joint) still to be turned into gains by the law."""

    source: str
    kp: np.ndarray | None = None
    kd: np.ndarray | None = None
    omega_n: np.ndarray | None = None
    zeta: np.ndarray | None = None

    @property
    def designed(self) -> bool:
        """True when the gains come from ω_n, ζ (given or the defaults)."""
        return self.source != FROM_KP


def choose_gains(
    n: int,
    kp: float | Sequence[float],
    kd: float | Sequence[float],
    omega_n: float | Sequence[float],
    zeta: float | Sequence[float],
) -> GainChoice:
    """The precedence rule of the controllers' gain parameters (0 = not given):

    1. ``omega_n`` > 0: the second-order design with ``omega_n``, ``zeta`` (kp, kd unused);
    2. else ``kp`` > 0: ``kp``, ``kd`` as given;
    3. else (nothing given): the design with :data:`DEFAULT_OMEGA_N` and ``zeta``.

    Each of kp, omega_n is either > 0 on every joint or 0 (all joints); ``kd`` > 0 needs
    ``kp`` > 0 (a K_D without a K_P is a mistake, not a request for ω_n/ζ gains); zeta >= 0.
    Raises ValueError with one reason otherwise.
    """
    kp_arr = nonnegative(kp, n, "kp")
    kd_arr = nonnegative(kd, n, "kd")
    omega = nonnegative(omega_n, n, "omega_n")
    zeta_arr = nonnegative(zeta, n, "zeta")
    for name, arr, meaning in (
        ("kp", kp_arr, "K_P ≻ 0"),
        ("omega_n", omega, "ω_n > 0"),
    ):
        if np.any(arr > 0) and np.any(arr == 0):
            raise ValueError(
                f"'{name}' must be > 0 on every joint ({meaning}), or 0 (not given), "
                f"got {arr.tolist()}"
            )
    kp_given = bool(np.all(kp_arr > 0))
    if np.any(kd_arr > 0) and not kp_given:
        raise ValueError(
            f"'kd' {kd_arr.tolist()} is given without 'kp': set kp > 0 too, or kd to 0 "
            "(gains from omega_n/zeta)"
        )
    if np.all(omega > 0):
        return GainChoice(FROM_OMEGA_N, omega_n=omega, zeta=zeta_arr)
    if kp_given:
        return GainChoice(FROM_KP, kp=kp_arr, kd=kd_arr)
    default = np.full(n, DEFAULT_OMEGA_N)
    default.setflags(write=False)
    return GainChoice(FROM_DEFAULT, omega_n=default, zeta=zeta_arr)


def inverse_dynamics_gains(
    omega_n: float | Sequence[float], zeta: float | Sequence[float], n: int
) -> PDGains:
    """K_P = ω_n², K_D = 2ζω_n [1/s², 1/s]: each joint error of the nominal inverse-dynamics
    loop obeys ë + K_D ė + K_P e = 0 (THEORY.md §3)."""
    kp, kd = second_order_to_gains(omega_n, zeta)
    return PDGains.build(n, kp, kd)


def pd_gains_from_second_order(
    inertia_diagonal: Sequence[float],
    omega_n: float | Sequence[float],
    zeta: float | Sequence[float],
    ki: float | Sequence[float] = 0.0,
) -> PDGains:
    """Decentralized PD gains K_P,i = B_ii ω_n,i², K_D,i = 2ζ_i B_ii ω_n,i [N·m/rad, N·m·s/rad].

    ``inertia_diagonal`` is diag B̂(q₀), the model's inertia at a configuration q₀: about q₀
    with the other joints at rest (and gravity compensated), joint i is B_ii q̈ + K_D q̇ + K_P q
    = 0, a second-order loop with natural frequency ω_n,i and damping ζ_i whatever B_ii.
    """
    b = np.asarray(inertia_diagonal, dtype=float).reshape(-1)
    if not (np.all(np.isfinite(b)) and np.all(b > 0)):
        raise ValueError(f"inertia diagonal must be finite and > 0, got {b.tolist()}")
    kp, kd = second_order_to_gains(omega_n, zeta)
    return PDGains.build(b.size, b * kp, b * kd, ki)
