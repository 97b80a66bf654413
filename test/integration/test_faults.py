"""Fault injection on real node processes: bad input at every boundary, stale and missing
data, crashes and restarts, isolation. Each test leases its own ROS domain and stops every
process it starts, also when it fails. Times compared are simulation times or message
counts, never wall-clock speed."""

from __future__ import annotations

import math
import signal
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from joint_space_control.processes.probe import LoopProbe
from joint_space_control.processes.processes import ProcessGroup, isolated_env
from joint_space_control.ros.messages import ns_to_stamp, stamp_to_ns
from test.corpus import BY_NAME, PACKAGE_PATHS

from .conftest import GAINS, JOINTS, next_domain_id

pytestmark = pytest.mark.integration

ROBOT = "planar_2dof"
J = JOINTS[ROBOT]
LIMITS = np.array([2000.0, 1000.0])  # the URDF's effort limits
MS = 1_000_000
SPACING = 0.1  # [s] between bad messages sent to a keep-last-1 subscription
#: The realtime plant's state rate in the kill-and-restart test [Hz], the same on every
#: machine: the brakes' command timeout (0.1 s) is ten of its periods, and the moment they
#: engage is judged to 2.5 periods in simulated time; what is asserted (brakes within the
#: timeout, a bumpless restart, commands within the limits) holds at any rate.
KILL_RATE = 100.0
QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE
)


class Rig:
    """Node processes and a probe in one leased domain; the probe records every command."""

    def __init__(self, workdir: Path) -> None:
        self.domain_id = next_domain_id()
        self.group = ProcessGroup(workdir, self.domain_id)
        self.probe = LoopProbe(self.domain_id, name="fault_probe")
        self.commands: list[tuple[int, list[float]]] = []
        self.probe.command_listeners.append(
            lambda _ns, m: self.commands.append((stamp_to_ns(m.header.stamp), list(m.effort)))
        )

    def publisher(self, msg_type: type, topic: str, subscribers: int = 1):
        pub = self.probe.node.create_publisher(msg_type, topic, QOS)
        self.probe.spin_until(
            lambda: pub.get_subscription_count() >= subscribers,
            20.0,
            f"a subscriber of {topic}",
            self.group.check_alive,
        )
        return pub

    def wait_for_publisher(self, topic: str) -> None:
        self.probe.spin_until(
            lambda: self.probe.node.count_publishers(topic) >= 1,
            20.0,
            f"a publisher of {topic}",
            self.group.check_alive,
        )

    def send(self, pub, msg) -> None:
        """Publish one message and give the node time to take it: the control topics keep
        only the newest sample, so a burst would be one message to the subscriber."""
        pub.publish(msg)
        self.probe.spin_for(SPACING)

    def kill(self, name: str) -> None:
        """SIGKILL a node process and forget it."""
        node = self.group.nodes.pop(name)
        node.signal(signal.SIGKILL)
        node.stop()

    def answered(self, stamp_ns: int) -> bool:
        return any(s == stamp_ns for s, _ in self.commands)

    def diagnostics(self, name: str, until, timeout: float = 20.0) -> dict:
        status = f"{name}: control loop"
        return self.probe.wait_for_diagnostics(
            [status],
            until=lambda d: until(d[status]),
            timeout=timeout,
            check=self.group.check_alive,
        )[status]

    def close(self) -> None:
        try:
            self.probe.close()
        finally:
            self.group.stop_all()


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    r = Rig(tmp_path)
    try:
        yield r
    finally:
        r.close()


def joint_state(stamp_ns: int, names=J, q=(0.1, -0.2), dq=(0.0, 0.0)) -> JointState:
    msg = JointState(name=list(names), position=[float(x) for x in q])
    msg.velocity = [float(x) for x in dq]
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


def reference(points, names=J, stamp_ns: int = 0) -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp = ns_to_stamp(stamp_ns)
    for t, q in points:
        sec, nsec = divmod(round(t * 1e9), 1_000_000_000)
        msg.points.append(
            JointTrajectoryPoint(
                positions=[float(x) for x in q], time_from_start=Duration(sec=sec, nanosec=nsec)
            )
        )
    return msg


