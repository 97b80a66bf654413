"""The PD + g(q) design of ``jsc tune`` for coupled arms (workbench/tuning/design.py, space.py,
session.py): the effective inertia along the step, the linearised loop it makes move as one
second order, the time scaling of the PD + g(q) loop, the shared stage and its
reproducibility."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from joint_space_control.analysis.spec import parse_spec
from joint_space_control.cli import tune as tune_cli
from joint_space_control.laws.gains import FROM_KP, choose_gains, pd_gains_from_second_order
from joint_space_control.laws.second_order import second_order_step
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.workbench.tuning.design import (
    SCALE_MARGIN,
    ZETA_LADDER,
    effective_inertia,
    theory_design,
    time_scale,
    zeta_ladder,
)
from joint_space_control.workbench.tuning.session import TuneOptions, prepare
from joint_space_control.workbench.tuning.space import SearchSpace
from test.unit.test_tune import ThreadPool
from test.unit.tuning_fakes import FakeResult, controller_metrics

JOINTS = ("joint1", "joint2", "joint3")
#: A symmetric positive definite inertia whose couplings all add along a step of (1, 1, 1).
B_AIDING = np.array([[2.0, 0.5, 0.1], [0.5, 1.0, 0.2], [0.1, 0.2, 0.05]])


def linear_response(b: np.ndarray, kp: np.ndarray, kd: np.ndarray, e0: np.ndarray, t):
    """e(t) of B ë + K_D ė + K_P e = 0 from (e0, 0), exactly (matrix exponential)."""
    n = e0.size
    a = np.block(
        [
            [np.zeros((n, n)), np.eye(n)],
            [-np.linalg.solve(b, np.diag(kp)), -np.linalg.solve(b, np.diag(kd))],
        ]
    )
    x0 = np.concatenate([e0, np.zeros(n)])
    return np.array([(expm(a * ti) @ x0)[:n] for ti in t])


# --------------------------------------------------------------------------- effective inertia


def test_on_decoupled_joints_the_effective_inertia_is_the_diagonal_and_the_old_design():
    b = np.diag([145.0, 22.5, 0.3])
    for step in ([0.2, 0.2, 0.2], [0.2, -0.1, 0.05], [0.0, 0.2, 0.0]):
        np.testing.assert_array_equal(effective_inertia(b, step), [145.0, 22.5, 0.3])
    np.testing.assert_array_equal(effective_inertia([[3.5]], [0.2]), [3.5])
    # the gains of the design: K_P = B ω_n², K_D = 2ζBω_n, as laws/gains.py designs them
    space = SearchSpace(JOINTS, inertia=tuple(effective_inertia(b, [0.2] * 3)))
    point = space.point(np.array([10.0, 20.0, 5.0]), np.array([1.0, 0.5, 0.8]))
    kp, kd = space.kp_kd(point)
    ref = pd_gains_from_second_order(np.diag(b), [10.0, 20.0, 5.0], [1.0, 0.5, 0.8])
    np.testing.assert_allclose(kp, ref.kp, rtol=1e-12)
    np.testing.assert_allclose(kd, ref.kd, rtol=1e-12)


def test_the_effective_inertia_is_b_dq_over_dq_where_the_coupling_aids_the_step():
    dq = np.full(3, 0.2)
    b = effective_inertia(B_AIDING, dq)
    np.testing.assert_allclose(b, B_AIDING @ dq / dq, rtol=1e-12)
    # a coupling that opposes the step: B_ii + |c_i|, stiffer than the joint's own inertia
    opposing = np.array([[2.0, -0.5], [-0.5, 0.3]])
    b = effective_inertia(opposing, [0.2, 0.2])
    np.testing.assert_allclose(b, [2.5, 0.8], rtol=1e-12)  # c = −0.5 on both
    with pytest.raises(ValueError, match="3×3"):
        effective_inertia(np.eye(2), dq)


@pytest.mark.parametrize(("omega_n", "zeta"), [(5.0, 0.8), (12.0, 1.0), (3.0, 0.6)])
def test_the_coupled_linear_loop_moves_every_joint_as_one_second_order(omega_n, zeta):
    """K_P = ω_n² b, K_D = 2ζω_n b on the coupled B: e(t) = s(t) Δq, s the second-order
    step response, on every joint; the diagonal design does not."""
    dq = np.array([0.2, 0.2, 0.2])
    t = np.linspace(0.0, 8.0 / omega_n, 40)
    ideal = second_order_step(t, omega_n, zeta)
    b = effective_inertia(B_AIDING, dq)
    q = dq - linear_response(B_AIDING, omega_n**2 * b, 2 * zeta * omega_n * b, dq, t)
    np.testing.assert_allclose(q / dq, np.tile(ideal[:, None], 3), atol=1e-9)
    diag = np.diag(B_AIDING)
    q = dq - linear_response(B_AIDING, omega_n**2 * diag, 2 * zeta * omega_n * diag, dq, t)
    assert np.max(np.abs(q / dq - ideal[:, None])) > 0.05


def test_the_design_keeps_the_pd_step_command_under_the_torque_bound():
    """The PD command at the step's instant is K_P Δq = b ω_n² Δq (b: the effective inertia),
    at most 90 % of the bound: at the bound on the joint it limits, under it elsewhere."""
    from joint_space_control.workbench.tuning.design import TORQUE_MARGIN

    spec = parse_spec("overshoot<=5, peak_torque_ratio<=0.5")
    b = effective_inertia(B_AIDING, [0.2] * 3)
    space = SearchSpace(JOINTS, inertia=tuple(b))
    point = theory_design(spec, space, b, [0.0] * 3, [100.0] * 3, [0.2] * 3)
    kp, _ = space.kp_kd(point)
    command = kp * 0.2
    assert np.all(command <= TORQUE_MARGIN * 0.5 * 100.0 + 1e-9)
    assert command[0] == pytest.approx(TORQUE_MARGIN * 0.5 * 100.0)  # b_1 ω² Δq at the bound
    omega, _ = space.second_order(point)
    assert omega[2] == pytest.approx(10.0)  # the light joint: the default ω_n, under the cap


# --------------------------------------------------------------------------- the space


def test_a_pd_point_with_an_inertia_is_written_as_kp_kd():
    b = (4.0, 0.5, 0.02)
    space = SearchSpace(JOINTS, inertia=b)
    point = space.point(np.array([5.0, 6.0, 7.0]), np.array([0.8, 0.9, 1.0]))
    gains = space.node_gains(point)
    np.testing.assert_allclose(gains["kp"], np.array(b) * [25.0, 36.0, 49.0])
    np.testing.assert_allclose(gains["kd"], 2 * np.array(b) * [4.0, 5.4, 7.0])
    assert gains["omega_n"] == 0.0
    assert choose_gains(3, gains["kp"], gains["kd"], 0.0, 1.0).source == FROM_KP
    omega, zeta = space.second_order(space.time_scaled(point, 1.5))
    np.testing.assert_allclose(omega, [7.5, 9.0, 10.5])
    np.testing.assert_allclose(zeta, [0.8, 0.9, 1.0])
    omega, _ = space.second_order(space.time_scaled(point, 100.0))  # clipped into the box
    np.testing.assert_allclose(omega, space.omega_n[1])


def test_the_zeta_ladder_raises_zeta_keeps_omega_and_stays_in_the_box():
    space = SearchSpace(JOINTS, zeta=(0.5, 1.0))
    point = space.point(np.full(3, 6.0), np.full(3, 0.8))
    ladder = zeta_ladder(point, space)
    zetas = [space.second_order(p)[1][0] for p in ladder]
    assert zetas == pytest.approx([0.8 + ZETA_LADDER[0], 1.0])  # 1.0 and 1.1 clip to one
    for p in ladder:
        np.testing.assert_allclose(space.second_order(p)[0], 6.0)


# --------------------------------------------------------------------------- time scaling


def test_time_scale_divides_the_time_bounds_and_leaves_the_overshoot_alone():
    spec = parse_spec("overshoot<=10, settling_2pct<=1, rise_time<=0.4")
    assert time_scale(spec, [2.0, 1.5, 0.3], 2.0) == pytest.approx(1.5 * SCALE_MARGIN)
    assert time_scale(spec, [2.0, 0.5, 0.39], 2.0) == pytest.approx(0.39 / 0.4 * SCALE_MARGIN)
    assert time_scale(spec, [2.0, 0.5, 0.1], 2.0) is None  # fast enough, with the margin
    assert time_scale(spec, [12.0, 1.5, 0.3], 2.0) is None  # overshoot: not a time matter
    assert time_scale(spec, [2.0, math.inf, 0.3], 2.0) == pytest.approx(2.0 * SCALE_MARGIN)
    torque = parse_spec("settling_2pct<=1, peak_torque_ratio<=0.8")
    assert time_scale(torque, [1.5, 0.2], 2.0) == pytest.approx(1.5 * SCALE_MARGIN)
    assert time_scale(torque, [1.5, 0.5], 2.0) is None  # √(0.8/0.5) < 1.65
    floor = parse_spec("settling_2pct<=1, rise_time>=0.2")
    assert time_scale(floor, [1.2, 0.3], 2.0) == pytest.approx(1.2 * SCALE_MARGIN)
    assert time_scale(floor, [1.2, 0.25], 2.0) is None  # 0.25/1.32 would be under 0.2


def _pd_gravity_run(model: RobotModel, q0, qd, kp, kd, duration: float, dt: float):
    """q(t) of B q̈ + C q̇ = K_P (q_d − q) − K_D q̇ (PD + g, g cancelled), classical RK4."""

    def f(x):
        q, v = x[: model.n], x[model.n :]
        tau = kp * (qd - q) - kd * v
        return np.concatenate(
            [v, np.linalg.solve(model.inertia(q), tau - model.coriolis(q, v) @ v)]
        )

    x = np.concatenate([q0, np.zeros(model.n)])
    out = [x[: model.n].copy()]
    for _ in range(int(round(duration / dt))):
        k1 = f(x)
        k2 = f(x + 0.5 * dt * k1)
        k3 = f(x + 0.5 * dt * k2)
        k4 = f(x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(x[: model.n].copy())
    return np.array(out)


def test_omega_n_times_alpha_runs_the_nonlinear_pd_gravity_loop_alpha_times_faster():
    """q(t) with (K_P, K_D) is q(αt) with (α²K_P, αK_D) on the planar arm's full dynamics."""
    model = RobotModel(resolve_robot("planar_2dof"))
    q0, qd = np.array([-1.0, 0.5]), np.array([-0.6, 0.9])
    b = effective_inertia(model.inertia(q0), qd - q0)
    kp, kd = 9.0 * b, 2 * 0.8 * 3.0 * b
    alpha, dt = 2.0, 2e-3
    slow = _pd_gravity_run(model, q0, qd, kp, kd, 1.0, dt)
    fast = _pd_gravity_run(model, q0, qd, alpha**2 * kp, alpha * kd, 0.5, dt / alpha)
    np.testing.assert_allclose(fast, slow, atol=1e-9)


