"""docs/reference, one page per node, is what the nodes' declarations render
(joint_space_control.nodes.reference), so it cannot drift from the code:

- the pages rendered into a temporary folder equal the committed ones, and a stale page
  names the command that regenerates it;
- every executable node has a page, and every parameter it declares is on it, in exactly
  one group (sim_bridge's per-robot groups are exactly what ``prefixed`` makes per robot);
- every topic and service a node's code creates under a literal name is in its
  ``INTERFACE``, every declared one is named in the code it runs, and every declared type
  exists.
"""

from __future__ import annotations

import ast
import importlib
import re
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from joint_space_control.nodes import reference
from joint_space_control.nodes.reference import COMMAND, KINDS, NodeReference
from sim_bridge.parameters import prefixed

ROOT = Path(__file__).resolve().parents[2]
FOLDER = ROOT / "docs" / "reference"
NODES = {node.executable: node for node in reference.nodes()}

#: The modules whose code creates each node's endpoints (the node's own, and its parts).
SOURCES = {
    "sim_bridge": ("sim_bridge/node.py", "sim_bridge/robot.py"),
    "pd_gravity_controller": ("joint_space_control/nodes/controller_base.py",),
    "inverse_dynamics_controller": ("joint_space_control/nodes/controller_base.py",),
    "trajectory_generator": ("joint_space_control/nodes/trajectory_generator.py",),
    "recorder": ("joint_space_control/nodes/recorder.py",),
    "dashboard": ("joint_space_control/nodes/dashboard.py",),
}
#: What a node does through the ROS layer every node shares (diagnostics, the robot
#: description, the plant's mode): its string constants count as the node's code too.
SHARED = sorted((ROOT / "joint_space_control" / "ros").glob("*.py"))
#: The call that creates an endpoint, and the kind of endpoint it makes.
CREATES = {
    "create_publisher": "publishes",
    "create_subscription": "subscribes",
    "subscription": "subscribes",  # the control path's
    "create_service": "serves",
    "create_client": "calls",
}


def test_the_committed_pages_are_what_the_declarations_render(tmp_path):
    written = reference.write(tmp_path)
    pages = {path.name: path.read_text(encoding="utf-8") for path in written}
    assert set(pages) == {f"{n}.md" for n in NODES} | {reference.INDEX}
    stale = reference.differences(FOLDER, pages)
    assert stale == [], (
        f"docs/reference is stale ({'; '.join(stale)}): regenerate it with "
        f"`.venv/bin/{COMMAND}` and commit the pages"
    )


def test_a_stale_page_is_found(tmp_path):
    """Not vacuous: a changed, a missing and an extra page are each reported."""
    reference.write(tmp_path)
    (tmp_path / "recorder.md").write_text("# recorder\n", encoding="utf-8")
    (tmp_path / "dashboard.md").unlink()
    (tmp_path / "old_node.md").write_text("# gone\n", encoding="utf-8")
    assert reference.differences(tmp_path) == [
        "dashboard.md: missing",
        "recorder.md: differs",
        "old_node.md: not generated (remove it)",
    ]


def test_every_executable_node_has_a_page():
    scripts = {
        ep.name
        for ep in entry_points(group="console_scripts")
        if ep.value.startswith(("sim_bridge.", "joint_space_control.nodes."))
    }
    assert scripts == set(NODES)
    index = (FOLDER / reference.INDEX).read_text(encoding="utf-8")
    for name in NODES:
        assert f"]({name}.md)" in index


def parameter_names(page: str) -> list[str]:
    """The parameter names in the rows of a page's parameter tables."""
    text = page.split("\n## Parameters\n", 1)[1]
    return re.findall(r"^\| `([^`]+)` \|", text, flags=re.MULTILINE)


@pytest.mark.parametrize("node", list(NODES))
def test_every_declared_parameter_is_on_the_page_once(node):
    ref: NodeReference = NODES[node]
    declared = [spec.name for spec in ref.parameters]
    assert declared and len(set(declared)) == len(declared)
    in_groups = [spec.name for group in ref.groups for spec in group.specs]
    assert sorted(in_groups) == sorted(declared)
    shown = parameter_names((FOLDER / f"{node}.md").read_text(encoding="utf-8"))
    assert sorted(shown) == sorted(declared), set(shown) ^ set(declared)
    for spec in ref.parameters:
        assert reference.parameter_row(spec) in reference.render_node(ref)