def assert_all_commands_safe(commands: list[tuple[int, list[float]]], limits=LIMITS) -> None:
    efforts = np.array([e for _, e in commands])
    assert efforts.shape[0] > 0
    assert np.isfinite(efforts).all()
    assert np.all(np.abs(efforts) <= limits)


def test_controller_rejects_bad_states_references_and_parameters(rig):
    """inverse_dynamics_controller alone, answering states the test publishes: each bad
    message is rejected and counted, no command answers it, the next valid state is answered,
    a state that makes the law non-finite gets no command, every command is finite and
    within the effort limits."""
    node = "inverse_dynamics_controller"
    # measured: a state without velocities is bad input (with the default, auto, it is a
    # plant that does not measure velocity: test_sampling_loop)
    rig.group.start(node, {"robot": ROBOT, "trigger": "state", "velocity_source": "measured"})
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    refs = rig.publisher(JointTrajectory, "reference")
    rig.wait_for_publisher("/effort_command")

    def answer(stamp_ns: int) -> None:
        rig.probe.spin_until(
            lambda: rig.answered(stamp_ns), 20.0, f"command {stamp_ns}", rig.group.check_alive
        )

    states.publish(joint_state(1 * MS))
    answer(1 * MS)
    bad_states = [
        joint_state(2 * MS, q=(math.nan, 0.0)),
        joint_state(3 * MS, dq=(0.0, math.inf)),
        joint_state(4 * MS, q=(0.1,)),  # one position for two names
        joint_state(5 * MS, names=["joint1"], q=(0.1,), dq=(0.0,)),  # joint2 missing
        joint_state(6 * MS, names=["joint1", "joint1", "joint2"], q=(0, 0, 0), dq=(0, 0, 0)),
        JointState(name=J, position=[0.1, 0.2]),  # no velocities
    ]
    bad_states[-1].header.stamp = ns_to_stamp(7 * MS)
    for msg in bad_states:
        rig.send(states, msg)
    states.publish(joint_state(8 * MS))
    answer(8 * MS)  # in order on one topic: the bad ones came first
    assert not any(rig.answered(k * MS) for k in range(2, 8))

    # finite but absurd, refused where they arrive (laws/plausible.py): a speed that would
    # overflow the Coriolis term, a position 1e9 rad away (taken, it drove the arm at its
    # effort limits for seconds in the fault soak)
    absurd = [joint_state(9 * MS, dq=(1e200, 1e200)), joint_state(9 * MS, q=(1e9, 0.0))]
    for msg in absurd:
        rig.send(states, msg)
    # large and plausible: the command is clamped to the effort limits
    states.publish(joint_state(10 * MS, dq=(5e2, -5e2)))
    answer(10 * MS)
    assert not rig.answered(9 * MS)
    clamped = dict(rig.commands)[10 * MS]
    np.testing.assert_array_equal(np.abs(clamped), LIMITS)

    bad_refs = [
        reference([(0.5, (0.1, 0.1)), (0.5, (0.2, 0.2))]),  # times not increasing
        reference([(0.0, (0.1, 0.1))], stamp_ns=1 * MS),  # ended before now (10 ms)
        reference([(0.5, (4.0, 0.0))]),  # joint1 beyond its 3.14159 rad limit
        reference([(0.5, (0.1, math.nan))]),
        reference([(0.5, (0.1, 0.1, 0.0))], names=J + ["joint3"]),  # unknown joint
    ]
    for msg in bad_refs:
        rig.send(refs, msg)
    results = rig.probe.set_parameters(node, {"kp": -1.0})
    assert not results[0].successful and "kp" in results[0].reason
    results = rig.probe.set_parameters(node, {"law": "no_such_law"})
    assert not results[0].successful

    status = rig.diagnostics(
        node, lambda s: s["rejected.references"] == len(bad_refs) and s["total.ticks"] >= 3
    )
    assert status["rejected.joint_states"] == len(bad_states) + len(absurd)
    assert status["dropped.nonfinite_torques"] == 0
    # q̇ = ±500 rad/s: the law asked for far more than 2 × the limits (clamped, but counted)
    assert status["beyond_bound.torques"] == 1
    assert status["rejected.parameters"] == 2
    assert status["commanding"] == 1
    # still running on the last valid data: a new valid state is answered
    states.publish(joint_state(11 * MS))
    answer(11 * MS)
    assert_all_commands_safe(rig.commands)


