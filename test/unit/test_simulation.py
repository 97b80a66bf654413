"""The closed loop in Python: ``simulate()`` against the theory, the policy a node shares
with it, and the run measured from memory equal to the same run measured from its bag."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.analysis.run_metrics import analyze_bag
from joint_space_control.control.configure import PD_GRAVITY
from joint_space_control.control.policy import ControlPolicy, Kind, Taken
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.simulation import Arm, Change, LoopError, World, simulate
from joint_space_control.trajectories.reference import Trajectory
from joint_space_control.workbench.experiments.execution.inprocess import InProcessLoop
from joint_space_control.workbench.experiments.scenarios.format import RobotSetup

ENGINES = ("pybullet", "mujoco")


@pytest.mark.parametrize("engine", ENGINES)
def test_nominal_inverse_dynamics_is_the_second_order_step(engine):
    """THEORY.md §3: nominal inverse dynamics makes every joint the second-order loop of
    its ω_n, ζ: with ζ = 1 a step has no overshoot and settles to 2 % at the closed-form
    critically damped time (ω_n t = 5.834), here within 1 % (the sampled loop lags the
    continuous one by about a period; the experiments' check allows 5 %). The arm hangs
    (q0 = (−π/2, 0)) so that the step's torque stays inside the limits."""
    omega = 8.0
    q0 = [-math.pi / 2, 0.0]
    r = simulate(
        "planar_2dof",
        "inverse_dynamics",
        target=[q0[0] + 0.1, 0.1],
        duration=2.5,
        parameters={"omega_n": omega, "zeta": 1.0},
        plant={"engine": engine, "initial_positions": q0},
    )
    info = r.step_info()
    assert set(info) == {"joint1", "joint2"}
    for joint in info.values():
        assert joint["overshoot_percent"] < 0.05
        assert joint["settling_time_2"] == pytest.approx(5.834 / omega, rel=0.01)
    np.testing.assert_allclose(r.q[-1], [q0[0] + 0.1, 0.1], atol=1e-6)
    assert np.all(np.abs(r.tau) < np.array(r.config["effort_limits"]))  # never saturated


def test_pd_without_gravity_settles_where_the_spring_holds_gravity():
    """THEORY.md §2: PD without gravity compensation settles at q_e with
    K_P (q_d − q_e) = g(q_e): the controller model's own g at the final state."""
    r = simulate(
        "planar_2dof",
        "pd_gravity",
        target=[0.5, -0.3],
        duration=6.0,
        parameters={"gravity_compensation": "none", "kp": [4000.0, 2000.0], "kd": [800, 400]},
    )
    model = RobotModel(resolve_robot("planar_2dof"))
    q_e = r.q[-1]
    kp = np.array([4000.0, 2000.0])
    assert np.all(np.abs(r.dq[-1]) < 1e-5)  # at rest
    np.testing.assert_allclose(kp * (np.array([0.5, -0.3]) - q_e), model.gravity(q_e), rtol=1e-5)
    assert np.all(np.abs(r.error[-1]) > 1e-3)  # an offset, not zero


def test_the_response_holds_the_split_and_the_command_on_the_state_grid():
    r = simulate("planar_2dof", "pd_gravity", target=[0.1, 0.1], duration=0.5)
    n = len(r.joints)
    assert r.t.shape == (501,) and r.q.shape == (501, n) == r.tau.shape == r.q_d.shape
    np.testing.assert_allclose(r.t[1] - r.t[0], 1e-3)
    # the split adds up to the law's torque; the command is it, clamped
    total = r.tau_feedback + r.tau_model + r.tau_gravity
    np.testing.assert_allclose(total, r.tau_unclamped, rtol=0, atol=1e-9)
    limits = np.array(r.config["effort_limits"])
    np.testing.assert_array_equal(r.tau, np.clip(r.tau_unclamped, -limits, limits))
    # the torque applied over a period is the command answering the state before it
    np.testing.assert_array_equal(r.tau_applied[1:], r.tau[:-1])
    assert r.law == "pd_gravity" and r.robot == "planar_2dof"


def test_a_control_period_longer_than_the_plants_holds_the_command():
    """rate 250 Hz over states at 1 kHz: a step is computed at every 4th state and held
    over the three between, as the node answers them."""
    r = simulate(
        "planar_2dof", "pd_gravity", target=[0.1, 0.1], duration=0.2, parameters={"rate": 250.0}
    )
    assert len(r.steps) == 51 and len(r.t) == 201
    np.testing.assert_array_equal(r.step_index, np.arange(201) // 4)
    np.testing.assert_array_equal(r.tau[1:4], np.repeat(r.tau[:1], 3, axis=0))


def test_a_scheduled_change_lands_at_its_time():
    """A change of ω_n at 0.5 s: the configuration after it carries the new gains, and the
    event says when."""
    r = simulate(
        "planar_2dof",
        "inverse_dynamics",
        target=[0.2, 0.2],
        duration=1.0,
        changes=[Change(0.5, {"omega_n": 5.0})],
    )
    assert r.events[0]["t"] == 0.5 and r.events[-1]["end"]
    np.testing.assert_array_equal(r.config["kp"], [25.0, 25.0])
    first = next(doc for _, doc in r.configs if doc["kp"] is not None)
    np.testing.assert_array_equal(first["kp"], [100.0, 100.0])  # the default ω_n = 10 rad/s


def test_bad_input_is_one_clear_error():
    with pytest.raises(ValueError, match="2 joints|values per point"):
        simulate("planar_2dof", "pd_gravity", target=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="outside its limits"):
        simulate("planar_2dof", "pd_gravity", target=[100.0, 0.0])
    with pytest.raises(ValueError, match="kp"):
        simulate("planar_2dof", "pd_gravity", target=[0.1, 0.1], parameters={"kp": -1.0})
    with pytest.raises(ValueError, match="unknown"):
        simulate("planar_2dof", "pd_gravity", parameters={"no_such_gain": 1.0})
    with pytest.raises(ValueError, match="non-finite"):
        simulate("planar_2dof", "pd_gravity", target=[math.nan, 0.0])
    with pytest.raises(ValueError, match="joints"):
        simulate(
            "planar_2dof",
            "pd_gravity",
            reference={"joints": ["joint1", "elbow"], "positions": [[0, 0]], "times": [0.0]},
        )
    with pytest.raises(LoopError, match="lockstep only"):
        World([Arm()], {"mode": "realtime"})


def test_a_run_from_memory_measures_as_its_bag(tmp_path):
    """The in-process run analysed from memory and the same run written as the recorder
    records it and read back give the same metrics, to the last bit."""
    setup = RobotSetup("", "planar_2dof", {}, "pd_gravity_controller", {"rate": 500.0}, {})
    loop = InProcessLoop([setup], {"position_noise": 1e-4}, tmp_path / "bag")
    loop.send_reference("", ["joint1", "joint2"], [[0.2, -0.1]], [0.0])
    loop.run_until(0.6)
    response = loop.response()
    loop.close()
    (from_bag,) = analyze_bag(tmp_path / "bag").controllers
    assert response.metrics() == from_bag.metrics
    np.testing.assert_array_equal(response.steps.log_time, from_bag.state.log_time)
    assert response.q_true is not None and not np.array_equal(response.q_true, response.q)


def test_the_policy_answers_a_state_once_and_holds_within_a_period():
    values = PD_GRAVITY.values(robot="planar_2dof", rate=500.0)
    policy = ControlPolicy(PD_GRAVITY, values)
    q, dq = np.zeros(2), np.zeros(2)
    first = policy.answer(0, q, dq)
    assert first.kind is Kind.COMPUTED and first.designed  # gains designed at q0
    assert policy.answer(0, q, dq).kind is Kind.REPEATED
    held = policy.answer(1_000_000, q, dq)  # 1 ms later, inside the 2 ms period
    assert held.kind is Kind.HELD and held.step is first.step
    assert policy.answer(2_000_000, q, dq).kind is Kind.COMPUTED


def test_the_policy_sends_nothing_for_a_state_it_cannot_answer():
    """No command for a non-finite state (the reason given), nor for a state without the
    velocity the law must measure. (A non-finite torque: test_inprocess.py.)"""
    policy = ControlPolicy(PD_GRAVITY, PD_GRAVITY.values(robot="planar_2dof"))
    answer = policy.answer(0, np.array([np.nan, 0.0]), np.zeros(2))
    assert answer.kind is Kind.NONE and answer.tau is None and "non-finite" in answer.reason
    measured = ControlPolicy(
        PD_GRAVITY, PD_GRAVITY.values(robot="planar_2dof", velocity_source="measured")
    )
    missing = measured.answer(0, np.zeros(2), np.zeros(0))
    assert missing.kind is Kind.NONE and missing.step is None and "velocity" in missing.reason


def test_the_policy_takes_references_in_the_order_they_arrived():
    policy = ControlPolicy(PD_GRAVITY, PD_GRAVITY.values(robot="planar_2dof"))
    traj = Trajectory.build(0.0, [0.0], [[0.1, 0.1]])
    first, second = policy.arrive(), policy.arrive()
    assert policy.take_reference(traj, second) is Taken.TAKEN
    assert policy.take_reference(traj, first) is Taken.SUPERSEDED
    assert policy.take_reference("no points", policy.arrive()) is Taken.REJECTED
    late = policy.arrive()
    policy.restart()
    assert policy.take_reference(traj, late) is Taken.FORGOTTEN


def test_the_policy_swaps_a_parameter_change_whole_or_not_at_all():
    policy = ControlPolicy(PD_GRAVITY, PD_GRAVITY.values(robot="planar_2dof", kp=100.0))
    before, values = policy.core.config, dict(policy.values)
    with pytest.raises(ValueError, match="ki"):
        policy.set_parameters({"kd": 5.0, "ki": -1.0})  # one invalid: nothing changes
    assert policy.core.config is before and dict(policy.values) == values
    policy.set_parameters({"kp": 200.0, "kd": 5.0})
    assert policy.core.config.gains.kp.tolist() == [200.0, 200.0]
    assert policy.values["kd"] == 5.0
