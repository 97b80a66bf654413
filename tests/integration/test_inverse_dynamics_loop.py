"""Inverse dynamics and feedforward + PD in closed loop (THEORY.md §3, experiments 6–8):
nominal second-order behaviour, decoupling, model mismatch, saturation."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.analysis.metrics import (
    second_order_prediction,
    step_metrics_per_joint,
    tracking_error,
)
from joint_space_control.analysis.run_metrics import analyze_bag
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot

from .conftest import JOINTS

pytestmark = pytest.mark.integration

CONTROLLER = "inverse_dynamics_controller"
#: Start configurations and steps whose peak torque B(q0)K_PΔ + g(q0) stays well inside the
#: effort limits (the second-order theory holds only without saturation).
CASES = {
    "planar_2dof": {
        "q0": [-1.0, 0.5],
        "omega_n": [8.0, 12.0],
        "zeta": [0.5, 0.8],
        "step": [0.1, -0.15],
        "duration": 2.5,
    },
    "iiwa": {
        "q0": [0.0, 0.3, 0.0, -1.2, 0.0, 0.6, 0.0],
        "omega_n": [8.0, 8.0, 10.0, 10.0, 12.0, 12.0, 12.0],
        "zeta": [0.5, 0.6, 0.7, 0.5, 0.6, 0.7, 0.8],
        "step": [0.1, -0.1, 0.1, 0.1, -0.1, 0.1, 0.1],
        "duration": 2.5,
    },
}
T_S = 1e-3  # control period [s]


def id_loop(make_loop, robot: str, law: str = "inverse_dynamics", **params):
    case = CASES[robot]
    return make_loop(
        robot,
        {"law": law, "omega_n": case["omega_n"], "zeta": case["zeta"], **params},
        controller=CONTROLLER,
        sim_params={"initial_positions": case["q0"]},
    )


@pytest.mark.parametrize("robot", list(CASES))
def test_nominal_step_response_is_the_second_order_theory(make_loop, robot):
    case = CASES[robot]
    q0, step = np.array(case["q0"]), np.array(case["step"])
    loop = id_loop(make_loop, robot)
    loop.start(JOINTS[robot], [q0 + step])
    loop.run_until(case["duration"])
    t, q, _, _ = loop.probe.recording.arrays()

    measured = step_metrics_per_joint(t, q, targets=q0 + step, t_step=0.0)
    theory = second_order_prediction(case["omega_n"], case["zeta"])
    for j, m in enumerate(measured):
        name = JOINTS[robot][j]
        assert abs(m.overshoot_percent - theory["overshoot_percent"][j]) < 1.0, name
        ts2 = theory["settling_time_2"][j]
        assert abs(m.settling_time_2 - ts2) <= max(0.05 * ts2, T_S), (name, m, ts2)
        assert m.abs_steady_state_error < 1e-4, (name, m)


@pytest.mark.parametrize(("robot", "moved"), [("planar_2dof", 0), ("iiwa", 1)])
def test_nominal_inverse_dynamics_decouples_the_joints(make_loop, robot, moved):
    case = CASES[robot]
    q0 = np.array(case["q0"])
    target = q0.copy()
    target[moved] += 0.15
    loop = id_loop(make_loop, robot)
    loop.start(JOINTS[robot], [target])
    loop.run_until(1.0)
    _, q, _, _ = loop.probe.recording.arrays()
    others = np.delete(np.abs(q - q0).max(axis=0), moved)
    assert np.abs(q[:, moved] - q0[moved]).max() > 0.1  # the moved joint did move
    assert others.max() < 1e-3, others


def sinusoid(q0: np.ndarray, amplitude: np.ndarray, omega: float, duration: float):
    """q_d = q0 + Δ(1 − cos ωt): starts at rest on q0; exact q, q̇, q̈ every 10 ms."""
    t = np.arange(0.0, duration + 1e-9, 0.01)
    c, s = np.cos(omega * t)[:, None], np.sin(omega * t)[:, None]
    return t, q0 + amplitude * (1 - c), amplitude * omega * s, amplitude * omega**2 * c


def tracking_rms(make_loop, law: str, plant_payload: float = 0.0, **model) -> np.ndarray:
    robot = "planar_2dof"
    q0 = np.array(CASES[robot]["q0"])
    t_ref, pos, vel, acc = sinusoid(q0, np.array([0.3, 0.4]), 2 * np.pi * 0.5, 2.0)
    params = {"omega_n": 10.0, "zeta": 1.0} if law == "inverse_dynamics" else {}
    if law == "feedforward_pd":  # the PD part as stiff as inverse dynamics' at q0
        params = {"kp": [6000.0, 2250.0], "kd": [1200.0, 450.0]}
    loop = make_loop(
        robot,
        {"law": law, **params, **model},
        controller=CONTROLLER,
        sim_params={"initial_positions": q0.tolist(), "payload_mass": plant_payload},
    )
    loop.start(JOINTS[robot], pos, t_ref, vel, acc)
    loop.run_until(2.0)
    t, q, _, _ = loop.probe.recording.arrays()
    q_d = np.array([np.interp(t, t_ref, pos[:, j]) for j in range(2)]).T
    rms = tracking_error(t, q, q_d, t_start=0.5)["rms"]
    loop.close()
    return rms


def test_mass_error_and_payload_degrade_tracking_for_both_laws(make_loop):
    """Experiment 7: the same sinusoid with the nominal model, with a model 20 % too light,
    and (inverse dynamics) with an unmodelled 10 kg payload on the plant."""
    results = {}
    for law in ("inverse_dynamics", "feedforward_pd"):
        nominal = tracking_rms(make_loop, law)
        light_model = tracking_rms(make_loop, law, model_mass_scale=0.8)
        results[law] = (nominal, light_model)
        assert np.all(light_model > 10 * nominal), (law, nominal, light_model)
    payload = tracking_rms(make_loop, "inverse_dynamics", plant_payload=10.0)
    assert np.all(payload > 10 * results["inverse_dynamics"][0]), (payload, results)
    # With a perfect model what is left is the sampled-data error: the torque is held over
    # each 1 ms period, a lag of about T/2 on a reference moving at up to 0.94 rad/s.
    assert results["inverse_dynamics"][0].max() < 5e-4, results


def test_large_omega_n_saturates_and_the_state_shows_it(make_loop, tmp_path):
    """Experiment 8: the peak torque grows like ω_n²; beyond the limits the command is
    clamped, and ~/state carries both the law's torque and the one sent."""
    robot = "planar_2dof"
    case = CASES[robot]
    q0 = np.array(case["q0"])
    peaks = {}
    for omega in (8.0, 60.0):
        loop = make_loop(
            robot,
            {"omega_n": omega, "zeta": 1.0},
            controller=CONTROLLER,
            sim_params={"initial_positions": q0.tolist()},
            record=tmp_path / f"bag_{omega:g}",
        )
        loop.start(JOINTS[robot], [q0 + [0.1, -0.15]])
        loop.run_until(0.8)
        loop.close()
        (controller,) = analyze_bag(loop.bag).controllers
        state, demand = controller.state.rows, controller.metrics["torque_demand"]
        limits = np.array([2000.0, 1000.0])
        assert list(demand["effort_limits"].values()) == limits.tolist()  # from ~/config
        saturated = np.array(list(demand["saturated_fraction"].values()))
        peaks[omega] = np.abs(state["tau_unclamped"]).max(axis=0)
        assert np.all(np.abs(state["tau"]) <= limits + 1e-9)  # never beyond the limits
        if omega == 8.0:
            np.testing.assert_array_equal(state["tau"], state["tau_unclamped"])
            assert np.all(saturated == 0.0)
        else:
            assert np.any(np.abs(state["tau_unclamped"]) > limits)  # the law asked for more
            assert np.any(saturated > 0.0)
    # K_P = ω_n²: the initial torque B(q0) K_P Δ grows by (60/8)² ≈ 56 before clamping
    assert np.all(peaks[60.0] > 20 * (peaks[8.0] - 700.0)), peaks