def test_plant_rejects_bad_commands_and_parameters_and_limits_the_torque(rig):
    """sim_bridge alone in lockstep: bad commands do not advance time and are counted; a
    huge valid command is applied at the effort limits; the torque-rate limit set at run
    time ramps the next change; invalid parameters of every kind are refused."""
    rig.group.start("sim_bridge", {"robot": ROBOT, "mode": "lockstep"})
    efforts = rig.publisher(JointState, "effort_command", subscribers=2)  # + the probe
    arrays = rig.publisher(Float64MultiArray, "/sim_bridge/commands")
    probe = rig.probe
    probe.run_until(0.0, 20.0, rig.group.check_alive)  # the state at t = 0, waiting

    def command(stamp_ns: int, names=J, effort=(0.0, 0.0)) -> JointState:
        msg = JointState(name=list(names), effort=[float(x) for x in effort])
        msg.header.stamp = ns_to_stamp(stamp_ns)
        return msg

    bad = [
        command(0, effort=(math.nan, 0.0)),
        command(0, effort=(0.0, -math.inf)),
        command(0, effort=(1.0,)),
        command(0, names=J + ["joint3"], effort=(0.0, 0.0, 0.0)),
        command(0, names=["joint2"], effort=(0.0,)),
        command(0, names=["joint1", "joint1", "joint2"], effort=(0, 0, 0)),
    ]
    for msg in bad:
        rig.send(efforts, msg)
    rig.send(arrays, Float64MultiArray(data=[0.0, math.nan]))
    rig.send(arrays, Float64MultiArray(data=[0.0, 0.0, 0.0]))
    status = rig.diagnostics("sim_bridge", lambda s: s["rejected.commands"] >= len(bad) + 2)
    assert status["rejected.commands"] == len(bad) + 2
    assert probe.latest_time() == 0.0  # no step was taken

    # 5·10⁵ × the limit: a broken sender, rejected (reject_factor 2), not clamped
    rig.send(efforts, command(0, effort=(1e9, -1e9)))
    status = rig.diagnostics("sim_bridge", lambda s: s["rejected.commands"] >= len(bad) + 3)
    assert status["rejected.commands"] == len(bad) + 3
    assert probe.latest_time() == 0.0  # no step was taken
    # 1.5 × the limit: between the limit and the bound, clamped as before
    efforts.publish(command(0, effort=(3000.0, -1500.0)))
    probe.run_until(0.001, 20.0, rig.group.check_alive)
    _, _, _, tau = probe.recording.arrays()
    np.testing.assert_array_equal(tau[-1], [2000.0, -1000.0])

    for values, what in [
        ({"max_torque_rate": -1.0}, "max_torque_rate"),
        ({"max_torque_rate": [1.0, 2.0, 3.0]}, "max_torque_rate"),
        ({"command_timeout": 0.0}, "command_timeout"),
        ({"viscous_friction": "a lot"}, "viscous_friction"),
        ({"payload_mass": math.nan}, "payload_mass"),
    ]:
        result = probe.set_parameters("sim_bridge", values)[0]
        assert not result.successful and what in result.reason, (values, result.reason)
    result = probe.set_parameters("sim_bridge", {"mode": "realtime"})[0]
    assert not result.successful  # read-only
    assert probe.set_parameters("sim_bridge", {"max_torque_rate": 1000.0})[0].successful

    efforts.publish(command(1 * MS, effort=(0.0, 0.0)))  # from the limits towards zero
    probe.run_until(0.002, 20.0, rig.group.check_alive)
    _, _, _, tau = probe.recording.arrays()
    np.testing.assert_allclose(tau[-1], [1999.0, -999.0], rtol=0, atol=1e-9)  # 1 N·m / ms


