"""The controllers behind ros2_control's contract, as node processes in lockstep: sim_bridge
as a ros2_control robot (``interface: ros2_control``: ``/joint_states`` as
joint_state_broadcaster publishes it, ``/effort_controller/commands`` with a forward effort
controller's semantics) and a controller with ``command_interface: forward_command``
remapped onto it (``-r commands:=/effort_controller/commands``).

Checked against the theory (THEORY.md §2-3, the tolerances of test/unit/test_inprocess.py):
PD + g(q) settles with no steady-state error, nominal inverse dynamics gives the
second-order step response; and a controller stopped mid-motion (SIGTERM) leaves the robot
the command that holds the arm, g(q) at the last state it measured."""

from __future__ import annotations

import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from std_msgs.msg import Float64MultiArray

from joint_space_control.analysis.metrics import second_order_prediction, step_metrics_per_joint
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.client import STARTUP_TIMEOUT
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.probe import LoopProbe
from joint_space_control.processes.processes import ProcessGroup
from test.loops import ID_CASES

from .conftest import GAINS, JOINTS, SETPOINTS

pytestmark = pytest.mark.integration
ROBOT = "planar_2dof"
COMMANDS = "/effort_controller/commands"
T_S = 1e-3  # control period [s]


class Contract:
    """sim_bridge (lockstep, ``interface: ros2_control``, paused) + one controller commanding
    it through ``/effort_controller/commands`` + a probe that keeps every command."""

    def __init__(self, workdir: Path, controller: str, params: dict, plant: dict) -> None:
        self.lease = lease_domain()
        domain = self.lease.domain_id
        self.group = ProcessGroup(workdir, domain, (self.lease.fileno(),))
        self.controller = controller
        self.probe = None
        self.commands: list[np.ndarray] = []
        try:
            self.group.start(
                "sim_bridge",
                {
                    "robot": ROBOT,
                    "mode": "lockstep",
                    "interface": "ros2_control",
                    "start_paused": True,
                    **plant,
                },
            )
            self.group.start(
                controller,
                {
                    "robot": ROBOT,
                    "command_interface": "forward_command",
                    "trigger": "state",
                    **params,
                },
                extra_args=["-r", f"commands:={COMMANDS}"],
            )
            self.probe = LoopProbe(domain, name=f"jsc_probe_{domain}")
            self.probe.observe(
                Float64MultiArray, COMMANDS, lambda msg: self.commands.append(np.array(msg.data))
            )
            self.probe.wait_for_subscriber(
                controller, ["/reference", "/joint_states"], check=self.group.check_alive
            )
            self.probe.wait_for_subscriber("sim_bridge", [COMMANDS], check=self.group.check_alive)
            node = self.probe.node
            self.probe.spin_until(
                lambda: (
                    node.count_publishers(COMMANDS) >= 1
                    and node.count_subscribers("/joint_states") >= 2
                ),
                STARTUP_TIMEOUT,
                "the controller and the robot to connect",
                self.group.check_alive,
            )
        except BaseException:
            self.close()
            raise

    def start(self, positions: list, times: list) -> None:
        self.probe.send_reference(JOINTS[ROBOT], positions, times)
        response = self.probe.call_trigger("/sim_bridge/resume")
        assert response.success, response.message

    def run_until(self, t: float) -> None:
        self.probe.run_until(t, 300.0, check=self.group.check_alive)

    def arrays(self) -> tuple[np.ndarray, ...]:
        t, q, dq, _ = self.probe.recording.arrays()
        return t, q, dq

    def close(self) -> None:
        if self.probe is not None:
            self.probe.close()
        self.group.stop_all()
        self.lease.release()


@pytest.fixture
def contract(tmp_path: Path):
    made: list[Contract] = []

    def make(controller: str, params: dict[str, Any], plant: dict | None = None) -> Contract:
        loop = Contract(tmp_path / f"run{len(made)}", controller, params, plant or {})
        made.append(loop)
        return loop

    yield make
    for loop in made:
        loop.close()