# --------------------------------------------------------------------------- the study

#: The stand-in's coupled loop settles this much slower than the second order of its gains.
SLOW = 1.8


def coupled_run(b: np.ndarray):
    """execute_run's stand-in for PD + g(q): the second-order response of (K_P/b, K_D/b),
    its settling SLOW times longer (the coupled tails), its overshoot unchanged."""

    def run(scenario, target: Path, short: bool) -> list[FakeResult]:
        p = scenario.parameters
        omega = np.sqrt(np.asarray(p["kp"]) / b)
        zeta = np.asarray(p["kd"]) / (2 * b * omega)
        step = np.subtract(scenario.reference["target"], scenario.plant["initial_positions"])
        metrics = controller_metrics(omega, zeta, tuple(step), scenario.duration)
        for entry in metrics["steps"][0]["joints"].values():
            for key in ("settling_time_2", "settling_time_5"):
                slow = None if entry[key] is None else SLOW * entry[key]
                entry[key] = slow if slow is not None and slow <= scenario.duration else None
        return [FakeResult(metrics, None, target)]

    return run


def test_the_shared_stage_time_scales_the_design_and_a_seeded_study_repeats(tmp_path):
    def study(out: Path) -> list[tuple]:
        o = TuneOptions(
            "planar_2dof",
            "pd_gravity",
            "overshoot<=10, settling_2pct<=1",
            trials=10,
            out=out,
            q0=(-1.5708, 0.0),
        )
        b = np.asarray(prepare(o).space.inertia)
        logs: list[str] = []
        code = tune_cli.run(o, ThreadPool, coupled_run(b), log=logs.append)
        report = (out / "report.md").read_text()
        return code, logs, report

    code, logs, report = study(tmp_path / "a")
    assert code == 0
    assert any(m.startswith("trial 0 is the theory's design") for m in logs)
    # trial 0 misses (SLOW × its second-order settling), trials 4-7 are 0-3 time-scaled
    assert "| 0 | missed (theory's design) |" in report
    for k, dz in enumerate(ZETA_LADDER, start=1):
        assert f"| {k} | missed (design, ζ + {dz:g}) |" in report
    assert "| 4 | met (trial 0, ω_n × " in report
    again = study(tmp_path / "b")
    table = [line for line in report.splitlines() if line.startswith("| ")]
    table_again = [line for line in again[2].splitlines() if line.startswith("| ")]
    strip = [line.rsplit("|", 2)[0] for line in table]  # the last column: wall time
    assert strip == [line.rsplit("|", 2)[0] for line in table_again]
