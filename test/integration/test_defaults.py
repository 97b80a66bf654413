"""Nodes on their defaults work together: ``trigger: auto`` follows the plant's mode, stale
states are judged by arrival (so a controller without use_sim_time commands a realtime
plant), the default gains (ω_n = 10 rad/s, ζ = 1) hold the arm, and a lockstep plant says
why it waits when a controller cannot answer it. Each test leases its own ROS domain and
stops every process it starts."""

from __future__ import annotations

import json
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.probe import LoopProbe
from joint_space_control.processes.processes import ProcessGroup
from joint_space_control.ros.messages import CONFIG_QOS, CONTROL_QOS

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

CONTROLLERS = ["pd_gravity_controller", "inverse_dynamics_controller"]
SIM = "sim_bridge: control loop"


class Nodes:
    def __init__(self, workdir: Path) -> None:
        domain = next_domain_id()
        self.group = ProcessGroup(workdir, domain)
        self.probe = LoopProbe(domain, name="defaults_probe")
        self.configs: dict[str, dict] = {}

    def start(self, executable: str, params: dict) -> None:
        self.group.start(executable, params)

    def watch_config(self, controller: str) -> None:
        self.probe.node.create_subscription(
            String,
            f"/{controller}/config",
            lambda m: self.configs.__setitem__(controller, json.loads(m.data)),
            CONFIG_QOS,
        )

    def status(self, name: str, until, timeout: float = 20.0) -> dict:
        return self.probe.wait_for_diagnostics(
            [name], until=lambda d: until(d[name]), timeout=timeout, check=self.group.check_alive
        )[name]

    def state_reliability(self, controller: str, expected: ReliabilityPolicy) -> None:
        """Wait until the controller's joint_states reader has ``expected`` reliability (it
        subscribes again once the plant's mode is known)."""

        def readers() -> list:
            infos = self.probe.node.get_subscriptions_info_by_topic("/joint_states")
            return [i.qos_profile.reliability for i in infos if i.node_name == controller]

        self.probe.spin_until(
            lambda: readers() == [expected],
            10.0,
            f"{controller}'s joint_states reader {expected.name}",
            self.group.check_alive,
        )

    def close(self) -> None:
        try:
            self.probe.close()
        finally:
            self.group.stop_all()


@pytest.fixture
def nodes(tmp_path: Path) -> Iterator[Nodes]:
    n = Nodes(tmp_path)
    try:
        yield n
    finally:
        n.close()


def pd_default_gains() -> tuple[np.ndarray, np.ndarray]:
    """ω_n = 10 rad/s, ζ = 1 scaled by B_ii at the default start configuration q = 0."""
    b = np.diag(RobotModel(resolve_robot("planar_2dof")).inertia(np.zeros(2)))
    return b * 100.0, b * 20.0


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_lockstep_plant_runs_with_a_controller_on_sim_time_only(nodes, controller):
    """The hook check: sim_bridge mode:=lockstep and a controller with nothing but
    use_sim_time:=true: simulated time passes 2 s (before: the timer waited for /clock)."""
    nodes.start("sim_bridge", {"mode": "lockstep"})
    nodes.start(controller, {"use_sim_time": True})
    nodes.watch_config(controller)
    nodes.probe.run_until(2.0, 60.0, nodes.group.check_alive)
    status = nodes.status(f"{controller}: control loop", lambda s: s["trigger"] == "state")
    assert status["trigger_parameter"] == "auto" and status["commanding"] == 1
    # a lockstep plant waits for the answer to each state: none may be lost
    nodes.state_reliability(controller, ReliabilityPolicy.RELIABLE)
    nodes.probe.spin_until(
        lambda: nodes.configs.get(controller, {}).get("kp") is not None,
        10.0,
        "the gains in ~/config",
        nodes.group.check_alive,
    )
    config = nodes.configs[controller]
    assert config["trigger"] == "state" and config["gains_from"] == "default"
    if controller == "pd_gravity_controller":
        kp, kd = pd_default_gains()
        np.testing.assert_allclose(config["kp"], kp, rtol=1e-9)
        np.testing.assert_allclose(config["kd"], kd, rtol=1e-9)
        np.testing.assert_allclose(config["gains_configuration"], [0.0, 0.0], atol=1e-9)
    else:
        np.testing.assert_allclose(config["kp"], [100.0, 100.0])
        np.testing.assert_allclose(config["kd"], [20.0, 20.0])
    # the arm holds where it started (gravity compensated, default gains)
    _, q, _, _ = nodes.probe.recording.arrays()
    assert np.max(np.abs(q[-1])) < 1e-2, q[-1]


