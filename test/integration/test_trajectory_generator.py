"""The trajectory_generator node as a real process: what it publishes on ``reference`` (on
start and through ``~/publish``), starting from the current configuration, in simulation
time, and how it rejects invalid parameters. Joint states and /clock come from the test's
own rclpy node (no simulator needed); every process is stopped also on failure."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.processes import processes
from joint_space_control.processes.probe import LoopProbe
from joint_space_control.processes.processes import ProcessGroup
from joint_space_control.ros.messages import CONTROL_QOS, REFERENCE_QOS, stamp_to_ns

from .conftest import JOINTS, next_domain_id

pytestmark = pytest.mark.integration

NODE = "trajectory_generator"
ROBOT = "planar_2dof"


class Harness:
    """A generator process plus the test's probe: references received, joint states and
    /clock sent on demand."""

    def __init__(self, workdir: Path, params: dict[str, Any]) -> None:
        domain = next_domain_id()
        self.group = ProcessGroup(workdir, domain)
        self.probe: LoopProbe | None = None
        try:
            self.group.start(NODE, {"robot": ROBOT, **params})
            self.probe = LoopProbe(domain)
            node = self.probe.node
            self.references: list[JointTrajectory] = []
            node.create_subscription(
                JointTrajectory, "reference", self.references.append, REFERENCE_QOS
            )
            self._state_pub = node.create_publisher(JointState, "joint_states", CONTROL_QOS)
            self._clock_pub = node.create_publisher(Clock, "/clock", 10)
            self.q: list[float] | None = None
            self.clock_ns: int | None = None
            node.create_timer(0.02, self._tick)
            self.params = AsyncParameterClient(node, NODE)
            self.probe.spin_until(
                self.params.services_are_ready, 20.0, "the generator", self.group.check_alive
            )
        except BaseException:
            self.close()
            raise

    def _tick(self) -> None:
        if self.q is not None:
            self._state_pub.publish(JointState(name=JOINTS[ROBOT], position=self.q))
        if self.clock_ns is not None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(self.clock_ns, 1_000_000_000)
            self._clock_pub.publish(msg)

    def next_reference(self, since: int | None = None, timeout: float = 10.0) -> JointTrajectory:
        """The first reference received after the first ``since`` (default: from now)."""
        count = len(self.references) if since is None else since
        self.probe.spin_until(
            lambda: len(self.references) > count, timeout, "a reference", self.group.check_alive
        )
        return self.references[count]

    def publish(self) -> tuple[Any, JointTrajectory | None]:
        """Call ``~/publish``: its answer, and the reference it published (if it did)."""
        count = len(self.references)
        answer = self.probe.call_trigger(f"/{NODE}/publish", timeout=10.0, resend=False)
        return answer, self.next_reference(since=count) if answer.success else None

    def set_atomically(self, values: dict[str, Any]) -> Any:
        future = self.params.set_parameters_atomically(
            [Parameter(k, value=v) for k, v in values.items()]
        )
        self.probe.spin_until(future.done, 10.0, "set_parameters_atomically")
        return future.result().result

    def close(self) -> None:
        if self.probe is not None:
            self.probe.close()
        self.group.stop_all()


@pytest.fixture
def generator(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    # The package registers the executable; this keeps the test independent of that order.
    monkeypatch.setitem(
        processes.EXECUTABLES, NODE, "joint_space_control.nodes.trajectory_generator"
    )
    harnesses: list[Harness] = []

    def start(**params: Any) -> Harness:
        harness = Harness(tmp_path / f"gen{len(harnesses)}", params)
        harnesses.append(harness)
        return harness

    yield start
    for harness in harnesses:
        harness.close()


def arrays(msg: JointTrajectory) -> tuple[np.ndarray, ...]:
    times = np.array(
        [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in msg.points]
    )
    fields = [
        np.array([list(getattr(p, name)) for p in msg.points])
        for name in ("positions", "velocities", "accelerations")
    ]
    return (times, *fields)


def test_sinusoid_on_start_and_on_request(generator):
    center, amplitude, omega, phase = [0.1, -0.2], [0.3, 0.1], [2.0, 3.0], [0.0, 0.5]
    gen = generator(
        shape="sinusoid",
        center=center,
        amplitude=amplitude,
        omega=omega,
        phase=phase,
        duration=1.0,
        sample_period=0.01,
        use_sim_time=True,
    )
    first = gen.next_reference()  # publish_on_start: once the probe subscribed
    assert list(first.joint_names) == JOINTS[ROBOT]
    assert stamp_to_ns(first.header.stamp) == 0  # start on receipt
    t, q, dq, ddq = arrays(first)
    np.testing.assert_allclose(t, np.arange(101) * 0.01, rtol=0, atol=1e-9)
    angle = np.outer(t, omega) + phase
    np.testing.assert_allclose(q, center + np.multiply(amplitude, np.sin(angle)), atol=1e-9)
    np.testing.assert_allclose(dq, np.multiply(amplitude, omega) * np.cos(angle), atol=1e-8)
    w2 = np.multiply(amplitude, np.square(omega))
    np.testing.assert_allclose(ddq, -w2 * np.sin(angle), atol=1e-7)

    answer, again = gen.publish()
    assert answer.success, answer.message
    assert "101 point(s)" in answer.message
    assert again == first


def test_start_delay_is_stamped_in_simulation_time(generator):
    gen = generator(
        shape="step",
        target=[0.5, -0.3],
        start_delay=0.5,
        publish_on_start=False,
        use_sim_time=True,
    )
    gen.clock_ns = 100_000_000_000  # simulation time 100 s, held
    # Until the generator has received /clock its time is 0 and the stamp 0.5 s.
    for _ in range(50):
        answer, msg = gen.publish()
        assert answer.success, answer.message
        if stamp_to_ns(msg.header.stamp) != 500_000_000:
            break
    assert stamp_to_ns(msg.header.stamp) == 100_500_000_000
    (point,) = msg.points
    assert list(point.positions) == [0.5, -0.3]
    assert len(point.velocities) == 0 and len(point.accelerations) == 0


def test_shapes_start_from_the_current_configuration(generator):
    q0 = [0.25, -0.75]
    gen = generator(
        shape="quintic",
        target=[0.5, -0.3],
        duration=2.0,
        start_from_current=True,
        publish_on_start=False,
    )
    answer, _ = gen.publish()  # no joint states yet: the service says so
    assert not answer.success and "no joint_states" in answer.message, answer.message

    gen.q = q0
    answer, msg = gen.publish()
    assert answer.success, answer.message
    t, q, dq, ddq = arrays(msg)
    np.testing.assert_array_equal(t, [0.0, 2.0])
    np.testing.assert_array_equal(q, [q0, [0.5, -0.3]])
    np.testing.assert_array_equal(dq, np.zeros((2, 2)))
    np.testing.assert_array_equal(ddq, np.zeros((2, 2)))

    # A sinusoid with an empty centre is centred on the current configuration.
    result = gen.set_atomically(
        {"shape": "sinusoid", "amplitude": 0.2, "omega": 1.0, "phase": math.pi / 2}
    )
    assert result.successful, result.reason
    answer, msg = gen.publish()
    assert answer.success, answer.message
    t, q, dq, _ = arrays(msg)
    np.testing.assert_allclose(q[0], np.add(q0, 0.2), atol=1e-12)  # q̄ + Δ sin(π/2): at rest
    np.testing.assert_allclose(dq[0], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(t[-1], 2.0)  # 'duration' is shared with the quintic


def test_publish_on_start_waits_for_the_current_configuration(generator):
    gen = generator(shape="sinusoid", amplitude=0.1, omega=2.0, start_from_current=True)
    gen.probe.spin_for(0.5)
    assert gen.references == [], "published before any joint state"
    gen.q = [-0.4, 0.6]
    t, q, dq, _ = arrays(gen.next_reference())
    np.testing.assert_allclose(q[0], gen.q, atol=1e-12)  # φ = 0: starts at the centre...
    np.testing.assert_allclose(dq[0], [0.2, 0.2], atol=1e-12)  # ... moving (Δω)
    np.testing.assert_allclose(t[-1], 5.0)  # the default duration


def test_invalid_parameters_rejected_and_waypoints_set_atomically(generator):
    gen = generator(target=[0.2, 0.1], publish_on_start=False)
    bad_updates = [
        {"shape": "triangle"},
        {"target": [0.1, 0.2, 0.3]},
        {"target": float("nan")},
        {"target": [4.0, 0.0]},  # outside joint1's limits (±3.14159)
        {"omega": -1.0},
        {"duration": 0.0},
        {"sample_period": float("inf")},
        {"waypoints": [0.1, 0.2, 0.3]},  # not a multiple of 2 joints
        {"waypoint_times": [1.0, 0.5]},
        {"start_delay": -1.0},
        {"amplitude": "large"},
        {"shape": "sinusoid"},  # centre empty without start_from_current
        {"shape": "waypoints"},  # none given
    ]
    for update in bad_updates:
        (result,) = gen.probe.set_parameters(NODE, update)
        assert not result.successful, f"{update} was accepted"
        assert result.reason, f"{update} rejected without a reason"
    shape, target, omega = gen.probe.get_parameters(NODE, ["shape", "target", "omega"])
    assert shape == "step" and list(target) == [0.2, 0.1] and omega == 1.0
    (readonly,) = gen.probe.set_parameters(NODE, {"robot": "iiwa"})
    assert not readonly.successful

    answer, msg = gen.publish()
    assert answer.success, answer.message
    (point,) = msg.points
    assert list(point.positions) == [0.2, 0.1]

    # Waypoints: positions only, the controllers spline them; both lists in one request.
    waypoints = {"waypoints": [0.1, 0.2, 0.4, -0.1, 0.0, 0.0], "waypoint_times": [0.5, 1.0, 2.0]}
    assert not gen.set_atomically({"shape": "waypoints", "waypoint_times": [0.5, 1.0]}).successful
    result = gen.set_atomically({"shape": "waypoints", **waypoints})
    assert result.successful, result.reason
    answer, msg = gen.publish()
    assert answer.success, answer.message
    t, q, dq, ddq = arrays(msg)
    np.testing.assert_array_equal(t, [0.5, 1.0, 2.0])
    np.testing.assert_array_equal(q, [[0.1, 0.2], [0.4, -0.1], [0.0, 0.0]])
    assert dq.size == 0 and ddq.size == 0


def test_controller_samples_the_generated_sinusoid_exactly(make_loop, monkeypatch):
    """generator → pd_gravity_controller → sim_bridge in lockstep: stamped 0.3 s ahead in
    simulation time, the controller's q_d, q̇_d (its ~/state) is the analytic sinusoid."""
    monkeypatch.setitem(
        processes.EXECUTABLES, NODE, "joint_space_control.nodes.trajectory_generator"
    )
    center, amplitude, omega, phase, start = [0.2, -0.1], [0.3, 0.2], [3.0, 5.0], 0.0, 0.3
    loop = make_loop(ROBOT)
    loop.group.start(
        NODE,
        {
            "robot": ROBOT,
            "shape": "sinusoid",
            "center": center,
            "amplitude": amplitude,
            "omega": omega,
            "phase": phase,
            "duration": 1.0,
            "start_delay": start,
            "publish_on_start": False,
            "use_sim_time": True,
        },
    )
    probe = loop.probe
    states: list[list[float]] = []
    probe.observe(
        Float64MultiArray,
        "/pd_gravity_controller/state",
        lambda msg: states.append(list(msg.data)),
    )
    # The simulator is paused at t = 0, so the generator's (simulation) time is 0 as well.
    # Volatile reference: publish until the controller is matched (repeats are identical).
    for _ in range(100):
        answer = probe.call_trigger(f"/{NODE}/publish", timeout=20.0, resend=False)
        assert answer.success, answer.message
        if "to 1 subscriber(s)" in answer.message:  # the controller
            break
        probe.spin_for(0.1)
    assert "starting at t=0.300 s" in answer.message, answer.message
    assert probe.call_trigger("/sim_bridge/resume").success
    loop.run_until(1.5)
    loop.pause()

    data = np.array(states)
    t, rows = data[:, 0], data[:, 1:].reshape(len(data), 12, 2)
    during = (t >= start) & (t < start + 1.0)
    assert np.count_nonzero(during) > 950, np.count_nonzero(during)
    angle = np.outer(t[during] - start, omega) + phase
    q_d, dq_d = rows[during, 0], rows[during, 1]
    np.testing.assert_allclose(q_d, center + np.multiply(amplitude, np.sin(angle)), atol=1e-9)
    np.testing.assert_allclose(dq_d, np.multiply(amplitude, omega) * np.cos(angle), atol=1e-7)
    before = t < start
    np.testing.assert_array_equal(rows[before, 0], np.zeros((np.count_nonzero(before), 2)))
    after = t >= start + 1.0  # holds the last sample
    np.testing.assert_allclose(rows[after, 0], rows[after, 0][:1].repeat(after.sum(), 0))
