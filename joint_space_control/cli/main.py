"""``jsc``: the package's command line. Subcommands wire the library; no maths here.

Each subcommand is a module of this package that registers its own parser with
``add_parser(subparsers)`` and the function that runs it as the ``handler`` default, so
adding a command is adding a module to :data:`COMMANDS`, and ``main`` has no per-command
code.
"""

from __future__ import annotations

import argparse
import sys

from joint_space_control.cli import analyze, bench, demo, experiment, recover, soak, tune, view

COMMANDS = (demo, view, analyze, experiment, tune, bench, soak, recover)
"""The subcommand modules, in the order ``jsc --help`` lists them."""


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``) and run the command; its exit code."""
    parser = argparse.ArgumentParser(prog="jsc", description="joint_space_control tools")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    args = parser.parse_args(argv)
    return args.handler(args)


if __name__ == "__main__":
    sys.exit(main())
