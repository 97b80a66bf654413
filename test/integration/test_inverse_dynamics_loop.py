"""Inverse dynamics and feedforward + PD in a real ROS 2 loop: runtime changes of the law, the
gains and the model through the parameter services.

Nominal second-order behaviour, decoupling, model mismatch and saturation (THEORY.md §3,
experiments 6–8) are checked on the in-process engine (test/unit/test_inprocess.py)."""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.model.dynamics import ModelPerturbation, RobotModel
from joint_space_control.model.robots import resolve_robot
from test.loops import ID_CASES as CASES

from .conftest import JOINTS

pytestmark = pytest.mark.integration

CONTROLLER = "inverse_dynamics_controller"


def id_loop(make_loop, robot: str, law: str = "inverse_dynamics", sim=None, **params):
    case = CASES[robot]
    return make_loop(
        robot,
        {"law": law, "omega_n": case["omega_n"], "zeta": case["zeta"], **params},
        controller=CONTROLLER,
        sim_params={"initial_positions": case["q0"], **(sim or {})},
    )


def test_runtime_changes_of_law_gains_and_model_are_validated(make_loop):
    robot = "planar_2dof"
    case = CASES[robot]
    q0 = np.array(case["q0"])
    target = q0 + case["step"]
    loop = id_loop(make_loop, robot, sim={"pause_at": 0.5})
    loop.start(JOINTS[robot], [target])
    # The plant pauses itself at t = 0.5 s while the parameters change: the new law and
    # model act from there however fast the loop runs compared to the service calls (a
    # pause asked for by a call came, under load, after the loop had passed t = 3 s).
    loop.hold_at(0.5)
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