@pytest.mark.realtime
@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_killed_controller_brakes_the_plant_and_a_new_one_takes_over_bumplessly(rig, engine):
    """Realtime: SIGKILL the controller → within command_timeout (simulation time) the plant
    brakes and says so; a new controller starts from the measured configuration, its first
    torque is the braking torque (both carry gravity) and the arm does not move. On both
    engines: MuJoCo's brakes are its dry friction at the effort limits, the torque they
    exert its constraint forces."""
    timeout = 0.1
    rate = KILL_RATE
    controller = {"robot": ROBOT, "trigger": "state", **GAINS[ROBOT]}
    rig.group.start(
        "sim_bridge",
        {
            "robot": ROBOT,
            "engine": engine,
            "mode": "realtime",
            "command_timeout": timeout,
            "initial_positions": [0.3, -0.2],
            "publish_rate": rate,
        },
    )
    rig.group.start("pd_gravity_controller", controller)
    rig.wait_for_publisher("/effort_command")
    probe = rig.probe
    probe.spin_until(
        lambda: len(rig.commands) > 0.3 * rate, 30.0, "commands", rig.group.check_alive
    )
    before = rig.diagnostics("sim_bridge", lambda s: s["braking"] == 0)["brake.engaged"]

    rig.kill("pd_gravity_controller")
    status = rig.diagnostics("sim_bridge", lambda s: s["braking"] == 1)
    assert status["level"] == 2 and "brakes engaged" in status["message"]
    # (a stall of the controller on a loaded machine may have braked the plant before)
    assert status["brake.engaged"] >= before + 1
    killed_at = len(rig.commands)
    last_stamp, last_tau = rig.commands[-1]
    t_braked = probe.latest_time() + 0.5
    probe.run_until(t_braked, 30.0, rig.group.check_alive)  # the arm stops and holds

    t, q, dq, tau = probe.recording.arrays()
    # After the kill the plant holds the last command it got, the same torque state after
    # state, until the timeout: the longest run of equal torques around the last command
    # the probe saw (the probe may miss the very last one, so it is not matched by value).
    # The timeout runs from that command's arrival, one state before its first state.
    window = np.flatnonzero((t > last_stamp * 1e-9 - 0.05) & (t < last_stamp * 1e-9 + 0.5))
    same = np.all(tau[window[1:]] == tau[window[:-1]], axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], same.astype(int), [0]))))
    starts, ends = edges[::2], edges[1::2]  # runs of equal torques: [start, end)
    longest = np.argmax(ends - starts)
    start, best = starts[longest], ends[longest] - starts[longest]
    t_hold, t_brake = t[window[start]], t[window[start + best + 1]]
    waited = t_brake - (t_hold - 1.0 / rate)
    # + two and a half state periods (25 ms at 100 Hz): the brake shows at the next state
    assert timeout < waited <= timeout + 2.5 / rate, (waited, t_hold, t_brake)
    assert np.max(np.abs(dq[-1])) < 1e-2
    q_held, brake_tau = q[-1], tau[-1]

    rig.group.start("pd_gravity_controller", controller)
    probe.spin_until(
        lambda: len(rig.commands) > killed_at + 0.5 * rate,
        30.0,
        "new commands",
        rig.group.check_alive,
    )
    first_new = np.array(rig.commands[killed_at][1])
    # bumpless: the new controller's first torque is what the brakes applied, both ≈ g(q);
    # what remains (~1 % of the limits here) is K_D times the brakes' slow creep
    g = RobotModel(resolve_robot(ROBOT)).gravity(q_held)
    assert np.all(np.abs(first_new - brake_tau) < 0.02 * LIMITS), (first_new, brake_tau)
    assert np.all(np.abs(first_new - g) < 0.02 * LIMITS), (first_new, g)
    assert np.all(np.abs(g) > 0.05 * LIMITS)  # the check is not trivial: gravity is large
    t, q, dq, tau = probe.recording.arrays()
    # it holds the configuration it measured first (the brakes may have crept until then)
    q_start = q[np.argmin(np.abs(t - rig.commands[killed_at][0] * 1e-9))]
    assert np.max(np.abs(q_start - q_held)) < 1e-2
    assert np.max(np.abs(q[-1] - q_start)) < 2e-3, q[-1] - q_start
    status = rig.diagnostics("sim_bridge", lambda s: s["braking"] == 0)
    assert status["level"] < 2
    assert_all_commands_safe(rig.commands)