def test_pd_gravity_through_the_contract_settles_and_a_stop_leaves_the_holding_command(
    contract,
):
    loop = contract("pd_gravity_controller", {**GAINS[ROBOT], "gravity_compensation": "full"})
    q_d = np.array(SETPOINTS[ROBOT])
    loop.start([q_d], [0.0])
    loop.run_until(6.0)
    _, q, _ = loop.arrays()
    assert np.max(np.abs(q_d - q[-1])) < 1e-3, f"steady-state error {q_d - q[-1]}"

    # mid-motion: a move of 30 s, the controller stopped a second into it (the lockstep
    # plant may run on by seconds of its time before the signal lands: still moving)
    loop.probe.send_reference(JOINTS[ROBOT], [q_d + [1.0, -0.5]], [30.0])
    t_now = loop.probe.latest_time()
    loop.run_until(t_now + 1.0)
    controller = loop.group.nodes[loop.controller]
    controller.signal(signal.SIGTERM)
    controller.proc.wait(timeout=10.0)
    assert controller.proc.returncode == 0, controller.log()[-2000:]
    loop.probe.spin_for(1.0)  # the last command and the state it made
    assert "sent the holding command" in controller.log()
    # what the robot holds is what it applied last: the effort of its last state (the
    # torque over the step before it; the plant took the holding command as the answer to
    # the state the controller had not answered). Judged on the plant's side: an observer of
    # the command topic may miss the last message of a node that exits.
    _, q, dq, applied = loop.probe.recording.arrays()
    model = RobotModel(resolve_robot(ROBOT))
    # g(q) of the last state the controller measured: the one it had answered last (the
    # stop came before the next state) or the one it was stopped at
    candidates = [model.gravity(qk) for qk in q[-3:]]
    gaps = [np.max(np.abs(applied[-1] - g)) for g in candidates]
    assert min(gaps) < 1e-9, f"last torque {applied[-1]} is no g(q) of the last states {gaps}"
    assert np.max(np.abs(dq[-3])) > 1e-5, "the arm should have been moving (at rest: ~1e-8)"
    assert np.max(np.abs(applied[-2] - applied[-1])) > 1e-6, "the stop changed the command"


def test_inverse_dynamics_through_the_contract_is_the_second_order_step(contract):
    case = ID_CASES[ROBOT]
    q0, step = np.array(case["q0"]), np.array(case["step"])
    loop = contract(
        "inverse_dynamics_controller",
        {"law": "inverse_dynamics", "omega_n": case["omega_n"], "zeta": case["zeta"]},
        {"initial_positions": case["q0"]},
    )
    loop.start([q0 + step], [0.0])
    loop.run_until(case["duration"])
    t, q, _ = loop.arrays()
    keep = t <= case["duration"] + 1e-9
    theory = second_order_prediction(case["omega_n"], case["zeta"])
    for j, m in enumerate(step_metrics_per_joint(t[keep], q[keep], targets=q0 + step, t_step=0.0)):
        assert abs(m.overshoot_percent - theory["overshoot_percent"][j]) < 1.0, j
        ts2 = theory["settling_time_2"][j]
        assert abs(m.settling_time_2 - ts2) <= max(0.05 * ts2, T_S), (j, m, ts2)
        assert m.abs_steady_state_error < 1e-4, (j, m)


def test_a_command_of_the_wrong_size_is_dropped_with_one_line(contract):
    loop = contract("pd_gravity_controller", GAINS[ROBOT])
    node = loop.probe.node
    publisher = node.create_publisher(Float64MultiArray, COMMANDS, 10)
    loop.probe.spin_until(
        lambda: publisher.get_subscription_count() >= 1, STARTUP_TIMEOUT, "sim_bridge"
    )
    for _ in range(3):
        publisher.publish(Float64MultiArray(data=[1.0, 2.0, 3.0]))
    deadline = time.monotonic() + 10.0
    sim = loop.group.nodes["sim_bridge"]
    while "dropped a command of 3 values" not in sim.log() and time.monotonic() < deadline:
        loop.probe.spin_for(0.2)
    lines = [line for line in sim.log().splitlines() if "dropped a command" in line]
    assert lines and "the robot has 2 joints" in lines[0], sim.log()[-2000:]
    assert len(lines) == 1  # throttled


def test_command_joints_that_are_no_permutation_stop_the_controller_with_one_line(tmp_path):
    with lease_domain() as lease:
        group = ProcessGroup(tmp_path, lease.domain_id, (lease.fileno(),))
        with group:
            node = group.start(
                "pd_gravity_controller",
                {
                    "robot": ROBOT,
                    "command_interface": "forward_command",
                    "command_joints": ["joint2", "joint3"],
                },
            )
            assert node.proc.wait(timeout=60.0) == 2
            lines = [line for line in node.log().splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: 'command_joints' must be a permutation"), lines
