"""The practical-specification checks (workbench/experiments/judging/practical.py) on
synthetic runs whose
answer is known: each passes on the predicted numbers and fails just outside its tolerance."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.workbench.experiments.judging import practical
from joint_space_control.workbench.experiments.judging.outcome import RunView

JOINTS = ["joint1", "joint2"]
KP = np.array([2000.0, 1000.0])
Q_F = np.array([0.5, -0.3])
W = np.array([0.0, 5.0, -30.0, 0.0, 4.0, 0.0])  # force [N], torque [N·m], world axes


def run(e, label="run", executable="pd_gravity_controller", parameters=None, plant=None):
    e = np.asarray(e, dtype=float)
    return RunView(
        label,
        "planar_2dof",
        {
            "joints": JOINTS,
            "final_error": dict(zip(JOINTS, e.tolist(), strict=True)),
            "config": {"kp": KP.tolist()},
        },
        [{"q": Q_F.tolist()}],
        parameters or {},
        plant or {},
        executable,
        reference={"target": (Q_F + e).tolist()},
    )


def model(robot: str) -> RobotModel:
    return RobotModel(resolve_robot(robot))


PUSH = {"wrench_link": "link2", "wrench_force": W[:3].tolist(), "wrench_torque": W[3:].tolist()}


def test_disturbance_offsets_of_pd_pid_and_inverse_dynamics():
    m = model("planar_2dof")
    tau_ext = m.link_jacobian(Q_F, "link2").T @ W
    assert np.all(np.abs(tau_ext) > 1.0)  # the wrench loads both joints
    e_pd = -tau_ext / KP
    e_id = -np.linalg.solve(m.inertia(Q_F), tau_ext) / KP
    pd, pid = run(e_pd, plant=PUSH), run(0 * e_pd, parameters={"ki": [10.0, 5.0]}, plant=PUSH)
    id_ = run(e_id, executable="inverse_dynamics_controller", plant=PUSH)
    assert [o.passed for o in practical.disturbance([pd, pid, id_])] == [True, True, True]
    off = 1.05 * e_pd  # 5 % off the prediction: beyond the 2 % tolerance
    bad_pid = run([2e-4, 0.0], parameters={"ki": 1.0}, plant=PUSH)
    assert [o.passed for o in practical.disturbance([run(off, plant=PUSH), bad_pid])] == [
        False,
        False,
    ]
    with pytest.raises(ValueError, match="wrench_link"):
        practical.disturbance([run(e_pd)])


def test_coulomb_band_claims_pd_and_reports_pid():
    friction = {"coulomb_friction": [100.0, 50.0], "static_friction": [150.0, 75.0]}
    band = np.array([150.0, 75.0]) / KP
    inside = run(0.99 * band * [1, -1], plant=friction)
    outside = run([1.02 * band[0], 0.0], plant=friction)
    pid = run(2 * band, parameters={"ki": [1.0, 1.0]}, plant=friction)
    outcomes = practical.coulomb_band([inside, outside, pid])
    assert [o.passed for o in outcomes] == [True, False, None]
    np.testing.assert_allclose(outcomes[0].numbers["band"], band)


def test_repeatability_groups_runs_and_judges_the_band_and_the_bias():
    friction = {"coulomb_friction": [40.0, 20.0], "static_friction": [60.0, 30.0]}
    band = np.array([60.0, 30.0]) / KP
    rng = np.random.default_rng(0)

    def group(name, finals, plant):
        target = Q_F
        runs = []
        for k, q in enumerate(finals):
            r = run(target - q, f"{name}-{k}", plant=plant)
            r.events, r.reference = [{"q": list(q)}], {"target": list(target)}
            runs.append(r)
        return runs

    stuck = group("friction", Q_F - 0.9 * band + rng.normal(0, 1e-5, (6, 2)), friction)
    beyond = group("leaky", Q_F - 1.1 * band + rng.normal(0, 1e-5, (6, 2)), friction)
    noisy = group("noise", Q_F + rng.normal(0, 1e-3, (6, 2)), {})
    biased = group("biased", Q_F + 5e-3 + rng.normal(0, 1e-3, (6, 2)), {})
    outcomes = practical.repeatability(stuck + beyond + noisy + biased)
    assert [(o.numbers["group"], o.passed) for o in outcomes] == [
        ("friction", True),
        ("leaky", False),
        ("noise", True),
        ("biased", False),
    ]
    np.testing.assert_allclose(outcomes[0].numbers["accuracy"], np.linalg.norm(0.9 * band), 1e-3)
    with pytest.raises(ValueError, match="one run"):
        practical.repeatability([run([0, 0], "alone-1")])


def test_predicted_chatter_matches_the_analytic_variance_of_the_noise_through_the_law():
    """PD + g at rest, position noise σ_q: with measured velocities (noise σ_v) δτ = A n_q −
    K_D n_v, A = ∂g/∂q − K_P, so Var Δδτ_i = 2 (Σ_j A_ij² σ_q² + K_D,i² σ_v²); with a backward
    difference (D = K_D/T) Δδτ_k = (A − D) n_k + (2D − A) n_{k−1} − D n_{k−2}. The simulated
    prediction (20000 samples) within 3 %."""
    from joint_space_control.workbench.experiments.judging.boundaries import gravity_jacobian
    from joint_space_control.workbench.experiments.judging.practical import predicted_chatter

    sigma_q, sigma_v, period = 1e-4, 0.02, 1e-3
    kd = np.array([900.0, 300.0])
    plant = {"position_noise": sigma_q, "velocity_noise": sigma_v}
    a = gravity_jacobian(model("planar_2dof"), Q_F) - np.diag(KP)
    d = np.diag(kd / period)

    def with_source(source):
        r = run([0.0, 0.0], parameters={"velocity_source": source}, plant=plant)
        r.controller["config"]["kd"] = kd.tolist()
        return predicted_chatter(r, Q_F, period)

    measured = np.sqrt(2 * (np.sum(a**2, axis=1) * sigma_q**2 + kd**2 * sigma_v**2))
    np.testing.assert_allclose(with_source("measured"), measured, rtol=0.03)
    rows = np.sum((a - d) ** 2 + (2 * d - a) ** 2 + d**2, axis=1)
    np.testing.assert_allclose(
        with_source("backward_difference"), sigma_q * np.sqrt(rows), rtol=0.03
    )
    assert with_source("filtered_difference")[0] < 0.3 * sigma_q * np.sqrt(rows[0])
