"""The closed loop against the theory on the in-process engine (THEORY.md §2, §3): the same
plant, controller objects and sub-step loop as the nodes' lockstep, without processes; every
test on both physics engines of the plant (PyBullet and MuJoCo).

These were integration tests of node processes; the ROS engine gives the same numbers bit
for bit (test/integration/test_experiments.py compares every scenario on both engines), so
the theory is checked here, fast, and the node processes are tested for what needs them.
Tolerances as before: a set-point to 1e-3 rad; the pure-PD equilibrium residual
g(q_e) − K_P(q_d − q_e) to 1e-3 N·m; second-order overshoot to 1 point and 2 % settling to
5 % (or one control period), steady-state error < 1e-4 rad.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from joint_space_control.analysis.metrics import (
    second_order_prediction,
    step_metrics_per_joint,
    tracking_error,
)
from joint_space_control.analysis.run_metrics import analyze_bag
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.workbench.experiments.execution.inprocess import (
    EngineError,
    InProcessLoop,
)
from joint_space_control.workbench.experiments.scenarios.format import RobotSetup
from sim_bridge.engines import ENGINES
from test.corpus import BY_NAME, PACKAGE_PATHS
from test.loops import GAINS, ID_CASES, SETPOINTS
from test.unit.test_corpus import step_inside_limits

T_S = 1e-3  # control period [s]
CONTROLLER = "inverse_dynamics_controller"
CASES = ID_CASES


@pytest.fixture(params=ENGINES)
def make_loop(request):
    """Factory of in-process loops of one robot, all closed at the end: every test that
    makes one runs on each physics engine of the plant (issue 26: the theory on both, to
    the same tolerances)."""
    loops: list[InProcessLoop] = []

    def make(
        robot: str,
        controller: str = "pd_gravity_controller",
        params: dict[str, Any] | None = None,
        sim: dict[str, Any] | None = None,
        record: Path | None = None,
    ) -> InProcessLoop:
        setup = RobotSetup("", robot, {}, controller, dict(params or {}), {})
        loop = InProcessLoop([setup], {"engine": request.param, **(sim or {})}, record)
        loops.append(loop)
        return loop

    yield make
    for loop in loops:
        loop.close()


def start(loop: InProcessLoop, *reference: Any) -> None:
    loop.send_reference("", loop.controllers[0].joints, *reference)


def final(loop: InProcessLoop) -> tuple[np.ndarray, np.ndarray]:
    _, q, dq, _ = loop.arrays()
    return q[-1], dq[-1]


# -- PD + gravity compensation (§2) --------------------------------------------------------
@pytest.mark.parametrize("robot", ["planar_2dof", "iiwa"])
def test_pd_gravity_converges_to_setpoint(make_loop, robot):
    loop = make_loop(robot, params={**GAINS[robot], "gravity_compensation": "full"})
    q_d = np.array(SETPOINTS[robot])
    start(loop, [q_d], [0.0])
    loop.run_until(6.0)
    q, dq = final(loop)
    assert np.max(np.abs(q_d - q)) < 1e-3, f"final error {q_d - q}"
    assert np.max(np.abs(dq)) < 1e-2


@pytest.mark.parametrize("robot", ["planar_2dof", "iiwa"])
def test_pure_pd_settles_at_predicted_offset_then_full_gravity_removes_it(make_loop, robot):
    loop = make_loop(robot, params={**GAINS[robot], "gravity_compensation": "none"})
    q_d = np.array(SETPOINTS[robot])
    start(loop, [q_d], [0.0])
    loop.run_until(8.0)
    q_e, _ = final(loop)
    assert np.max(np.abs(q_d - q_e)) > 1e-2, "pure PD should leave a visible offset"
    # g(q_e) − K_P (q_d − q_e), with an independent Pinocchio model of the same URDF
    residual = RobotModel(resolve_robot(robot)).gravity(q_e) - np.array(GAINS[robot]["kp"]) * (
        q_d - q_e
    )
    assert np.max(np.abs(residual)) < 1e-3, f"g(q_e) - K_P(q_d - q_e) = {residual}"
    loop.set_controller("", {"gravity_compensation": "full"})
    loop.run_until(16.0)
    q, _ = final(loop)
    assert np.max(np.abs(q_d - q)) < 1e-3, f"offset left after switching to full: {q_d - q}"


def test_two_runs_are_bit_identical(make_loop):
    runs = []
    for _ in range(2):
        loop = make_loop("planar_2dof", params=GAINS["planar_2dof"])
        start(loop, [SETPOINTS["planar_2dof"]], [0.0])
        loop.run_until(2.0)
        runs.append(loop.arrays())
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
    assert len(runs[0][0]) == 2001  # 0 … 2 s at 1 kHz


def test_invalid_values_are_refused_with_the_reason_and_the_loop_keeps_its_own(make_loop):
    loop = make_loop("planar_2dof", params=GAINS["planar_2dof"])
    start(loop, [SETPOINTS["planar_2dof"]], [0.0])
    loop.run_until(0.5)
    for update, reason in [
        ({"kp": -5.0}, "'kp' must be >= 0"),
        ({"kp": [100.0, 100.0, 100.0]}, "kp"),
        ({"kd": float("nan")}, "finite"),
        ({"gravity_compensation": "sometimes"}, "sometimes"),
        ({"robot": "iiwa"}, "robot: read-only"),
        ({"no_such_gain": 1.0}, "no such parameter"),
    ]:
        with pytest.raises(EngineError, match="rejected") as err:
            loop.set_controller("", update)
        assert reason in str(err.value), (update, err.value)
    assert loop.controllers[0].core.config.gains.kp.tolist() == GAINS["planar_2dof"]["kp"]
    with pytest.raises(EngineError, match="payload_mass"):
        loop.set_plant({"payload_mass": -1.0})
    loop.run_until(6.0)
    assert np.max(np.abs(np.array(SETPOINTS["planar_2dof"]) - final(loop)[0])) < 1e-3


def test_realtime_is_refused_in_one_line():
    setup = RobotSetup("", "planar_2dof", {}, "pd_gravity_controller", {}, {})
    with pytest.raises(EngineError, match="lockstep only") as err:
        InProcessLoop([setup], {"mode": "realtime"})
    assert "\n" not in str(err.value)


# -- inverse dynamics (§3) -----------------------------------------------------------------
def id_loop(make_loop, robot: str, law: str = "inverse_dynamics", **params: Any):
    case = CASES[robot]
    return make_loop(
        robot,
        CONTROLLER,
        {"law": law, "omega_n": case["omega_n"], "zeta": case["zeta"], **params},
        {"initial_positions": case["q0"]},
    )


@pytest.mark.parametrize("robot", list(CASES))
def test_nominal_step_response_is_the_second_order_theory(make_loop, robot):
    case = CASES[robot]
    q0, step = np.array(case["q0"]), np.array(case["step"])
    loop = id_loop(make_loop, robot)
    start(loop, [q0 + step], [0.0])
    loop.run_until(case["duration"])
    t, q, _, _ = loop.arrays()
    theory = second_order_prediction(case["omega_n"], case["zeta"])
    for j, m in enumerate(step_metrics_per_joint(t, q, targets=q0 + step, t_step=0.0)):
        assert abs(m.overshoot_percent - theory["overshoot_percent"][j]) < 1.0, j
        ts2 = theory["settling_time_2"][j]
        assert abs(m.settling_time_2 - ts2) <= max(0.05 * ts2, T_S), (j, m, ts2)
        assert m.abs_steady_state_error < 1e-4, (j, m)


@pytest.mark.parametrize(("robot", "moved"), [("planar_2dof", 0), ("iiwa", 1)])
def test_nominal_inverse_dynamics_decouples_the_joints(make_loop, robot, moved):
    q0 = np.array(CASES[robot]["q0"])
    target = q0.copy()
    target[moved] += 0.15
    loop = id_loop(make_loop, robot)
    start(loop, [target], [0.0])
    loop.run_until(1.0)
    _, q, _, _ = loop.arrays()
    others = np.delete(np.abs(q - q0).max(axis=0), moved)
    assert np.abs(q[:, moved] - q0[moved]).max() > 0.1  # the moved joint did move
    assert others.max() < 1e-3, others


def tracking_rms(make_loop, law: str, plant_payload: float = 0.0, **model: Any) -> np.ndarray:
    """RMS tracking error of q0 + Δ(1 − cos ωt) (exact q, q̇, q̈ every 10 ms) after 0.5 s."""
    q0 = np.array(CASES["planar_2dof"]["q0"])
    amplitude, omega = np.array([0.3, 0.4]), 2 * np.pi * 0.5
    t_ref = np.arange(0.0, 2.0 + 1e-9, 0.01)
    c, s = np.cos(omega * t_ref)[:, None], np.sin(omega * t_ref)[:, None]
    pos, vel, acc = q0 + amplitude * (1 - c), amplitude * omega * s, amplitude * omega**2 * c
    params = {"omega_n": 10.0, "zeta": 1.0} if law == "inverse_dynamics" else {}
    if law == "feedforward_pd":  # the PD part as stiff as inverse dynamics' at q0
        params = {"kp": [6000.0, 2250.0], "kd": [1200.0, 450.0]}
    loop = make_loop(
        "planar_2dof",
        CONTROLLER,
        {"law": law, **params, **model},
        {"initial_positions": q0.tolist(), "payload_mass": plant_payload},
    )
    start(loop, pos, t_ref, vel, acc)
    loop.run_until(2.0)
    t, q, _, _ = loop.arrays()
    q_d = np.array([np.interp(t, t_ref, pos[:, j]) for j in range(2)]).T
    return tracking_error(t, q, q_d, t_start=0.5)["rms"]


def test_mass_error_and_payload_degrade_tracking_for_both_laws(make_loop):
    """Experiment 7: the nominal model, a model 20 % too light, an unmodelled 10 kg payload."""
    nominal = {}
    for law in ("inverse_dynamics", "feedforward_pd"):
        nominal[law] = tracking_rms(make_loop, law)
        light_model = tracking_rms(make_loop, law, model_mass_scale=0.8)
        assert np.all(light_model > 10 * nominal[law]), (law, nominal[law], light_model)
    payload = tracking_rms(make_loop, "inverse_dynamics", plant_payload=10.0)
    assert np.all(payload > 10 * nominal["inverse_dynamics"]), (payload, nominal)
    # with a perfect model what is left is the sampled-data error (a lag of about T/2)
    assert nominal["inverse_dynamics"].max() < 5e-4, nominal


def test_large_omega_n_saturates_and_the_recorded_state_shows_it(make_loop, tmp_path):
    """Experiment 8: the peak torque grows like ω_n²; beyond the limits the command is
    clamped, and the recorded ~/state carries the law's torque and the one sent."""
    q0 = np.array(CASES["planar_2dof"]["q0"])
    limits = np.array([2000.0, 1000.0])
    peaks = {}
    for omega in (8.0, 60.0):
        bag = tmp_path / f"bag_{omega:g}"
        loop = make_loop(
            "planar_2dof",
            CONTROLLER,
            {"omega_n": omega, "zeta": 1.0},
            {"initial_positions": q0.tolist()},
            record=bag,
        )
        start(loop, [q0 + [0.1, -0.15]], [0.0])
        loop.run_until(0.8)
        loop.close()
        (controller,) = analyze_bag(bag).controllers
        state, demand = controller.state.rows, controller.metrics["torque_demand"]
        assert list(demand["effort_limits"].values()) == limits.tolist()  # from ~/config
        saturated = np.array(list(demand["saturated_fraction"].values()))
        peaks[omega] = np.abs(state["tau_unclamped"]).max(axis=0)
        assert np.all(np.abs(state["tau"]) <= limits + 1e-9)
        if omega == 8.0:
            np.testing.assert_array_equal(state["tau"], state["tau_unclamped"])
            assert np.all(saturated == 0.0)
        else:
            assert np.any(np.abs(state["tau_unclamped"]) > limits)
            assert np.any(saturated > 0.0)
    assert np.all(peaks[60.0] > 20 * (peaks[8.0] - 700.0)), peaks


