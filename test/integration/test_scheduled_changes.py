"""Changes at exact simulation times: sim_bridge's ``pause_at`` holds the lockstep loop at a
given state, so that parameter changes apply from the next step in every run alike."""

from __future__ import annotations

import numpy as np
import pytest

from .conftest import JOINTS, SETPOINTS

pytestmark = pytest.mark.integration

ROBOT = "planar_2dof"


def run_with_change(make_loop, t_change: float) -> tuple[np.ndarray, np.ndarray]:
    loop = make_loop(ROBOT, {"gravity_compensation": "none"}, sim_params={"pause_at": t_change})
    loop.start(JOINTS[ROBOT], [SETPOINTS[ROBOT]])
    loop.hold_at(t_change)
    loop.probe.spin_for(0.3)
    assert loop.probe.latest_time() == pytest.approx(t_change)  # paused there
    (result,) = loop.probe.set_parameters(loop.controller, {"gravity_compensation": "full"})
    assert result.successful
    loop.resume()
    loop.run_until(1.0)
    t, q, _, _ = loop.probe.recording.arrays()
    loop.close()
    return t, q


@pytest.mark.long  # two whole runs (make test-long): make test within 5 minutes
def test_a_change_at_a_simulation_time_is_reproducible(make_loop):
    t1, q1 = run_with_change(make_loop, 0.4)
    t2, q2 = run_with_change(make_loop, 0.4)
    np.testing.assert_array_equal(t1, t2)
    np.testing.assert_array_equal(q1, q2)  # bit for bit, however the machine was loaded
    assert t1[-1] >= 1.0 - 1e-9 and np.all(np.diff(t1) > 0)
