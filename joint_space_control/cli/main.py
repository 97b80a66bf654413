"""``jsc``: the package's command line. Subcommands wire the library; no maths here."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from joint_space_control.cli import analyze, demo


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="jsc", description="joint_space_control tools")
    sub = parser.add_subparsers(dest="command", required=True)
    p_demo = sub.add_parser(
        "demo",
        help="run the default closed loop (planar_2dof, PD + g(q), "
        "a step) headless and write its results",
    )
    p_demo.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    p_demo.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    p_demo.add_argument(
        "--domain-id",
        type=int,
        default=None,
        help="ROS domain for the run (default: one no other run on this machine uses)",
    )
    p_analyze = sub.add_parser(
        "analyze",
        help="analyse a recorded rosbag2 bag: metrics.json, figures and report.md",
    )
    p_analyze.add_argument("bag", type=Path, help="rosbag2 directory (metadata.yaml + .mcap/.db3)")
    p_analyze.add_argument(
        "--out", type=Path, default=None, help="output directory (default: <BAG>_report)"
    )
    p_analyze.add_argument("--quiet", action="store_true", help="no progress display on stderr")
    p_exp = sub.add_parser(
        "experiment",
        help="run scenarios of THEORY.md §5 end to end (nodes, bag, analysis, theory checks)",
    )
    p_exp.add_argument("names", nargs="*", help="scenario names or YAML files")
    p_exp.add_argument("--list", action="store_true", help="list the installed scenarios")
    p_exp.add_argument("--all", action="store_true", help="run every installed scenario")
    p_exp.add_argument("--out", type=Path, default=Path("out/experiments"), help="output dir")
    p_exp.add_argument(
        "--short", action="store_true", help="CI form: short durations, first and last variant"
    )
    p_exp.add_argument("--jobs", type=int, default=2, help="variants run in parallel")
    p_exp.add_argument(
        "--report", type=Path, default=None, help="also write DIR/results.md (e.g. docs/)"
    )
    p_bench = sub.add_parser(
        "bench",
        help="measure the control loop: law compute, lockstep over ROS 2 vs ping-pong and "
        "in-process, realtime 1 kHz, jsc analyze; prints a table, writes bench.json",
    )
    p_bench.add_argument("--out", type=Path, default=Path("out/bench"), help="output dir")
    p_bench.add_argument("--quick", action="store_true", help="short runs (< 1 min in all)")
    p_bench.add_argument(
        "--sections", type=lambda s: s.split(","), default=None, help="comma-separated subset"
    )
    p_bench.add_argument(
        "--realtime-seconds", type=float, default=None, help="realtime run length [s] (30)"
    )
    p_soak = sub.add_parser(
        "soak",
        help="soak run: realtime 1 kHz loop for minutes, gains changed every second; memory "
        "growth, command safety, parameter updates; writes soak.json, non-zero exit on fail",
    )
    p_soak.add_argument("--minutes", type=float, default=10.0, help="run length [min] (10)")
    p_soak.add_argument("--robot", default="iiwa", help="built-in robot (iiwa)")
    p_soak.add_argument(
        "--controller",
        choices=("inverse_dynamics", "pd_gravity"),
        default="inverse_dynamics",
        help="controller law (inverse_dynamics)",
    )
    p_soak.add_argument("--out", type=Path, default=Path("out/soak"), help="output dir")
    p_recover = sub.add_parser(
        "recover",
        help="rewrite what is readable of a bag whose recorder was killed into a complete bag",
    )
    p_recover.add_argument("bag", type=Path, help="rosbag2 directory (or its .mcap/.db3 file)")
    p_recover.add_argument(
        "--out", type=Path, default=None, help="new bag directory (default: <BAG>_recovered)"
    )
    args = parser.parse_args(argv)
    if args.command == "recover":
        from joint_space_control.cli import recover

        return recover.run(args.bag, args.out)
    if args.command == "soak":
        from joint_space_control.cli import soak

        return soak.run(args.out, args.minutes, args.robot, args.controller)
    if args.command == "experiment":
        from joint_space_control.cli import experiment

        if args.list:
            return experiment.list_scenarios()
        return experiment.run(args.names, args.all, args.out, args.short, args.jobs, args.report)
    if args.command == "bench":
        from joint_space_control.cli import bench

        return bench.run(args.out, args.quick, args.sections, args.realtime_seconds)
    if args.command == "analyze":
        return analyze.run(args.bag, args.out, args.quiet)
    if args.command == "demo":
        return demo.run(args.out, args.duration, args.domain_id)
    return 2  # pragma: no cover - argparse requires a command


if __name__ == "__main__":
    sys.exit(main())