def test_runtime_changes_of_law_gains_and_model_are_validated(make_loop):
    robot = "planar_2dof"
    case = CASES[robot]
    q0 = np.array(case["q0"])
    target = q0 + case["step"]
    loop = id_loop(make_loop, robot)
    loop.start(JOINTS[robot], [target])
    loop.run_until(0.5)
    # Paused while the parameters change: the new law and model act from t ≈ 0.5 s however
    # fast the loop runs compared to the parameter service calls.
    loop.pause()
    bad_updates = [
        {"law": "computed_torque"},
        {"omega_n": -3.0},
        {"omega_n": [10.0, 10.0, 10.0]},
        {"zeta": -0.5},
        {"model_mass_scale": 0.0},
        {"model_payload_mass": -1.0},
        {"model_friction": [float("nan"), 0.0]},
        {"model_gravity": "yes"},
    ]
    for update in bad_updates:
        (result,) = loop.probe.set_parameters(loop.controller, update)
        assert not result.successful, f"{update} was accepted"
        assert result.reason, f"{update} rejected without a reason"
    law, omega = loop.probe.get_parameters(loop.controller, ["law", "omega_n"])
    assert law == "inverse_dynamics" and list(omega) == case["omega_n"]

    good = {"law": "feedforward_pd", "omega_n": 0.0, "kp": 4000.0, "kd": 800.0}
    assert all(r.successful for r in loop.probe.set_parameters(loop.controller, good))
    (mass,) = loop.probe.set_parameters(loop.controller, {"model_mass_scale": [1.0, 1.1]})
    assert mass.successful, mass.reason
    loop.resume()
    loop.run_until(3.0)
    q_e, _ = loop.final_state()
    # Feedforward + PD with a constant reference is PD + ĝ(q); with link 2 modelled 10 %
    # too heavy it settles where K_P (q_d − q_e) = g(q_e) − ĝ(q_e).
    spec = resolve_robot(robot)
    g, g_hat = (
        RobotModel(spec, perturbation=ModelPerturbation(mass_scale=s)).gravity(q_e)
        for s in ([1.0, 1.0], [1.0, 1.1])
    )
    assert np.max(np.abs(target - q_e)) > 1e-3  # a visible offset ...
    np.testing.assert_allclose(4000.0 * (target - q_e), g - g_hat, rtol=0.01)  # as predicted
