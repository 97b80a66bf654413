"""PD + gravity compensation in a real ROS 2 loop: sim_bridge + pd_gravity_controller as
separate processes in lockstep, changed through the parameter services.

The theory of the loop itself (THEORY.md §2: convergence, the pure-PD offset, identical
runs) is checked on the in-process engine (test/unit/test_inprocess.py), which records the
same loop bit for bit (test/integration/test_corpus_loops.py)."""

from __future__ import annotations

import numpy as np
import pytest

from .conftest import GAINS, JOINTS, SETPOINTS

pytestmark = pytest.mark.integration
ROBOTS = ["planar_2dof", "iiwa"]


def test_invalid_parameter_updates_are_rejected_and_the_loop_keeps_running(make_loop):
    robot = "planar_2dof"
    loop = make_loop(robot, {"gravity_compensation": "full"})
    q_d = np.array(SETPOINTS[robot])
    loop.start(JOINTS[robot], [q_d])
    loop.run_until(1.0)
    bad_updates = [
        {"kp": -5.0},
        {"kp": [100.0, 100.0, 100.0]},
        {"kd": float("nan")},
        {"gravity_compensation": "sometimes"},
        {"ki": "high"},
    ]
    for update in bad_updates:
        (result,) = loop.probe.set_parameters(loop.controller, update)
        assert not result.successful, f"{update} was accepted"
        assert result.reason, f"{update} rejected without a reason"
    kp, kd, mode = loop.probe.get_parameters(loop.controller, ["kp", "kd", "gravity_compensation"])
    assert list(kp) == GAINS[robot]["kp"] and list(kd) == GAINS[robot]["kd"]
    assert mode == "full"
    (readonly,) = loop.probe.set_parameters(loop.controller, {"robot": "iiwa"})
    assert not readonly.successful
    loop.run_until(6.0)
    q, _ = loop.final_state()
    assert np.max(np.abs(q_d - q)) < 1e-3
