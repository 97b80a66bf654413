"""The reference page of every node, generated from its declarations so that it cannot drift.

    python -m joint_space_control.nodes.reference docs/reference           # write the pages
    python -m joint_space_control.nodes.reference docs/reference --check   # exit 1 if stale

One Markdown page per executable node (``<node>.md``) and an index (``README.md``). A page
says what the node does (the first paragraph of its module's docstring), how to run it, its
topics and services (the ``INTERFACE`` constant beside the node's code: kind, relative
name, type, meaning), its safety counters where it declares them, and every parameter from
its :class:`~joint_space_control.control.parameters.ParamSpec` declarations: type, default,
range or choices, unit, read-only or runtime, description. Nothing here is typed twice:
test/unit/test_node_reference.py renders the pages and fails when docs/reference differs.

No node is started; the node modules are imported for their declarations only.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from joint_space_control.control.parameters import (
    REALTIME_PARAMETERS,
    ROBOT_PARAMETERS,
    ParamSpec,
)

#: The command that regenerates the pages (said by the test when they are stale).
COMMAND = "python -m joint_space_control.nodes.reference docs/reference"
#: The index page of the folder (GitHub shows it when the folder is opened).
INDEX = "README.md"
#: The package's parameter files (``--params-file``), package data.
CONFIG = Path(__file__).resolve().parents[1] / "config"
#: Parameter files of a node their name does not start with.
WORLD_FILES = {"two_robots.yaml": "sim_bridge"}

#: (kind, relative name, type, meaning): one row of a node's ``INTERFACE``.
Endpoint = tuple[str, str, str, str]
#: The kinds of an endpoint, in the order a page lists them.
KINDS = ("subscribes", "publishes", "serves", "calls")


@dataclass(frozen=True)
class Group:
    """Parameters shown together under a title, with a line on what they have in common."""

    title: str
    note: str
    specs: tuple[ParamSpec, ...]


@dataclass(frozen=True)
class NodeReference:
    """What one node's page is made of."""

    executable: str
    summary: str
    interface: tuple[Endpoint, ...]
    parameters: tuple[ParamSpec, ...]
    """Every parameter the node declares, in its order."""
    groups: tuple[Group, ...]
    counters: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    guides: tuple[tuple[str, str], ...] = ()
    """(title, link relative to docs/): the pages that explain how to use it."""

    @property
    def parameter_files(self) -> list[str]:
        return parameter_files(self.executable)


def parameter_files(executable: str) -> list[str]:
    """The package's parameter files for ``executable``: those whose name starts with it,
    and the worlds of :data:`WORLD_FILES`."""
    return sorted(
        path.name
        for path in CONFIG.glob("*.yaml")
        if WORLD_FILES.get(path.name, "") == executable
        or (path.name not in WORLD_FILES and path.stem.startswith(executable))
    )


#: The group that takes every parameter no other group names.
REST = None


def grouped(
    specs: Sequence[ParamSpec], groups: Sequence[tuple[str, str, Iterable[str] | None]]
) -> tuple[Group, ...]:
    """``specs`` in the groups whose names hold them, in their declared order; the group
    whose names are :data:`REST` takes the others. Empty groups are left out; every
    parameter is in exactly one group."""
    sets = [None if names is REST else set(names) for _, _, names in groups]
    rest = sets.index(None)
    chosen: list[list[ParamSpec]] = [[] for _ in groups]
    for spec in specs:
        index = next((k for k, names in enumerate(sets) if names and spec.name in names), rest)
        chosen[index].append(spec)
    return tuple(
        Group(title, note, tuple(found))
        for (title, note, _), found in zip(groups, chosen, strict=True)
        if found
    )


def _names(specs: Iterable[ParamSpec]) -> tuple[str, ...]:
    return tuple(spec.name for spec in specs)


