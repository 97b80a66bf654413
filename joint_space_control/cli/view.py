"""``jsc view``: the dashboard (a web page of the running loop) as a command, for machines
without the ``ros2`` command line; the same node as the ``dashboard`` executable."""

from __future__ import annotations

import argparse


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``jsc view``."""
    p = subparsers.add_parser(
        "view",
        help="serve the dashboard: the robots of the ROS graph in 3D, live plots, their "
        "parameters as controls (a browser on http://localhost:8080)",
    )
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default: local)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    p.add_argument(
        "ros_args",
        nargs=argparse.REMAINDER,
        help="--ros-args ... for the node (e.g. --ros-args -p window:=5.0)",
    )
    p.set_defaults(handler=lambda args: run(args.host, args.port, args.ros_args))


def run(host: str, port: int, ros_args: list[str]) -> int:
    from joint_space_control.nodes import dashboard

    extra = ros_args[1:] if ros_args[:1] == ["--ros-args"] else ros_args
    argv = ["dashboard", "--ros-args", "-p", f"host:={host}", "-p", f"port:={port}", *extra]
    dashboard.main(argv)
    return 0
