"""No module imports from a layer above its own.

The package is built in layers so that the maths can be used, tested and read without ROS,
the ROS layer without the tools built on it, and the product without its workbench and its
lab. The modules are parsed, not imported: every
``import`` statement counts, including the ones inside functions (deferred imports are still
dependencies).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("joint_space_control", "sim_bridge")

#: sim_bridge's plant: the engines and what a robot's plant does on them, with no ROS (the
#: node around them is in sim_bridge's other modules).
PLANT = (
    "sim_bridge.torque_plant",
    "sim_bridge.plant",
    "sim_bridge.mujoco_plant",
    "sim_bridge.engines",
    "sim_bridge.robot_plant",
    "sim_bridge.sensors",
    "sim_bridge.wrench",
    "sim_bridge.parameters",
    "sim_bridge.view",
)

# Low → high. A module may import from its own layer and the layers below it. The layers
# form three parts, each depending only on those before it: the product (what a user runs),
# the workbench (what a student explores with), the lab (what a maintainer proves it with).
# The product:
# - arrays, paths, json_values, enums, machine, memory, scheduling, throttle, time_jumps,
#   staleness: no knowledge of robots, control or ROS;
# - model, laws, trajectories: the maths of the robot and the control laws;
# - control: the controllers themselves (configuration, state, step) and the policy a node
#   drives them by, no ROS;
# - the plant (PLANT): sim_bridge's engines and robot plants, no ROS;
# - analysis, recording: bags and metrics (rosbags, matplotlib; no running ROS graph);
# - simulation: the closed loop in one process (plant + policy), simulate() -> Response;
# - ros: the ROS 2 layer the nodes share (parameters, messages, control path, diagnostics);
# - nodes, dashboard, sim_bridge: the ROS 2 nodes (sim_bridge is a node of its own top-level
#   package; dashboard holds the web page the dashboard node serves);
# - processes: the nodes as processes in a leased ROS domain, the lockstep loop over them,
#   make demo;
# The workbench: experiments (jsc experiment: scenarios, execution on either engine, judging,
# presentation), tuning (jsc tune).
# The lab: bench (jsc bench), soaks (jsc soak), discretisation.
# - cli: argument parsing over all three (a workbench or lab verb imports its part only
#   when it runs).
PRODUCT: tuple[tuple[str, ...], ...] = (
    (
        "joint_space_control.arrays",
        "joint_space_control.paths",
        "joint_space_control.json_values",
        "joint_space_control.enums",
        "joint_space_control.machine",
        "joint_space_control.memory",
        "joint_space_control.scheduling",
        "joint_space_control.throttle",
        "joint_space_control.time_jumps",
        "joint_space_control.staleness",
    ),
    (
        "joint_space_control.model",
        "joint_space_control.laws",
        "joint_space_control.trajectories",
        "joint_space_control.robots",
    ),
    ("joint_space_control.control",),
    PLANT,
    ("joint_space_control.analysis", "joint_space_control.recording"),
    ("joint_space_control.simulation",),
    ("joint_space_control.ros",),
    ("joint_space_control.nodes", "joint_space_control.dashboard", "sim_bridge"),
    ("joint_space_control.processes",),
)
WORKBENCH = (("joint_space_control.workbench",),)
LAB = (("joint_space_control.lab",),)
LAYERS: tuple[tuple[str, ...], ...] = (
    *PRODUCT,
    *WORKBENCH,
    *LAB,
    ("joint_space_control.cli",),
)


def layer_of(module: str) -> int | None:
    """Index in :data:`LAYERS` of ``module`` (a dotted name), None outside the packages."""
    for level, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if module == prefix or module.startswith(prefix + "."):
                return level
    return None


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(tree: ast.AST, module: str, is_package: bool) -> list[tuple[int, str]]:
    """(line, dotted name) of every module ``tree`` imports, relative imports resolved;
    ``from package import name`` counts as importing ``package.name``."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".")
                anchor = anchor[: len(anchor) - node.level + (1 if is_package else 0)]
                base = ".".join(anchor + ([base] if base else []))
            found += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return found


def sources() -> list[Path]:
    return sorted(p for package in PACKAGES for p in (ROOT / package).rglob("*.py"))


def test_every_module_has_a_layer():
    missing = [module_name(p) for p in sources() if layer_of(module_name(p)) is None]
    # the package roots themselves hold nothing
    assert [m for m in missing if m not in PACKAGES] == []


@pytest.mark.parametrize("path", sources(), ids=lambda p: module_name(p))
def test_no_import_from_a_layer_above(path: Path):
    module = module_name(path)
    own = layer_of(module)
    if own is None:
        return
    tree = ast.parse(path.read_text(), str(path))
    upward = []
    for line, name in imported_modules(tree, module, path.name == "__init__.py"):
        level = layer_of(name)
        if level is not None and level > own:
            upward.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert upward == []


def test_layer_walk_sees_deferred_and_relative_imports():
    """The walk itself: an import inside a function and a relative import are both found."""
    code = (
        "def f():\n    from joint_space_control.cli import analyze\nfrom ..lab.bench import run\n"
    )
    found = imported_modules(ast.parse(code), "joint_space_control.analysis.x", False)
    assert sorted((name, layer_of(name)) for _, name in found) == [
        ("joint_space_control.cli.analyze", LAYERS.index(("joint_space_control.cli",))),
        ("joint_space_control.lab.bench.run", LAYERS.index(("joint_space_control.lab",))),
    ]


def test_the_loop_imports_no_ros():
    """The closed loop and what it is built on import no ROS package, at any depth: the
    simulation runs where rclpy is not installed."""
    below_ros = LAYERS.index(("joint_space_control.ros",))
    ros = (
        "rclpy",
        "rcl_interfaces",
        "sensor_msgs",
        "std_msgs",
        "trajectory_msgs",
        "rosgraph_msgs",
    )
    found = []
    for path in sources():
        module = module_name(path)
        level = layer_of(module)
        if level is None or level >= below_ros:
            continue
        tree = ast.parse(path.read_text(), str(path))
        for line, name in imported_modules(tree, module, path.name == "__init__.py"):
            if name.split(".")[0] in ros:
                found.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert found == []
    assert any(module_name(p).startswith("joint_space_control.simulation") for p in sources())


def test_the_product_needs_neither_the_workbench_nor_the_lab():
    """lab → workbench → product, never back: what a user runs imports nothing of the
    workbench or the lab, and the workbench nothing of the lab (the folder names say which
    part a module belongs to)."""
    parts = {"workbench": len(PRODUCT), "lab": len(PRODUCT) + len(WORKBENCH)}
    backwards = []
    for path in sources():
        module = module_name(path)
        level = layer_of(module)
        if level is None or level >= parts["lab"] + len(LAB):  # the cli dispatches to all
            continue
        tree = ast.parse(path.read_text(), str(path))
        for line, name in imported_modules(tree, module, path.name == "__init__.py"):
            target = layer_of(name)
            if target is None:
                continue
            for part, first in parts.items():
                if level < first <= target:
                    backwards.append(f"{path.relative_to(ROOT)}:{line} imports the {part}: {name}")
    assert backwards == []
    assert layer_of("joint_space_control.workbench.tuning.study") == parts["workbench"]
    assert layer_of("joint_space_control.lab.bench.run") == parts["lab"]
