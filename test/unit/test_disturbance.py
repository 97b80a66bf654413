"""Rest positions under a constant disturbance and Coulomb friction (laws/disturbance.py),
against closed-loop simulations of a one-joint arm and a two-joint check of B̂ K_P e = −τ_ext."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.laws.disturbance import (
    coulomb_dead_band,
    inverse_dynamics_static_offset,
    pd_gravity_static_offset,
)

# one revolute joint: a point mass m at length l, angle q from the horizontal, gravity g0
M, L, G0 = 2.0, 0.5, 9.81
B = M * L * L  # [kg·m²]
F_VISC = 0.1  # [N·m·s/rad]
Q_D = 0.4  # [rad]
FORCE = np.array([0.0, -15.0])  # [N] applied to the mass (w), world frame (x, y)


def gravity(q):
    return M * G0 * L * math.cos(q)


def tau_ext(q, force=FORCE):
    """Jᵀ w of the force w applied at the mass: J = l (−sin q, cos q)."""
    return L * (-math.sin(q) * force[0] + math.cos(q) * force[1])


def simulate(torque, duration=20.0, h=1e-4, coulomb=0.0, q0=0.0, force=FORCE):
    """B q̈ + F q̇ + f_c + g(q) = τ + Jᵀ w by semi-implicit Euler; the Coulomb torque holds the
    joint while |τ + Jᵀw − g| ≤ F_c at (numerically) zero speed."""
    q, v = q0, 0.0
    for _ in range(round(duration / h)):
        drive = torque(q, v) + tau_ext(q, force) - gravity(q) - F_VISC * v
        if coulomb > 0.0 and abs(v) < 1e-9 and abs(drive) <= coulomb:
            v = 0.0
            continue
        friction = coulomb * math.copysign(1.0, v if v != 0.0 else drive)
        v_new = v + h * (drive - friction) / B
        if coulomb > 0.0 and v != 0.0 and v_new * v < 0.0:
            v_new = 0.0  # friction stops it within the step
        v = v_new
        q += h * v
    return q, v


def test_pd_gravity_offset_matches_simulation():
    kp, kd = 200.0, 20.0
    q, v = simulate(lambda q, v: gravity(q) + kp * (Q_D - q) - kd * v)
    predicted = pd_gravity_static_offset(kp, tau_ext(q))  # Jᵀ w at the rest position
    assert abs(v) < 1e-9
    assert Q_D - q == pytest.approx(predicted[0], abs=1e-9)
    # the theory's form K_P e = Jᵀ h_e, h_e = −w
    assert kp * (Q_D - q) == pytest.approx(-tau_ext(q), rel=1e-9)


def test_inverse_dynamics_offset_with_a_wrong_inertia():
    omega_n, zeta, b_hat = 10.0, 0.8, 0.6 * B
    kp, kd = omega_n**2, 2 * zeta * omega_n

    def law(q, v):
        return b_hat * (kp * (Q_D - q) - kd * v) + F_VISC * v + gravity(q)

    q, v = simulate(law)
    predicted = inverse_dynamics_static_offset(kp, [[b_hat]], [tau_ext(q)])
    assert abs(v) < 1e-9
    assert Q_D - q == pytest.approx(predicted[0], abs=1e-9)
    assert kp * (Q_D - q) == pytest.approx(-tau_ext(q) / b_hat, rel=1e-9)


def test_gravity_error_adds_to_the_disturbance():
    kp = np.array([100.0, 50.0])
    e = pd_gravity_static_offset(kp, [1.0, -2.0], gravity_error=[0.5, 0.5])
    np.testing.assert_allclose(e, [-0.5 / 100, 2.5 / 50])
    b_hat = np.array([[2.0, 0.3], [0.3, 0.5]])
    e = inverse_dynamics_static_offset(kp, b_hat, [1.0, -2.0])
    np.testing.assert_allclose(b_hat @ (kp * e), [-1.0, 2.0], atol=1e-14)


def test_coulomb_dead_band_contains_where_pd_gravity_stops():
    kp, kd, fc = 50.0, 5.0, 2.0
    band = coulomb_dead_band(kp, fc)[0]
    assert band == pytest.approx(fc / kp)
    none = np.zeros(2)

    def law(q, v):
        return gravity(q) + kp * (Q_D - q) - kd * v

    for q0 in (-0.5, 0.0, 0.3, 0.39, 1.2):
        q, v = simulate(law, duration=5.0, coulomb=fc, q0=q0, force=none)
        assert v == 0.0
        assert abs(Q_D - q) <= band * (1 + 1e-9)
    # starting at rest inside the band it never moves
    start = Q_D - 0.9 * band
    assert simulate(law, 1.0, coulomb=fc, q0=start, force=none)[0] == start


def test_dead_band_per_joint_and_stiction():
    np.testing.assert_allclose(
        coulomb_dead_band([10.0, 20.0], [1.0, 1.0], [2.0, 0.5]), [0.2, 0.05]
    )
    with pytest.raises(ValueError):
        coulomb_dead_band(0.0, 1.0)
    with pytest.raises(ValueError):
        inverse_dynamics_static_offset(1.0, np.eye(2), [1.0])
