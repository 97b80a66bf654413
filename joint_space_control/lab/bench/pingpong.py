"""The reference for the lockstep loop: a minimal rclpy ping-pong of the same messages,
written the plain way (the way the tutorials write a node).

``ping`` publishes a JointState of n joints (position, velocity, effort; stamp k ms) and
publishes the next one when the answer to it arrives; ``pong`` answers every JointState with
a JointState of the same names carrying effort and the same stamp. Both run ``rclpy`` with
message objects, default QoS depth 10 and ``rclpy.spin`` (a SingleThreadedExecutor): no
physics, no control law. ``ping`` prints one JSON line with the round trips per second.

    python -m joint_space_control.lab.bench.pingpong pong --joints j1,j2
    python -m joint_space_control.lab.bench.pingpong ping --joints j1,j2 --seconds 5
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState

#: Round trips before the clock starts (discovery, first messages).
WARMUP = 200


class Pong(Node):
    def __init__(self, joints: list[str]) -> None:
        super().__init__("bench_pong")
        self.pub = self.create_publisher(JointState, "effort_command", 10)
        self.create_subscription(JointState, "joint_states", self.on_state, 10)
        self.joints = joints

    def on_state(self, msg: JointState) -> None:
        answer = JointState()
        answer.header.stamp = msg.header.stamp
        answer.name = self.joints
        answer.effort = [-p for p in msg.position]
        self.pub.publish(answer)


class Ping(Node):
    def __init__(self, joints: list[str], seconds: float) -> None:
        super().__init__("bench_ping")
        self.pub = self.create_publisher(JointState, "joint_states", 10)
        self.create_subscription(JointState, "effort_command", self.on_command, 10)
        self.joints = joints
        self.seconds = seconds
        self.k = 0
        self.t0 = 0.0
        self.done = Future()

    def send(self) -> None:
        msg = JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(self.k * 1_000_000, 10**9)
        msg.name = self.joints
        msg.position = [0.001 * self.k] * len(self.joints)
        msg.velocity = [0.0] * len(self.joints)
        msg.effort = [0.0] * len(self.joints)
        self.pub.publish(msg)

    def on_command(self, msg: JointState) -> None:
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if stamp != self.k * 1_000_000:
            return
        self.k += 1
        if self.k == WARMUP:
            self.t0 = time.perf_counter()
        elif self.k > WARMUP and time.perf_counter() - self.t0 >= self.seconds:
            self.done.set_result((self.k - WARMUP) / (time.perf_counter() - self.t0))
            return
        self.send()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="pingpong")
    parser.add_argument("role", choices=("ping", "pong"))
    parser.add_argument("--joints", default="joint1,joint2", help="names, comma-separated")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args(argv)
    joints = args.joints.split(",")
    rclpy.init()
    try:
        if args.role == "pong":
            node = Pong(joints)
            try:
                rclpy.spin(node)
            except (KeyboardInterrupt, ExternalShutdownException):
                pass
            return 0
        node = Ping(joints, args.seconds)
        deadline = time.monotonic() + args.timeout
        while node.pub.get_subscription_count() < 1 or node.count_publishers("effort_command") < 1:
            if time.monotonic() > deadline:
                print(json.dumps({"error": "pong not found"}))
                return 1
            time.sleep(0.05)
        time.sleep(0.5)  # let the answer path match too
        node.send()
        rclpy.spin_until_future_complete(node, node.done, timeout_sec=args.timeout)
        if not node.done.done():
            print(json.dumps({"error": f"only {node.k} round trips in {args.timeout} s"}))
            return 1
        print(json.dumps({"round_trips_per_s": node.done.result(), "round_trips": node.k}))
        return 0
    finally:
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