def test_the_pages_declare_what_the_nodes_declare():
    """A page's parameters are those its node declares at start (the same tuples)."""
    from joint_space_control.control.configure import CONTROLLERS
    from joint_space_control.nodes import dashboard, recorder, trajectory_generator
    from sim_bridge import node as sim_bridge

    assert NODES["sim_bridge"].parameters == sim_bridge.PARAMETERS
    for exe, kind in CONTROLLERS.items():
        assert NODES[exe].parameters == kind.parameters
    assert NODES["trajectory_generator"].parameters == trajectory_generator.PARAMETERS
    assert NODES["recorder"].parameters == recorder.PARAMETERS
    assert NODES["dashboard"].parameters == dashboard.PARAMETERS


def test_sim_bridge_per_robot_groups_are_what_each_robot_gets():
    groups = {group.title: group for group in NODES["sim_bridge"].groups}
    own = {s.name for title in ("The robot", "Each robot's plant") for s in groups[title].specs}
    assert own == {spec.name.removeprefix("arm.") for spec in prefixed("arm")}


def declared_types() -> list[tuple[str, str]]:
    return sorted({(node, e[2]) for node, ref in NODES.items() for e in ref.interface})


@pytest.mark.parametrize(("node", "msg_type"), declared_types())
def test_every_declared_type_exists(node, msg_type):
    if "/" not in msg_type:
        assert msg_type == "(any)", (node, msg_type)
        return
    package, kind, name = msg_type.split("/")
    assert kind in ("msg", "srv"), msg_type
    assert hasattr(importlib.import_module(f"{package}.{kind}"), name), msg_type


def segment(name: str) -> str:
    """The last path segment of a name: ``~/state`` and ``<node>/state`` give ``state``."""
    return name.rstrip("/").rsplit("/", 1)[-1].removeprefix("~")


def declared(node: str, fixed: bool = False) -> set[tuple[str, str]]:
    """(kind, last segment) of every endpoint a node declares (``fixed``: only those whose
    name is fixed, not found in the graph: no ``<...>`` in it)."""
    ref = NODES[node]
    assert all(e[0] in KINDS for e in ref.interface), ref.interface
    return {
        (e[0], segment(part))
        for e in ref.interface
        for part in e[1].split(", ")
        if not (fixed and "<" in part)
    }


def trailing_text(arg: ast.expr) -> str | None:
    """The literal end of a name argument: ``"~/state"``, ``prefix + "joint_states"``,
    ``f"{node}/config"``; None when it has none."""
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value
    if isinstance(arg, ast.BinOp) and isinstance(arg.op, ast.Add):
        return trailing_text(arg.right)
    if isinstance(arg, ast.JoinedStr) and arg.values:
        return trailing_text(arg.values[-1])
    return None


def created(node: str) -> set[tuple[str, str]]:
    """(kind, last segment) of every endpoint the node's code creates under a literal name."""
    found = set()
    for source in SOURCES[node]:
        tree = ast.parse((ROOT / source).read_text(encoding="utf-8"))
        for call in ast.walk(tree):
            if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)):
                continue
            kind = CREATES.get(call.func.attr)
            if kind is None or len(call.args) < 2:
                continue
            text = trailing_text(call.args[1])
            if text is not None and segment(text):
                found.add((kind, segment(text)))
    return found


@pytest.mark.parametrize("node", list(NODES))
def test_every_endpoint_the_code_creates_is_declared(node):
    made = created(node)
    assert made, f"{node}: no endpoint found in {SOURCES[node]}: parser broken?"
    assert made <= declared(node), made - declared(node)


def string_constants(paths: list[Path]) -> set[str]:
    out = set()
    for path in paths:
        for item in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(item, ast.Constant) and isinstance(item.value, str):
                out.add(item.value)
    return out


@pytest.mark.parametrize("node", list(NODES))
def test_every_declared_endpoint_is_named_in_the_code(node):
    """A declared topic or service with a fixed name is named in the node's code or in the
    ROS layer it uses: a renamed or removed one is caught."""
    constants = string_constants([ROOT / s for s in SOURCES[node]] + SHARED)
    for _kind, last in declared(node, fixed=True):
        pattern = re.compile(rf"(^|[/~]){re.escape(last)}$")
        assert any(pattern.search(c) for c in constants), (node, last)


def test_the_endpoint_walk_sees_literal_concatenated_and_formatted_names():
    code = (
        "n.create_publisher(T, '~/state', 1)\n"
        "n.create_subscription(T, prefix + 'joint_states', f, 1)\n"
        "n.create_subscription(T, f'{node}/config', f, 1)\n"
        "n.create_service(T, NAME, f)\n"
    )
    names = [
        trailing_text(c.args[1]) for c in ast.walk(ast.parse(code)) if isinstance(c, ast.Call)
    ]
    assert [segment(n) for n in names if n is not None] == ["state", "joint_states", "config"]
