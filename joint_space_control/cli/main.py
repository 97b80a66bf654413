"""``jsc``: the package's command line. Subcommands wire the library; no maths here.

Each subcommand is a module of this package that registers its own parser with
``add_parser(subparsers)`` and the function that runs it as the ``handler`` default, so
adding a command is adding a module to :data:`COMMANDS`, and ``main`` has no per-command
code. The product's commands (``demo``, ``view``, ``analyze``, ``recover``) need only the
package; the workbench's (``experiment``, ``tune``) and the lab's (``bench``, ``soak``)
need its extra (``pip install 'joint_space_control[workbench]'``, ``[lab]``): without it
the command is listed and says so in one line.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from types import ModuleType

#: The subcommand modules (of joint_space_control.cli), in the order ``jsc --help`` lists
#: them, each with the extra it needs ("": none).
COMMANDS = (
    ("demo", ""),
    ("view", ""),
    ("analyze", ""),
    ("experiment", "workbench"),
    ("tune", "workbench"),
    ("bench", "lab"),
    ("soak", "lab"),
    ("recover", ""),
)


def _missing_extra(name: str, extra: str, err: ImportError):
    """A stand-in subcommand for a command whose extra is not installed."""

    def add_parser(sub: argparse._SubParsersAction) -> None:
        p = sub.add_parser(name, help=f"(needs: pip install 'joint_space_control[{extra}]')")
        p.add_argument("rest", nargs=argparse.REMAINDER)

        def handler(args: argparse.Namespace) -> int:
            print(
                f"jsc {name}: error: needs the {extra} extra ({err.name} is not installed): "
                f"pip install 'joint_space_control[{extra}]'",
                file=sys.stderr,
            )
            return 2

        p.set_defaults(handler=handler)

    return add_parser


def _command(name: str, extra: str) -> ModuleType | object:
    try:
        return importlib.import_module(f"joint_space_control.cli.{name}")
    except ImportError as err:
        if not extra or err.name is None or err.name.startswith("joint_space_control"):
            raise

        class Missing:
            add_parser = staticmethod(_missing_extra(name, extra, err))

        return Missing


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``) and run the command; its exit code."""
    parser = argparse.ArgumentParser(prog="jsc", description="joint_space_control tools")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, extra in COMMANDS:
        _command(name, extra).add_parser(sub)
    args = parser.parse_args(argv)
    return args.handler(args)


if __name__ == "__main__":
    sys.exit(main())
