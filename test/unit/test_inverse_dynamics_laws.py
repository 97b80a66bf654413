"""Inverse dynamics (eq. 15), feedforward + PD (eq. 17) and precomputed feedforward
against the direct formulas built from Pinocchio's B, C, g and rnea (THEORY.md §3)."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.laws.gains import PDGains
from joint_space_control.laws.inverse_dynamics import (
    LAWS,
    ModelLaw,
    feedforward_pd,
    inverse_dynamics,
    pd_acceleration,
    precomputed_feedforward,
    reference_feedforward,
)
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.trajectories.reference import Sample

ROBOTS = ["planar_2dof", "iiwa", "panda"]


@pytest.fixture(scope="module", params=ROBOTS)
def model(request) -> RobotModel:
    # friction and a payload, so that every term of n̂ is exercised
    return RobotModel(
        resolve_robot(request.param), perturbation=ModelPerturbation(friction=0.7, payload_mass=2)
    )


def random_states(model: RobotModel, seed: int, count: int = 10):
    rng = np.random.default_rng(seed)
    n = model.n
    for _ in range(count):
        q, dq, q_d, dq_d, ddq_d = (rng.uniform(-1.5, 1.5, n) for _ in range(5))
        gains = PDGains.build(n, rng.uniform(1, 900, n), rng.uniform(0, 60, n))
        yield q, dq, Sample(q_d, dq_d, ddq_d), gains


def test_inverse_dynamics_is_eq_15(model):
    for q, dq, ref, gains in random_states(model, 1):
        y = ref.ddq + gains.kd * (ref.dq - dq) + gains.kp * (ref.q - q)
        B, C, g, F = model.inertia(q), model.coriolis(q, dq), model.gravity(q), model.friction
        direct = B @ y + C @ dq + F * dq + g
        split = inverse_dynamics(model, q, dq, ref, gains)
        scale = 1 + np.max(np.abs(direct))
        np.testing.assert_allclose(split.total, direct, atol=1e-10 * scale)
        # one rnea call with the commanded acceleration gives the same torque
        np.testing.assert_allclose(split.total, model.rnea(q, dq, y), atol=1e-10 * scale)
        np.testing.assert_allclose(split.feedback, B @ (y - ref.ddq), atol=1e-10 * scale)
        np.testing.assert_allclose(split.gravity, g, atol=1e-12 * scale)


def test_feedforward_pd_is_eq_17(model):
    for q, dq, ref, gains in random_states(model, 2):
        B, C, g, F = model.inertia(q), model.coriolis(q, dq), model.gravity(q), model.friction
        direct = (
            B @ ref.ddq
            + C @ ref.dq
            + F * ref.dq
            + g
            + gains.kd * (ref.dq - dq)
            + gains.kp * (ref.q - q)
        )
        split = feedforward_pd(model, q, dq, ref, gains)
        scale = 1 + np.max(np.abs(direct))
        np.testing.assert_allclose(split.total, direct, atol=1e-10 * scale)
        np.testing.assert_allclose(split.feedback, pd_acceleration(q, dq, ref, gains))


def test_precomputed_feedforward_uses_the_reference(model):
    for q, dq, ref, gains in random_states(model, 3):
        Bd, Cd = model.inertia(ref.q), model.coriolis(ref.q, ref.dq)
        ff = Bd @ ref.ddq + Cd @ ref.dq + model.friction * ref.dq
        direct = ff + model.gravity(q) + gains.kd * (ref.dq - dq) + gains.kp * (ref.q - q)
        split = precomputed_feedforward(model, q, dq, ref, gains)
        scale = 1 + np.max(np.abs(direct))
        np.testing.assert_allclose(split.total, direct, atol=1e-10 * scale)
        np.testing.assert_allclose(reference_feedforward(model, ref), ff, atol=1e-10 * scale)
        # a precomputed feedforward is used as given
        given = precomputed_feedforward(model, q, dq, ref, gains, feedforward=ff)
        np.testing.assert_allclose(given.total, split.total, atol=1e-10 * scale)


def test_feedforward_pd_with_a_constant_reference_is_pd_plus_gravity(model):
    for q, dq, ref, gains in random_states(model, 4):
        still = Sample(ref.q, np.zeros(model.n), np.zeros(model.n))
        for law in (feedforward_pd, precomputed_feedforward):
            split = law(model, q, dq, still, gains)
            expected = model.gravity(q) + gains.kp * (ref.q - q) - gains.kd * dq  # PD + g(q)
            np.testing.assert_allclose(split.total, expected, atol=1e-10)
            np.testing.assert_allclose(split.model, 0.0, atol=1e-10)


def test_all_laws_agree_on_the_reference_at_zero_error(model):
    """On the reference (e = ė = 0) all three laws are the model's inverse dynamics."""
    for _, _, ref, gains in random_states(model, 5):
        expected = model.rnea(ref.q, ref.dq, ref.ddq)
        for law in LAWS.values():
            split = law(model, ref.q, ref.dq, ref, gains)
            np.testing.assert_allclose(
                split.total, expected, atol=1e-9 * (1 + abs(expected).max())
            )
            np.testing.assert_allclose(split.feedback, 0.0, atol=1e-12)


def test_nominal_inverse_dynamics_closes_a_linear_second_order_loop():
    """Plant = model: the acceleration the plant reaches under eq. 15 is exactly
    q̈ = q̈_d + K_D ė + K_P e, i.e. ë + K_D ė + K_P e = 0."""
    model = RobotModel(resolve_robot("iiwa"), perturbation=ModelPerturbation(friction=0.3))
    for q, dq, ref, gains in random_states(model, 6):
        tau = inverse_dynamics(model, q, dq, ref, gains).total
        ddq = np.linalg.solve(model.inertia(q), tau - model.nonlinear_effects(q, dq))
        e, de, dde = ref.q - q, ref.dq - dq, ref.ddq - ddq
        np.testing.assert_allclose(dde + gains.kd * de + gains.kp * e, 0.0, atol=1e-8)


def test_law_names_parse():
    assert ModelLaw.parse("feedforward_pd") is ModelLaw.FEEDFORWARD_PD
    assert set(LAWS) == set(ModelLaw)
    with pytest.raises(ValueError, match="allowed: inverse_dynamics, feedforward_pd"):
        ModelLaw.parse("computed_torque")