# run alone (realtime marker): its waits are for the lockstep loop's own time, within limits
# (60 s for 1.7 s of simulated time) that a loop sharing the machine with another worker's
# tests need not meet
@pytest.mark.realtime
def test_restarted_simulator_is_detected_and_the_controller_resumes_cleanly(make_loop):
    """Lockstep: SIGKILL sim_bridge mid-run and start a new one. Its time starts again at 0:
    the controller notices, forgets reference and integrators, holds the measured (initial)
    configuration, i.e. commands exactly g(q0), and the new loop runs."""
    loop = make_loop(ROBOT, {"state_timeout": 0.1})
    commands: list[tuple[int, list[float]]] = []
    loop.probe.observe(
        JointState,
        "effort_command",
        lambda m: commands.append((stamp_to_ns(m.header.stamp), list(m.effort))),
    )
    loop.start(J, [[0.5, -0.3]])
    loop.run_until(0.3)
    old = loop.group.nodes.pop("sim_bridge")
    old.signal(signal.SIGKILL)
    old.stop()
    seen = len(commands)
    q0 = [0.2, 0.1]
    # The new simulator's states only: a subscription made now matches no dead publisher
    # (the probe's own recording may still hold states of the old one, which ran ahead).
    states: list[tuple[int, list[float]]] = []
    loop.probe.observe(
        JointState,
        "joint_states",
        lambda m: states.append((stamp_to_ns(m.header.stamp), list(m.position))),
    )

    def run_until(t: float) -> np.ndarray:
        loop.probe.spin_until(
            lambda: bool(states) and states[-1][0] >= round(t * 1e9),
            60.0,
            f"the new simulator at t={t} s",
            loop.group.check_alive,
        )
        return np.array(states[-1][1])

    loop.group.start("sim_bridge", {"robot": ROBOT, "mode": "lockstep", "initial_positions": q0})
    loop.probe.spin_until(
        lambda: any(s == 0 for s, _ in commands[seen:]),
        30.0,
        "the answer to the new t=0",
        loop.group.check_alive,
    )
    first = np.array(next(e for s, e in commands[seen:] if s == 0))
    g0 = RobotModel(resolve_robot(ROBOT)).gravity(np.array(q0))
    np.testing.assert_allclose(first, g0, rtol=1e-9, atol=1e-9)
    q = run_until(0.3)
    np.testing.assert_allclose(q, q0, atol=1e-3)  # held, the old set-point is forgotten
    status = loop.probe.wait_for_diagnostics(
        ["pd_gravity_controller: control loop"], check=loop.group.check_alive
    )["pd_gravity_controller: control loop"]
    assert status["restarts"] == 1
    # a new reference is followed
    loop.probe.send_reference(J, [[0.4, 0.0]])
    # from when the controller starts it (its newest state's time, which may be ahead of
    # the probe's: on a loaded machine the probe lags behind a lockstep loop)
    accepted = "reference accepted: 1 point(s) from t="
    log = loop.group.nodes["pd_gravity_controller"]
    loop.probe.spin_until(
        lambda: log.log().count(accepted) >= 2, 20.0, "the reference", loop.group.check_alive
    )
    t_start = float(log.log().rsplit(accepted, 1)[1].split(" s", 1)[0])
    q = run_until(t_start + 1.7)
    target = np.array([0.4, 0.0])
    assert np.linalg.norm(q - target) < 0.7 * np.linalg.norm(np.array(q0) - target), q


@pytest.mark.realtime
def test_controller_stops_commanding_on_stale_states_and_resumes(rig):
    """trigger=timer on the system clock: while states keep coming it commands; when they
    stop for longer than state_timeout it stops and raises an ERROR; when they come back it
    restarts from the measured configuration."""
    node = "pd_gravity_controller"
    rig.group.start(
        node, {"robot": ROBOT, "trigger": "timer", "rate": 200.0, "state_timeout": 0.1}
    )
    states = rig.publisher(JointState, "joint_states", subscribers=2)  # + the probe
    rig.wait_for_publisher("/effort_command")
    clock = rig.probe.node.get_clock()

    feeding = [False]

    def feed() -> None:  # every 5 ms while feeding, on the probe's own executor
        if feeding[0]:
            states.publish(joint_state(clock.now().nanoseconds))

    rig.probe.node.create_timer(0.005, feed)
    feeding[0] = True
    rig.probe.spin_for(0.5)
    assert len(rig.commands) > 10
    feeding[0] = False
    status = rig.diagnostics(node, lambda s: s["stale.stops"] == 1, timeout=20.0)
    assert status["commanding"] == 0 and status["level"] == 2
    assert "not commanding" in status["message"]
    stopped = len(rig.commands)
    rig.probe.spin_for(0.5)
    assert len(rig.commands) == stopped  # nothing sent on stale data
    # the states come back and keep coming until the diagnostics (1 Hz) say so
    feeding[0] = True
    rig.probe.spin_for(0.5)
    assert len(rig.commands) > stopped + 10
    status = rig.diagnostics(node, lambda s: s["commanding"] == 1 and s["restarts"] == 1)
    assert status["level"] < 2
    feeding[0] = False
    assert_all_commands_safe(rig.commands)


