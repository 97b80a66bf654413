"""Closed loops of real nodes on robot descriptions nobody here wrote (tests/corpus.py).

Every corpus robot is checked in process against the defaults (tests/unit/test_corpus.py);
here a few of them run as separate node processes in lockstep:
- PD + g(q) on the controller's defaults alone (gains from the default ω_n/ζ design) settles a
  0.05 rad step to < 1e-3 rad within 4 s of simulated time;
- inverse dynamics (eq. 15) reproduces the second-order overshoot and 2 % settling time of
  its ω_n/ζ on every joint, with the tolerances of test_inverse_dynamics_loop.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.analysis.metrics import second_order_prediction, step_metrics_per_joint
from joint_space_control.experiments.loop import ClosedLoop
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from tests.corpus import BY_NAME, PACKAGE_PATHS
from tests.unit.test_corpus import step_inside_limits

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

T_S = 1e-3  # control period [s]


def corpus_loop(tmp_path, name: str, controller: str, controller_params: dict) -> ClosedLoop:
    robot = BY_NAME[name]
    model = RobotModel(resolve_robot(urdf_path=str(robot.path), package_paths=PACKAGE_PATHS))
    q0, target = step_inside_limits(model)
    loop = ClosedLoop(
        tmp_path / name,
        next_domain_id(),
        name,
        controller,
        controller_params={**robot.params(), **controller_params},
        sim_params={**robot.params(), "initial_positions": q0.tolist()},
    )
    loop.model, loop.q0, loop.target = model, q0, target
    return loop


@pytest.mark.parametrize("name", ["kinova", "z1"])
def test_pd_gravity_on_its_defaults_settles_a_step(tmp_path, name):
    with corpus_loop(tmp_path, name, "pd_gravity_controller", {}) as loop:
        loop.start(loop.model.joint_names, [loop.target.tolist()])
        loop.run_until(4.0)
        q, _ = loop.final_state()
    error = np.max(np.abs(q - loop.target))
    assert error < 1e-3, (name, error)
    assert np.max(np.abs(q - loop.q0)) > 0.01


@pytest.mark.parametrize("name", ["ur5", "xarm7", "so101"])
def test_inverse_dynamics_is_the_second_order_theory(tmp_path, name):
    omega_n, zeta = 10.0, 0.6
    params = {"law": "inverse_dynamics", "omega_n": omega_n, "zeta": zeta}
    with corpus_loop(tmp_path, name, "inverse_dynamics_controller", params) as loop:
        loop.start(loop.model.joint_names, [loop.target.tolist()])
        loop.run_until(2.0)
        t, q, _, _ = loop.probe.recording.arrays()
    theory = second_order_prediction(omega_n, zeta)
    for j, m in enumerate(step_metrics_per_joint(t, q, targets=loop.target, t_step=0.0)):
        joint = loop.model.joint_names[j]
        assert abs(m.overshoot_percent - theory["overshoot_percent"]) < 1.0, (joint, m)
        ts2 = theory["settling_time_2"]
        assert abs(m.settling_time_2 - ts2) <= max(0.05 * ts2, T_S), (joint, m, ts2)
        assert m.abs_steady_state_error < 1e-4, (joint, m)
