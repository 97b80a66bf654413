"""The control path's wait-set loop, in one process (its own rclpy context and a leased
ROS domain): order, draining, entities changed while it spins, stop and drain limits."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Int64

from joint_space_control.ros.control_path import ControlPath

from .conftest import next_domain_id

pytestmark = pytest.mark.integration

QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE
)


@pytest.fixture
def node() -> Iterator[rclpy.node.Node]:
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=next_domain_id())
    node = rclpy.create_node("control_path_test", context=context)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def publish_matched(node, topic: str, values) -> None:
    pub = node.create_publisher(Int64, topic, QOS)
    end = time.monotonic() + 10
    while pub.get_subscription_count() < 1:
        assert time.monotonic() < end, f"no subscriber on {topic}"
        time.sleep(0.01)
    for v in values:
        pub.publish(Int64(data=v))
    assert pub.wait_for_all_acked(rclpy.duration.Duration(seconds=5))


def spin_until(path: ControlPath, done, timeout: float = 10.0) -> None:
    end = time.monotonic() + timeout
    while not done():
        assert time.monotonic() < end, "timed out"
        path.spin_once(0.05)


def test_ready_subscriptions_are_taken_in_creation_order_one_each(node):
    path = ControlPath(node)
    got = []
    path.subscription(Int64, "first", lambda m, i: got.append(("first", m.data)), QOS)
    path.subscription(Int64, "second", lambda m, i: got.append(("second", m.data)), QOS)
    publish_matched(node, "second", [1, 2])
    publish_matched(node, "first", [3, 4])
    time.sleep(0.2)  # both delivered before the first wait
    assert path.spin_once(1.0) == 2
    assert got == [("first", 3), ("second", 1)]  # one message per subscription per wait
    spin_until(path, lambda: len(got) == 4)
    assert got[2:] == [("first", 4), ("second", 2)]


def test_drain_takes_every_queued_message_with_its_info(node):
    path = ControlPath(node)
    got = []
    path.subscription(Int64, "many", lambda m, i: got.append((m.data, i)), QOS, drain=True)
    publish_matched(node, "many", range(20))
    time.sleep(0.2)
    assert path.spin_once(1.0) == 20
    assert [v for v, _ in got] == list(range(20))
    assert all(i["received_timestamp"] >= i["source_timestamp"] > 0 for _, i in got)


def test_raw_delivery(node):
    path = ControlPath(node)
    got = []
    path.subscription(Int64, "raw", lambda m, i: got.append(m), QOS, raw=True)
    publish_matched(node, "raw", [7])
    spin_until(path, lambda: got)
    assert isinstance(got[0], bytes) and got[0][4:12] == (7).to_bytes(8, "little")


def test_subscriptions_added_and_removed_while_spinning(node):
    path = ControlPath(node)
    got = []
    thread = threading.Thread(target=path.spin, daemon=True)
    thread.start()
    try:
        sub = path.subscription(Int64, "late", lambda m, i: got.append(m.data), QOS)
        publish_matched(node, "late", [1])
        end = time.monotonic() + 10
        while not got:
            assert time.monotonic() < end, "a subscription added while spinning is not served"
            time.sleep(0.01)
        path.destroy_subscription(sub)
        end = time.monotonic() + 10
        while node.count_subscribers("late"):
            assert time.monotonic() < end, "the removed subscription is still there"
            time.sleep(0.01)
    finally:
        path.stop()
        thread.join(timeout=5)
    assert not thread.is_alive(), "stop() did not end spin()"
    assert got == [1]


def test_drain_hands_out_what_arrived_before_the_limit_then_returns(node):
    path = ControlPath(node)
    got = []
    path.subscription(Int64, "d", lambda m, i: got.append(m.data), QOS, drain=True)
    publish_matched(node, "d", [1, 2, 3])
    time.sleep(0.2)
    limit = time.time_ns()
    publish_matched(node, "d", [4, 5])
    time.sleep(0.2)
    path.stop()
    path.drain(0.05, limit)
    assert got == [1, 2, 3]


def test_clock_is_taken_on_the_control_path_with_use_sim_time():
    """use_sim_time: /clock leaves the executor's callback group for the control path,
    whose wait sets the node's time; without it there is nothing to take."""
    from rclpy.parameter import Parameter
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=next_domain_id())
    try:
        plain = rclpy.create_node("wall_time", context=context)
        assert ControlPath(plain).take_clock() is False
        node = rclpy.create_node(
            "sim_time",
            context=context,
            parameter_overrides=[Parameter("use_sim_time", Parameter.Type.BOOL, True)],
        )
        path = ControlPath(node)
        clock_subs = lambda: [s for s in node.subscriptions if s.topic_name == "/clock"]  # noqa: E731
        (given,) = clock_subs()
        assert given.callback_group is node.default_callback_group
        assert path.take_clock() is True
        (taken,) = clock_subs()
        assert taken is not given and taken.callback_group is path.group
        assert path.take_clock() is False  # once

        pub = plain.create_publisher(Clock, "/clock", qos_profile_sensor_data)
        end = time.monotonic() + 10
        while pub.get_subscription_count() < 1:
            assert time.monotonic() < end, "/clock not matched"
            time.sleep(0.01)
        for sec in (7, 8):  # best effort, as rclpy's time source asks: sent until taken
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = sec, 250_000_000
            end = time.monotonic() + 10
            while node.get_clock().now().nanoseconds != sec * 10**9 + 250_000_000:
                assert time.monotonic() < end, f"the node's time is not {sec}.25 s"
                pub.publish(msg)
                path.spin_once(0.05)
        path.close()
        node.destroy_node()
        plain.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