ROBOT_GROUP = (
    "The robot",
    "Read at start, the same on every node: `robot_description`, else `urdf_path`, else "
    "`robot` ([Bring your own robot](../robots.md)).",
    _names(ROBOT_PARAMETERS),
)
REALTIME_GROUP = (
    "Realtime threads",
    "What the threads that must be on time run with, when the system permits it "
    "([Thread priority](../performance.md#thread-priority)).",
    _names(REALTIME_PARAMETERS),
)


def summary(module: str) -> str:
    """The first paragraph of ``module``'s docstring as Markdown, without the leading
    ``name``: ("``sim_bridge``: the plant ..." gives "The plant ...")."""
    doc = importlib.import_module(module).__doc__ or ""
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    text = markdown_of_rst(paragraph)
    text = re.sub(r"^`[\w]+`:\s*", "", text)
    return text[:1].upper() + text[1:]


def markdown_of_rst(text: str) -> str:
    """Docstring markup as Markdown: ``x`` and :role:`~x` become `x`."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def controller(executable: str, module: str) -> NodeReference:
    from joint_space_control.control.configure import (
        COMMAND_PARAMETERS,
        MODEL_PARAMETERS,
        controller_kind,
    )
    from joint_space_control.nodes import controller_base

    kind = controller_kind(executable)
    return NodeReference(
        executable,
        summary(module),
        controller_base.INTERFACE,
        kind.parameters,
        grouped(
            kind.parameters,
            [
                ROBOT_GROUP,
                (
                    "Control",
                    "The same on both controllers: [Gains](../parameters.md#gains), "
                    "[Sampling and velocity](../parameters.md#sampling-and-velocity), "
                    "[Trigger](../parameters.md#trigger).",
                    REST,
                ),
                (
                    "The law",
                    "What only this controller has.",
                    _names(kind.law_parameters),
                ),
                (
                    "Towards the robot",
                    "How the command reaches it: sim_bridge's `effort_command`, or a "
                    "ros2_control robot's forward effort controller ([Towards a "
                    "ros2_control robot](../parameters.md#towards-a-ros2_control-robot)).",
                    _names(COMMAND_PARAMETERS),
                ),
                (
                    "The controller's model",
                    "The controller's own model of the robot (B̂, Ĉ, F̂, ĝ), which may differ "
                    "from the plant on purpose; a change rebuilds it.",
                    MODEL_PARAMETERS,
                ),
                REALTIME_GROUP,
            ],
        ),
        controller_base.COUNTERS,
        (
            "`pd_gravity_controller` and `inverse_dynamics_controller` have the same topics, "
            "the same common parameters and the same `~/state` layout: run one of them per "
            "robot.",
        ),
        (
            ("Parameters: choosing values", "parameters.md"),
            ("Safety", "safety.md"),
            ("Tutorial: watch and tune it live", "tutorials/2-watch-and-tune.md"),
        ),
    )


def sim_bridge() -> NodeReference:
    from sim_bridge import node
    from sim_bridge.parameters import PARAMETERS, PLANT_PARAMETERS

    return NodeReference(
        "sim_bridge",
        summary("sim_bridge.node"),
        node.INTERFACE,
        PARAMETERS,
        grouped(
            PARAMETERS,
            [
                ROBOT_GROUP,
                ("The world", "One set for the whole world, however many robots.", REST),
                (
                    "Each robot's plant",
                    "With `robots`, these and the robot parameters are each robot's own: "
                    "`<name>.<parameter>` ([Several robots](../robots.md#several-robots)).",
                    _names(PLANT_PARAMETERS),
                ),
                REALTIME_GROUP,
            ],
        ),
        node.COUNTERS,
        (
            "With `robots`, each robot's topics and `~/release` are in its namespace "
            "(`<robot>/joint_states`, `<robot>/effort_command`, `<robot>/sim_bridge/commands`, "
            "`<robot>/sim_bridge/wrench`, `<robot>/sim_bridge/release`, ...) and its counters "
            "on `/diagnostics` are prefixed `<robot>.`; `/clock`, `~/reset`, `~/pause`, "
            "`~/resume` and `/diagnostics` are the world's.",
        ),
        (
            ("What the plant is, exactly", "plant.md"),
            ("Bring your own robot", "robots.md"),
            ("Safety", "safety.md"),
            ("Tutorial: a first loop", "tutorials/1-first-loop.md"),
        ),
    )


def trajectory_generator() -> NodeReference:
    from joint_space_control.nodes import trajectory_generator as module

    return NodeReference(
        "trajectory_generator",
        summary(module.__name__),
        module.INTERFACE,
        module.PARAMETERS,
        grouped(
            module.PARAMETERS,
            [ROBOT_GROUP, ("The reference", "Checked as a whole against the shape.", REST)],
        ),
        guides=(("References", "references.md"),),
    )


def recorder() -> NodeReference:
    from joint_space_control.nodes import recorder as module

    return NodeReference(
        "recorder",
        summary(module.__name__),
        module.INTERFACE,
        module.PARAMETERS,
        grouped(module.PARAMETERS, [("Recording", "All read at start.", REST)]),
        notes=(
            "SIGINT and SIGTERM close the bag (summary and `metadata.yaml` written); after a "
            "SIGKILL, `jsc recover BAG` makes a complete bag of what reached the disk.",
        ),
        guides=(
            ("Recording", "recording.md"),
            ("Tutorial: record and analyse", "tutorials/3-record-and-analyse.md"),
        ),
    )


def dashboard() -> NodeReference:
    from joint_space_control.nodes import dashboard as module

    return NodeReference(
        "dashboard",
        summary(module.__name__),
        module.INTERFACE,
        module.PARAMETERS,
        grouped(module.PARAMETERS, [("The page", "Served on `host`:`port`.", REST)]),
        notes=(
            "It never publishes effort, and reaches the loop only through what any user "
            "could call: topics, the standard parameter services and the plant's services.",
        ),
        guides=(
            ("The dashboard", "dashboard.md"),
            ("Tutorial: watch and tune it live", "tutorials/2-watch-and-tune.md"),
        ),
    )


def nodes() -> tuple[NodeReference, ...]:
    """Every executable node, in the order a user meets them."""
    return (
        sim_bridge(),
        controller("pd_gravity_controller", "joint_space_control.nodes.pd_gravity_controller"),
        controller(
            "inverse_dynamics_controller",
            "joint_space_control.nodes.inverse_dynamics_controller",
        ),
        trajectory_generator(),
        recorder(),
        dashboard(),
    )


# -- rendering ---------------------------------------------------------------------------


def _number(x: float) -> str:
    short = f"{x:g}"
    return short if float(short) == x else f"{x:.15g}"


def type_text(spec: ParamSpec) -> str:
    """The ROS type of the parameter, with its shape."""
    kind = spec.type
    if kind == "flag":
        return "bool"
    if kind == "number":
        return "integer" if isinstance(spec.default, int) else "double"
    if kind == "numbers":
        if spec.length:
            return f"double[{spec.length}]"
        return "double or double[] per joint" if spec.dynamic else "double[]"
    return "string[]" if kind == "names" else "string"


def default_text(spec: ParamSpec) -> str:
    """The declared default as a parameter file would give it."""
    value = spec.default
    if isinstance(value, bool):
        text = str(value).lower()
    elif isinstance(value, int | float):
        text = _number(value)
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(_number(v) if not isinstance(v, str) else v for v in value) + "]"
    else:
        text = value or '""'
    return f"`{text}`"


def range_text(spec: ParamSpec) -> str:
    """The declared choices or range (the descriptor's words), "" when there is none."""
    if spec.choices:
        return " \\| ".join(f"`{choice}`" for choice in spec.choices)
    return f"`{spec.bound}`" if spec.bound else ""


#: The "set" column: read-only parameters are given at start only.
READ_ONLY, RUNTIME = "start (RO)", "runtime"


def cell(text: str) -> str:
    """Text safe in a Markdown table cell: pipes escaped, and outside code spans a tag-like
    ``<name>`` not taken for HTML."""
    parts = re.split(r"(`[^`]*`)", text.replace("|", "\\|"))
    return "".join(
        part if part.startswith("`") else re.sub(r"<(?=[A-Za-z])", "&lt;", part) for part in parts
    )


def parameter_row(spec: ParamSpec) -> str:
    cells = (
        f"`{spec.name}`",
        type_text(spec),
        default_text(spec),
        range_text(spec),
        spec.unit,
        READ_ONLY if spec.read_only else RUNTIME,
        cell(spec.description),
    )
    return "| " + " | ".join(cells) + " |"


def endpoint_name(name: str) -> str:
    return ", ".join(f"`{part}`" for part in name.split(", "))


def endpoint_row(endpoint: Endpoint) -> str:
    kind, name, msg_type, meaning = endpoint
    shown = f"`{msg_type}`" if "/" in msg_type else msg_type
    return f"| {kind} | {endpoint_name(name)} | {shown} | {cell(meaning)} |"


GENERATED = "<!-- Generated by `{command}` from the nodes' declarations; do not edit. -->"


def render_node(node: NodeReference) -> str:
    exe = node.executable
    files = node.parameter_files
    given = f"--params-file config/{files[0]}" if files else "-p name:=value"
    lines = [
        GENERATED.format(command=COMMAND),
        "",
        f"# `{exe}`",
        "",
        node.summary,
        "",
        "```bash",
        f"ros2 run joint_space_control {exe} --ros-args -p name:=value   # a ROS 2 workspace",
        f".venv/bin/{exe} --ros-args {given}   # the checkout's virtual environment",
        "```",
        "",
    ]
    if files:
        links = ", ".join(f"[`{name}`](../../joint_space_control/config/{name})" for name in files)
        lines += [f"Parameter files shipped with the package (`config/`): {links}.", ""]
    if node.guides:
        links = ", ".join(f"[{title}](../{link})" for title, link in node.guides)
        lines += [f"How to use it: {links}.", ""]
    lines += [
        "## Topics and services",
        "",
        "Relative names resolve in the node's namespace; `~/x` is `<node name>/x`. "
        "`<...>` stands for a name found in the ROS graph.",
        "",
        "| | name | type | meaning |",
        "|---|---|---|---|",
    ]
    order = {kind: k for k, kind in enumerate(KINDS)}
    for endpoint in sorted(node.interface, key=lambda e: order.get(e[0], len(KINDS))):
        lines.append(endpoint_row(endpoint))
    lines.append("")
    for note in node.notes:
        lines += [note, ""]
    if node.counters:
        counters = ", ".join(f"`{c}`" for c in node.counters)
        lines += [
            f"Safety counters on `/diagnostics`, since the start: {counters} "
            "([Safety](../safety.md)).",
            "",
        ]
    lines += [
        "## Parameters",
        "",
        f"`{READ_ONLY}`: given at start only (`-p`, `--params-file`). `{RUNTIME}`: can also "
        "be changed while the node runs (`ros2 param set`, the dashboard); an invalid value "
        "is refused with the reason and the old value stays. A range applies to each value "
        "of a list.",
        "",
    ]
    for group in node.groups:
        lines += [
            f"### {group.title}",
            "",
            group.note,
            "",
            "| parameter | type | default | range | unit | set | description |",
            "|---|---|---|---|---|---|---|",
            *(parameter_row(spec) for spec in group.specs),
            "",
        ]
    lines += [
        "Besides these, rclpy's `use_sim_time` (bool, default `false`): the node's clock "
        "follows `/clock`.",
    ]
    return "\n".join(lines) + "\n"


def render_index(references: Sequence[NodeReference]) -> str:
    lines = [
        GENERATED.format(command=COMMAND),
        "",
        "# Node reference",
        "",
        "One page per node: its topics and services, and every parameter with its type, "
        "default, range, unit and whether it can change at runtime, generated from the "
        "declarations in the code. How to choose the values is in "
        "[Parameters](../parameters.md); the walk-throughs are the "
        "[tutorials](../tutorials/README.md).",
        "",
        "| node | what it does |",
        "|---|---|",
        *(f"| [`{n.executable}`]({n.executable}.md) | {cell(n.summary)} |" for n in references),
        "",
        "## What every node shares",
        "",
        "- **Running.** `ros2 run joint_space_control <node> --ros-args ...` in a ROS 2 "
        "workspace, `.venv/bin/<node> --ros-args ...` from the package's virtual environment. "
        "The standard `--ros-args` work: `-p name:=value`, `--params-file FILE`, "
        "`-r old:=new`, `-r __ns:=/robot1`, `-r __node:=name`.",
        "- **Names.** Topics and services are relative: in a namespace, a node's topics "
        "move with it. `~/x` is the node's own: `/sim_bridge/release` for `sim_bridge`.",
        "- **Parameters.** Checked against their declaration at start (an invalid value is "
        "one `error:` line and exit code 2; a name the node does not have is one warning) "
        "and at runtime (refused with the reason, the old value kept). A whole number given "
        "for a double is taken as that double (`-p publish_rate:=250`). Descriptors carry the "
        "range, so rqt_reconfigure and the dashboard draw sliders.",
        "- **Time.** With `use_sim_time:=true` a node's clock follows `/clock`, which "
        "`sim_bridge` publishes.",
        "- **Also on every node**: `/rosout`, `/parameter_events` and rclpy's parameter "
        "services (`~/list_parameters`, `~/describe_parameters`, `~/get_parameters`, "
        "`~/set_parameters`, ...).",
        "- **Stopping.** SIGINT and SIGTERM stop a node cleanly; a node started by `jsc` "
        "stops by itself once the process that started it is gone.",
    ]
    return "\n".join(lines) + "\n"


def render(references: Sequence[NodeReference] | None = None) -> dict[str, str]:
    """{file name: Markdown} of every page and the index."""
    references = nodes() if references is None else references
    pages = {f"{n.executable}.md": render_node(n) for n in references}
    pages[INDEX] = render_index(references)
    return pages


def differences(folder: Path, pages: dict[str, str] | None = None) -> list[str]:
    """What in ``folder`` differs from the rendered pages: missing, changed, or Markdown
    files that are not generated (empty when it is up to date)."""
    pages = render() if pages is None else pages
    found = {path.name for path in folder.glob("*.md")} if folder.is_dir() else set()
    out = [f"{name}: missing" for name in sorted(set(pages) - found)]
    out += [
        f"{name}: differs"
        for name in sorted(set(pages) & found)
        if (folder / name).read_text(encoding="utf-8") != pages[name]
    ]
    out += [f"{name}: not generated (remove it)" for name in sorted(found - set(pages))]
    return out


def write(folder: Path) -> list[Path]:
    """Write every page into ``folder`` (created); returns the files written."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in render().items():
        path = folder / name
        path.write_text(text, encoding="utf-8")
        written.append(path)
    return written


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m joint_space_control.nodes.reference",
        description="Write the nodes' reference pages from their declarations.",
    )
    parser.add_argument("folder", type=Path, help="where the pages go, e.g. docs/reference")
    parser.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 if the pages differ"
    )
    args = parser.parse_args(argv)
    if args.check:
        stale = differences(args.folder)
        for line in stale:
            print(f"{args.folder / line}", file=sys.stderr)
        if stale:
            print(f"stale: run {COMMAND}", file=sys.stderr)
        return 1 if stale else 0
    for path in write(args.folder):
        print(path)
    for line in differences(args.folder):
        print(f"{args.folder / line}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