def test_runs_stay_inside_their_domain(rig, tmp_path):
    """A simulator in one leased domain is invisible from another; the environment every
    node process gets forces localhost discovery whatever the caller's environment says."""
    env = isolated_env(7, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_DOMAIN_ID": "0"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"] == "7"
    rig.group.start("sim_bridge", {"robot": ROBOT, "mode": "lockstep"})
    rig.probe.run_until(0.0, 20.0, rig.group.check_alive)  # seen in its own domain
    other = LoopProbe(next_domain_id(), name="outsider")
    try:
        other.spin_for(2.0)
        assert other.node.count_publishers("/joint_states") == 0
        assert other.recording.stamps == []
    finally:
        other.close()


def test_a_blown_up_mujoco_simulation_stops_with_one_line_until_reset(rig):
    """engine:=mujoco (issue 26): MuJoCo would restart a blown-up simulation from q = 0 with
    only a printed warning. Here: the SO-101 of example-robot-data with its effort limits
    raised to 1e6 N·m and reject_factor as loose as it goes; a valid 1e6 N·m on its gripper
    joint ((B⁻¹)₁₁ = 7.3e4: q̈ ~ 7e10, beyond MuJoCo's 1e10) blows it up in its first step;
    sim_bridge says so in one ERROR line, publishes nothing more, reports the fault on
    /diagnostics, and ~/reset starts it again from the initial configuration."""
    so101 = BY_NAME["so101"]
    model = RobotModel(resolve_robot(urdf_path=str(so101.path), package_paths=PACKAGE_PATHS))
    assert model.joint_names[0] == "gripper"
    n = model.n
    rig.group.start(
        "sim_bridge",
        {
            **so101.params(),
            "mode": "lockstep",
            "engine": "mujoco",
            "effort_limits": [1e6],
            "reject_factor": 100.0,
        },
    )
    arrays = rig.publisher(Float64MultiArray, "/sim_bridge/commands")
    probe = rig.probe
    probe.run_until(0.0, 20.0, rig.group.check_alive)
    rig.send(arrays, Float64MultiArray(data=[1e6] + [0.0] * (n - 1)))
    status = rig.diagnostics("sim_bridge", lambda s: "blew up" in str(s["message"]))
    assert status["level"] == 2  # ERROR
    rig.send(arrays, Float64MultiArray(data=[0.0] * n))  # nothing steps a stopped plant
    probe.spin_for(0.5)
    assert probe.latest_time() == 0.0
    log = rig.group.nodes["sim_bridge"].log()
    lines = [line for line in log.splitlines() if "blew up" in line]
    assert len(lines) == 1 and "at joint 'gripper'" in lines[0], lines
    assert "Traceback" not in log and "Nan, Inf or huge" not in log  # MuJoCo's own: not printed

    probe.trigger("/sim_bridge/reset", rig.group.check_alive)
    rig.send(arrays, Float64MultiArray(data=[0.0] * n))
    probe.run_until(0.001, 20.0, rig.group.check_alive)
    _, q, _, _ = probe.recording.arrays()
    # one step of gravity from the initial configuration, not the blown-up state (1e4 rad)
    assert np.all(np.isfinite(q[-1])) and np.max(np.abs(q[-1] - q[0])) < 0.05
    rig.diagnostics("sim_bridge", lambda s: "blew up" not in str(s["message"]))