def test_a_non_finite_torque_ends_the_run_with_the_reason(make_loop):
    loop = make_loop("planar_2dof", params=GAINS["planar_2dof"])
    start(loop, [SETPOINTS["planar_2dof"]], [0.0])
    loop.run_until(0.1)
    core = loop.controllers[0].core  # a u that no parameter can give (they are checked)
    core.set_config(dataclasses.replace(core.config, gravity_estimate=np.full(2, np.nan)))
    with pytest.raises(EngineError, match="non-finite torque"):
        loop.run_until(0.2)


# -- robots nobody here wrote (test/corpus.py) --------------------------------------------
def corpus_loop(make_loop, name: str, controller: str, params: dict[str, Any]):
    robot = BY_NAME[name]
    model = RobotModel(resolve_robot(urdf_path=str(robot.path), package_paths=PACKAGE_PATHS))
    q0, target = step_inside_limits(model)
    sim = {**robot.params(), "initial_positions": q0.tolist()}
    loop = make_loop(name, controller, {**robot.params(), **params}, sim)
    return loop, model, q0, target


@pytest.mark.parametrize("name", ["kinova", "z1"])
def test_pd_gravity_on_its_defaults_settles_a_step(make_loop, name):
    loop, model, q0, target = corpus_loop(make_loop, name, "pd_gravity_controller", {})
    start(loop, [target.tolist()], [0.0])
    loop.run_until(4.0)
    q, _ = final(loop)
    assert np.max(np.abs(q - target)) < 1e-3, name
    assert np.max(np.abs(q - q0)) > 0.01


@pytest.mark.parametrize("name", ["ur5", "xarm7", "so101"])
def test_inverse_dynamics_is_the_second_order_theory_on_corpus_robots(make_loop, name):
    omega_n, zeta = 10.0, 0.6
    params = {"law": "inverse_dynamics", "omega_n": omega_n, "zeta": zeta}
    loop, model, q0, target = corpus_loop(make_loop, name, CONTROLLER, params)
    start(loop, [target.tolist()], [0.0])
    loop.run_until(2.0)
    t, q, _, _ = loop.arrays()
    theory = second_order_prediction(omega_n, zeta)
    for j, m in enumerate(step_metrics_per_joint(t, q, targets=target, t_step=0.0)):
        assert abs(m.overshoot_percent - theory["overshoot_percent"]) < 1.0, (j, m)
        ts2 = theory["settling_time_2"]
        assert abs(m.settling_time_2 - ts2) <= max(0.05 * ts2, T_S), (j, m, ts2)
        assert m.abs_steady_state_error < 1e-4, (j, m)
