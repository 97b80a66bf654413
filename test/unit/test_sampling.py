"""How the controller objects sample (joint_space_control.control.sampling): the control
period's hold, the velocity source, the regulation form of the reference."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.control.inverse_dynamics import (
    IDConfig,
    InverseDynamicsController,
    gains_from_choice,
)
from joint_space_control.control.pd_gravity import PDConfig, PDGravityController
from joint_space_control.control.sampling import ControlPeriod, Sampling, VelocitySource
from joint_space_control.laws.gains import PDGains, choose_gains
from joint_space_control.laws.inverse_dynamics import ModelLaw
from joint_space_control.laws.pd_gravity import GravityCompensation, pid_torque_split
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.trajectories.reference import Trajectory

MS = 1e-3


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return RobotModel(resolve_robot("planar_2dof"))


def pd(model: RobotModel, sampling: Sampling | None = None, ki=0.0) -> PDGravityController:
    n, zero = model.n, np.zeros(model.n)
    choice = choose_gains(n, 100.0, 10.0, 0.0, 1.0)
    ki = np.full(n, ki)
    config = PDConfig(
        model, PDGains.build(n, choice.kp, choice.kd, ki), GravityCompensation.FULL, zero,
        choice, ki,
    )  # fmt: skip
    return PDGravityController(config, np.full(n, 1e6), sampling)


def inverse_dynamics(model: RobotModel, sampling: Sampling | None = None):
    n = model.n
    choice = choose_gains(n, 0.0, 0.0, 8.0, 0.5)
    config = IDConfig(model, gains_from_choice(choice, n), ModelLaw.INVERSE_DYNAMICS, choice)
    return InverseDynamicsController(config, np.full(n, 1e6), sampling)


# -- the control period -------------------------------------------------------------------


def computed_states(period: float, stamps) -> list[int]:
    hold = ControlPeriod(period)
    out = []
    for k, t in enumerate(stamps):
        if hold.due(t):
            hold.computed(t)
            out.append(k)
    return out, hold


def test_a_period_of_ten_states_computes_every_tenth_state():
    stamps = np.round(np.arange(101) * 1e6) * 1e-9  # 1 kHz, whole ns as sim_bridge stamps
    computed, hold = computed_states(10 * MS, stamps)
    assert computed == list(range(0, 101, 10))
    assert hold.realised == pytest.approx(10 * MS, abs=1e-12) and not hold.indivisible


def test_jittered_stamps_keep_the_grid():
    """±50 µs on 1 ms states: still every tenth state (the half state period of tolerance
    absorbs it; the period is counted from the last computed stamp, so jitter beyond a
    quarter of a state period could move a period by one state)."""
    rng = np.random.default_rng(3)
    stamps = np.arange(201) * MS + rng.uniform(-50e-6, 50e-6, 201) * (np.arange(201) > 0)
    computed, _ = computed_states(10 * MS, stamps)
    assert computed == list(range(0, 201, 10))


@pytest.mark.parametrize(
    ("period", "every"), [(2.4 * MS, 2), (2.6 * MS, 3), (3.4 * MS, 3), (0.4 * MS, 1)]
)
def test_a_period_the_states_do_not_divide_is_flagged_and_rounded(period, every):
    """The realised period is the multiple of the state period nearest to T_s, at least
    one state."""
    computed, hold = computed_states(period, np.arange(60) * MS)
    assert computed == list(range(0, 60, every))
    assert hold.indivisible
    assert hold.realised == pytest.approx(every * MS, abs=1e-12)


def test_a_gap_in_the_states_is_not_their_period():
    """States every 1 ms with one 28 ms gap (a node starting while the plant runs, as a
    restarted controller does): the 1 ms period divides itself, nothing is flagged (the
    gap was once flagged as 'the realised period is 28 ms')."""
    stamps = np.concatenate([[0.0, MS], 29 * MS + np.arange(20) * MS])
    computed, hold = computed_states(MS, stamps)
    assert computed == list(range(len(stamps)))
    assert not hold.indivisible


def test_no_period_computes_every_state_and_a_repeated_stamp_is_not_a_new_period():
    computed, _ = computed_states(0.0, np.arange(5) * MS)
    assert computed == [0, 1, 2, 3, 4]
    hold = ControlPeriod(2 * MS)
    assert [hold.due(t) for t in (0.0,)] == [True]
    hold.computed(0.0)
    assert [hold.due(t) for t in (0.0, MS, MS, 2 * MS)] == [False, False, False, True]


# -- the controller with a control period -----------------------------------------------------


def test_the_torque_is_held_over_the_period_and_the_integral_uses_the_realised_period(model):
    """T_s = 10 ms on 1 kHz states: one torque per 10 states, computed from the state at the
    start of the period (the held step is the same object); K_I ∫e advances by e·T_s."""
    c = pd(model, Sampling(period=10 * MS), ki=50.0)
    q0 = np.array([0.3, -0.2])
    c.step(0.0, q0, np.zeros(2))
    c.add_trajectory(Trajectory.build(0.0, np.array([0.0]), np.array([[0.4, -0.1]])))
    taus, steps = [], []
    for k in range(1, 41):
        q = q0 + 1e-4 * k  # a moving state: a new torque would differ at every state
        steps.append(c.step(k * MS, q, np.zeros(2)))
        taus.append(steps[-1].tau)
    taus = np.array(taus)
    for start in (9, 19, 29):  # states 10, 20, 30 start periods
        assert all(steps[start + j] is steps[start] for j in range(10))
        np.testing.assert_array_equal(taus[start : start + 10], np.tile(taus[start], (10, 1)))
        np.testing.assert_array_equal(steps[start].q, q0 + 1e-4 * (start + 1))
    assert not np.array_equal(taus[19], taus[9])
    # computed at 10, 20, 30, 40 ms (the first step, at 0, integrates nothing): Σ e(t_k)·T_s
    errors = [np.array([0.4, -0.1]) - (q0 + 1e-4 * k) for k in (10, 20, 30, 40)]
    np.testing.assert_allclose(c._integral, np.sum(errors, axis=0) * 10 * MS, rtol=1e-12)


def test_no_period_is_bit_identical_to_the_law(model):
    """Default sampling, measured velocities: each step is the law on that state."""
    rng = np.random.default_rng(5)
    a, b = pd(model), pd(model, Sampling(period=0.0, velocity=VelocitySource.MEASURED))
    for k in range(20):
        q, dq = rng.normal(size=2), rng.normal(size=2)
        sa, sb = a.step(k * MS, q, dq), b.step(k * MS, q, dq)
        np.testing.assert_array_equal(sa.tau, sb.tau)
        law = pid_torque_split(q, dq, sa.ref.q, np.zeros(2), a.config.gains, model.gravity(q))
        np.testing.assert_array_equal(sa.unclamped, law.total)
        assert sa.dq is dq and a.velocity_used is VelocitySource.MEASURED


# -- the velocity source --------------------------------------------------------------------------


def test_auto_estimates_when_the_state_has_no_velocity(model):
    """A ramp at 0.5 rad/s without velocities: the filtered difference (exact on a ramp from
    the second state on) is the law's q̇; with T_s = 5 ms it is differenced over 5 ms."""
    for period in (0.0, 5 * MS):
        c = pd(model, Sampling(period=period))
        empty = np.empty(0)
        steps = [c.step(k * MS, np.full(2, 0.5 * k * MS), empty) for k in range(30)]
        assert c.velocity_used is VelocitySource.FILTERED_DIFFERENCE
        np.testing.assert_array_equal(steps[0].dq, 0.0)
        for s in steps[6:]:
            np.testing.assert_allclose(s.dq, 0.5, rtol=1e-9)
            expected = model.gravity(s.q) + 100.0 * (s.ref.q - s.q) - 10.0 * 0.5
            np.testing.assert_allclose(s.unclamped, expected, rtol=1e-9)