@pytest.mark.parametrize("controller", CONTROLLERS)
@pytest.mark.realtime
def test_realtime_plant_is_commanded_by_a_controller_with_nothing_set(nodes, controller):
    """Realtime sim_bridge and a controller on the wall clock (no use_sim_time): the states'
    stamps are simulation time, yet the controller commands and the brakes come off."""
    nodes.start("sim_bridge", {})
    nodes.start(controller, {})
    status = nodes.status(
        f"{controller}: control loop", lambda s: s["trigger"] == "timer", timeout=30.0
    )
    assert status["commanding"] == 1 and status["stale.stops"] == 0
    # behind a realtime plant only the newest state matters: a stalled controller is not
    # handed the writer's backlog (REALTIME_STATE_QOS)
    nodes.state_reliability(controller, ReliabilityPolicy.BEST_EFFORT)
    status = nodes.status(f"{controller}: control loop", lambda s: True)
    assert status["plant"] == "not_lockstep"
    assert status["joint_states_reliability"] == "best_effort"
    sim = nodes.status(SIM, lambda s: s["braking"] == 0 and s["sim_time_s"] > 1.5, 30.0)
    assert sim["brake.engaged"] == 0  # never timed out once commanding
    nodes.probe.spin_for(0.3)
    _, q, _, tau = nodes.probe.recording.arrays()
    assert np.max(np.abs(q[-1])) < 2e-2, q[-1]  # held under gravity
    assert np.abs(tau[-1]).max() > 1.0  # by torques, not by the brakes alone


def test_a_controller_answering_each_state_keeps_its_reader_reliable(nodes):
    """trigger: state behind a publisher that is not a lockstep plant (here the probe, which
    has no ``mode``): the controller answers each state, so its joint_states reader stays
    reliable once the plant is judged (subscribing again, best effort, lost states that
    tests publishing their own states waited for, in CI)."""
    controller = "pd_gravity_controller"
    nodes.start(controller, {"trigger": "state"})
    nodes.probe.node.create_publisher(JointState, "joint_states", CONTROL_QOS)
    name = f"{controller}: control loop"
    status = nodes.status(name, lambda s: s["plant"] == "not_lockstep")
    assert status["trigger"] == "state"
    # the decision is followed on the control path: give it time to act, then look
    nodes.probe.spin_for(2.0)
    status = nodes.status(name, lambda s: True)
    assert status["joint_states_reliability"] == "reliable"
    nodes.state_reliability(controller, ReliabilityPolicy.RELIABLE)


@pytest.mark.realtime
def test_a_controller_answering_each_state_takes_the_newest_behind_a_realtime_plant(nodes):
    """trigger: state behind sim_bridge in realtime: the reader turns best effort, so a
    controller that stalled (SIGSTOP, 8 s: as one restarted on a loaded machine) answers the
    newest state when it runs again and the plant's brakes come off within seconds. Kept
    reliable, the fault soak's restarted controller was handed states over 100 ms old for a
    minute, dropped them all and never commanded again."""
    controller = "pd_gravity_controller"
    nodes.start("sim_bridge", {"command_timeout": 0.1})
    nodes.start(controller, {"trigger": "state"})
    name = f"{controller}: control loop"
    nodes.status(name, lambda s: s["plant"] == "not_lockstep" and s["commanding"] == 1, 30.0)
    nodes.state_reliability(controller, ReliabilityPolicy.BEST_EFFORT)
    nodes.status(SIM, lambda s: s["braking"] == 0, 30.0)
    process = nodes.group.nodes[controller]
    process.signal(signal.SIGSTOP)
    try:
        nodes.status(SIM, lambda s: s["braking"] == 1, 10.0)  # no command: braked
        nodes.probe.spin_for(8.0)
    finally:
        process.signal(signal.SIGCONT)
    sim = nodes.status(SIM, lambda s: s["braking"] == 0, 10.0)  # commanded again
    assert sim["owner"] == f"/{controller}", sim
    status = nodes.status(name, lambda s: s["trigger"] == "state")
    assert status["joint_states_reliability"] == "best_effort"


def test_lockstep_plant_warns_about_a_timer_controller_on_sim_time(nodes):
    """trigger: timer with use_sim_time against a lockstep plant cannot run: sim_bridge
    says so at WARN with the likely cause, within a second or so of the stall."""
    nodes.start("sim_bridge", {"mode": "lockstep"})
    nodes.start("pd_gravity_controller", {"use_sim_time": True, "trigger": "timer"})
    sim = nodes.group.nodes["sim_bridge"]
    nodes.probe.spin_until(
        lambda: "publish(es) effort_command" in sim.log(),
        20.0,
        "the stall warning",
        nodes.group.check_alive,
    )
    line = next(x for x in sim.log().splitlines() if "publish(es) effort_command" in x)
    assert "[WARN]" in line and "pd_gravity_controller" in line
    assert "use_sim_time" in line and "trigger:=state or auto" in line
    nodes.probe.spin_for(2.0)
    assert nodes.probe.latest_time() == 0.0  # still waiting: the warning was not a false one
    assert sum("publish(es) effort_command" in x for x in sim.log().splitlines()) == 1  # once
