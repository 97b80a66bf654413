"""The ROS engine and the in-process engine are the same loop, bit for bit: one test per law,
on robot descriptions nobody here wrote (test/corpus.py).

The node processes (sim_bridge in lockstep, the controller, the recorder) and the in-process
engine (:mod:`joint_space_control.workbench.experiments.execution.inprocess`: the same plant,
controller
objects and sub-step loop, no ROS graph) run the same step of a corpus robot from the
controllers' parameters; every recorded ``~/state`` row (q_d … τ, the joint state answered) is
equal to the last bit, and so are the metrics of the analysis. The theory itself is checked on
the in-process engine (test/unit/test_inprocess.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from joint_space_control.analysis.run_metrics import analyze_bag
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.loop import ClosedLoop
from joint_space_control.workbench.experiments.execution.equivalence import differences
from joint_space_control.workbench.experiments.execution.inprocess import InProcessLoop
from joint_space_control.workbench.experiments.scenarios.format import RobotSetup
from test.corpus import BY_NAME, PACKAGE_PATHS
from test.unit.test_corpus import step_inside_limits

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

LAWS = {
    # PD + g(q) on the controller's defaults alone: gains designed from the default ω_n, ζ
    "pd_gravity": ("kinova", "pd_gravity_controller", {}),
    "inverse_dynamics": (
        "ur5",
        "inverse_dynamics_controller",
        {"law": "inverse_dynamics", "omega_n": 10.0, "zeta": 0.6},
    ),
    # the second engine (issue 26): sim_bridge engine:=mujoco over ROS is the in-process
    # engine's MuJoCo world, to the last bit
    "pd_gravity_on_mujoco": ("panda", "pd_gravity_controller", {}),
}
#: The plant's engine of a case (the others: sim_bridge's default, PyBullet).
ENGINE = {"pd_gravity_on_mujoco": "mujoco"}
DURATION = 1.5


@pytest.mark.parametrize("law", list(LAWS))
def test_ros_and_in_process_engines_record_the_same_loop(tmp_path, law):
    name, controller, law_params = LAWS[law]
    robot = BY_NAME[name]
    model = RobotModel(resolve_robot(urdf_path=str(robot.path), package_paths=PACKAGE_PATHS))
    q0, target = step_inside_limits(model)
    params = {**robot.params(), **law_params}
    sim = {**robot.params(), "initial_positions": q0.tolist(), "pause_at": DURATION}
    if law in ENGINE:
        sim["engine"] = ENGINE[law]
    joints, reference = list(model.joint_names), [target.tolist()]

    ros_bag = tmp_path / "ros"
    with ClosedLoop(
        tmp_path / "logs", next_domain_id(), name, controller, params, sim, record=ros_bag
    ) as loop:
        loop.start(joints, reference)
        loop.hold_at(DURATION)
        loop.settle_recording()
    local_bag = tmp_path / "inprocess"
    local = InProcessLoop([RobotSetup("", name, {}, controller, params, {})], sim, local_bag)
    try:
        local.send_reference("", joints, reference, [0.0])
        local.run_until(DURATION)
    finally:
        local.close()

    (ros,), (mine,) = analyze_bag(ros_bag).controllers, analyze_bag(local_bag).controllers
    assert len(mine.state.stamp) == round(DURATION * 1000) + 1  # every state, 0 … 1.5 s
    np.testing.assert_array_equal(ros.state.stamp, mine.state.stamp)
    assert set(ros.state.rows) == set(mine.state.rows)
    for field, rows in ros.state.rows.items():
        np.testing.assert_array_equal(rows, mine.state.rows[field], err_msg=field)
    assert differences(ros.metrics, mine.metrics) == []
    # and the loop did something: the arm moved towards its target
    assert np.max(np.abs(mine.state.rows["q"][-1] - q0)) > 0.01