def test_measured_without_a_velocity_is_an_error_and_a_switch_is_bumpless(model):
    c = pd(model, Sampling(velocity=VelocitySource.MEASURED))
    with pytest.raises(ValueError, match="no velocity"):
        c.step(0.0, np.zeros(2), np.empty(0))
    c = pd(model, Sampling(velocity=VelocitySource.MEASURED))
    for k in range(5):  # measured: the estimator observes
        c.step(k * MS, np.full(2, 2.0 * k * MS), np.full(2, 2.0))
    c.set_sampling(Sampling(velocity=VelocitySource.BACKWARD_DIFFERENCE))
    np.testing.assert_allclose(c.step(5 * MS, np.full(2, 10 * MS), np.empty(0)).dq, 2.0)
    c.set_sampling(Sampling(velocity=VelocitySource.FILTERED_DIFFERENCE, cutoff=5.0))
    np.testing.assert_allclose(c.step(6 * MS, np.full(2, 12 * MS), np.empty(0)).dq, 2.0)
    c.restart()
    np.testing.assert_array_equal(c.step(0.0, np.zeros(2), np.empty(0)).dq, 0.0)


# -- the regulation form -----------------------------------------------------------------------


def test_regulation_form_drops_the_reference_derivatives(model):
    """reference_derivatives off: τ = B̂(q)(K_P e − K_D q̇) + n̂(q, q̇) on a moving reference
    (nonzero q̇_d, q̈_d); on: the full eq. 15."""
    q, dq = np.array([0.3, -0.2]), np.array([0.4, -0.3])
    traj = Trajectory.build(0.0, np.array([1.0]), np.array([[1.3, 0.8]]))
    results = {}
    for flag in (True, False):
        c = inverse_dynamics(model, Sampling(reference_derivatives=flag))
        c.step(0.0, q, dq)
        c.add_trajectory(traj)
        results[flag] = c.step(0.3, q, dq)
    full, regulation = results[True], results[False]
    assert np.all(np.abs(full.ref.dq) > 0.1) and np.all(np.abs(full.ref.ddq) > 0.0)
    np.testing.assert_array_equal(regulation.ref.q, full.ref.q)
    np.testing.assert_array_equal(regulation.ref.dq, 0.0)
    np.testing.assert_array_equal(regulation.ref.ddq, 0.0)
    e = full.ref.q - q
    expected = model.inertia(q) @ (64.0 * e - 8.0 * dq) + model.nonlinear_effects(q, dq)
    np.testing.assert_allclose(regulation.unclamped, expected, rtol=1e-12, atol=1e-12)
    y = 64.0 * e + 8.0 * (full.ref.dq - dq) + full.ref.ddq
    np.testing.assert_allclose(full.unclamped, model.rnea(q, dq, y), rtol=1e-10)


def test_after_a_non_finite_torque_the_next_state_is_computed_again(model):
    """Nothing was sent for the non-finite step, so there is nothing to hold: the next state
    starts a new period (and the one after it is held again)."""
    c = pd(model, Sampling(period=10 * MS))
    q = np.array([0.3, -0.2])
    assert c.step(0.0, q, np.zeros(2)).tau is not None
    assert c.step(1 * MS, q, np.zeros(2)).tau is not None  # held
    c.restart()  # a period starts at the next state, which makes the law non-finite
    bad = c.step(2 * MS, q, np.array([np.nan, 0.0]))
    assert bad.tau is None
    good = c.step(3 * MS, q, np.zeros(2))
    assert good.tau is not None and good is not bad
    # inside good's period the state is not used (the node rejects non-finite states anyway)
    assert c.step(4 * MS, q, np.array([np.nan, 0.0])) is good
