"""The parameters as declared by the nodes (their ParamSpec lists, the one place each is
declared) agree with the tables of docs/parameters.md and with the parameter files in
config/: every parameter is documented, under its node, with its default and its
read-only mark, and every key of a parameter file is a parameter of that node."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from joint_space_control.control.configure import COMMON_PARAMETERS, INVERSE_DYNAMICS, PD_GRAVITY
from joint_space_control.nodes.recorder import PARAMETERS as RECORDER
from joint_space_control.nodes.trajectory_generator import PARAMETERS as GENERATOR
from joint_space_control.ros.parameters import ROBOT_PARAMETERS, ParamSpec
from sim_bridge.node import PARAMETERS as SIM_BRIDGE
from sim_bridge.parameters import prefixed

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "parameters.md"
CONFIG = ROOT / "joint_space_control" / "config"

NODES: dict[str, tuple[ParamSpec, ...]] = {
    "sim_bridge": SIM_BRIDGE,
    "pd_gravity_controller": PD_GRAVITY.parameters,
    "inverse_dynamics_controller": INVERSE_DYNAMICS.parameters,
    "trajectory_generator": GENERATOR,
    "recorder": RECORDER,
}
#: Parameters the docs describe once for several nodes: the robot ones ("every node") and
#: the controllers' common ones (under pd_gravity_controller, "same common parameters").
SHARED = {"every node": ROBOT_PARAMETERS, "pd_gravity_controller": COMMON_PARAMETERS}


#: Pages holding one node's table, besides docs/parameters.md (sections by bold node names).
PAGES = {"references.md": "trajectory_generator", "recording.md": "recorder"}


def documented_rows() -> dict[str, dict[str, tuple[str, bool]]]:
    """{section: {parameter: (default text, read-only)}} from the parameter tables of the
    docs; a section is a node name (or "every node")."""
    sections: dict[str, dict[str, tuple[str, bool]]] = {}
    for page in ["parameters.md", *PAGES]:
        section = PAGES.get(page)
        all_ro = False
        for line in (DOC.parent / page).read_text().splitlines():
            bold = re.match(r"\*\*(\w+)\*\*", line)
            if bold and page == "parameters.md":
                section, all_ro = bold.group(1), False
            if line.startswith("| parameter"):
                if "every node" in line:
                    section = "every node"
                all_ro = "RO" in line
                continue
            if not line.startswith("| `") or section is None:
                continue
            cells = [c.strip() for c in line.strip("|").split("|")]
            names = re.findall(r"`([a-z_]+)`", cells[0])
            ro = "(RO)" in cells[0] or all_ro
            defaults = [d.strip() for d in cells[1].split(",")] if len(names) > 1 else [cells[1]]
            for name, default in zip(names, defaults, strict=False):
                sections.setdefault(section, {})[name] = (default, ro)
    return sections


def same_default(text: str, value: object) -> bool:
    """The documented default is the declared one (an empty declared default may be
    documented by what it means, e.g. the recorder's generated bag name)."""
    text = text.strip().strip("`")
    if isinstance(value, bool):
        return text == str(value).lower()
    if isinstance(value, int | float):
        try:
            return float(text) == float(value)
        except ValueError:
            return False
    if value in ("", []):
        return bool(text)
    if isinstance(value, list):  # a vector, documented as [0, 0, 0]
        try:
            return [float(v) for v in yaml.safe_load(text)] == [float(v) for v in value]
        except (TypeError, ValueError, yaml.YAMLError):
            return False
    return text == value


#: Where the controllers' shared parameters are documented: under either controller.
CONTROLLERS = ("pd_gravity_controller", "inverse_dynamics_controller")


def sections_of(node: str, name: str) -> tuple[str, ...]:
    if name in {s.name for s in ROBOT_PARAMETERS}:
        return ("every node",)
    if node in CONTROLLERS and name in {s.name for s in COMMON_PARAMETERS}:
        return CONTROLLERS
    return (node,)


@pytest.mark.parametrize("node", list(NODES))
def test_every_parameter_is_documented_with_its_default_and_read_only_mark(node):
    rows = documented_rows()
    for spec in NODES[node]:
        sections = sections_of(node, spec.name)
        found = [rows[s][spec.name] for s in sections if spec.name in rows.get(s, {})]
        assert found, f"{node}: '{spec.name}' not documented under {sections}"
        default, ro = found[0]
        assert same_default(default, spec.default), (node, spec.name, default, spec.default)
        assert ro == spec.read_only, (node, spec.name, "RO mark", ro, spec.read_only)


def test_the_docs_list_no_parameter_that_does_not_exist():
    declared = {s.name for specs in NODES.values() for s in specs}
    for section, rows in documented_rows().items():
        assert set(rows) <= declared, (section, set(rows) - declared)


@pytest.mark.parametrize("path", sorted(CONFIG.glob("*.yaml")), ids=lambda p: p.name)
def test_parameter_files_set_only_declared_parameters(path):
    node = WORLDS.get(path.name) or next(
        n for n in sorted(NODES, key=len, reverse=True) if path.stem.startswith(n)
    )
    for entry in yaml.safe_load(path.read_text()).values():
        values = entry["ros__parameters"]
        robots = values.get("robots", []) if node == "sim_bridge" else []
        declared = {s.name for s in NODES[node]} | {"use_sim_time"}
        declared |= {s.name for name in robots for s in prefixed(name)}
        keys = set(flat(values))
        assert keys <= declared, (path.name, keys - declared)
        assert set(robots) <= set(values), (path.name, "a robot without its parameters")


#: Parameter files of a node their name does not start with.
WORLDS = {"two_robots.yaml": "sim_bridge"}


def flat(values: dict, prefix: str = "") -> dict:
    """A params file's nested mappings as ROS names them: ``a: {b: 1}`` is ``a.b``."""
    out = {}
    for key, value in values.items():
        if isinstance(value, dict):
            out |= flat(value, f"{prefix}{key}.")
        else:
            out[prefix + key] = value
    return out


def test_the_checker_sees_a_wrong_default():
    """Not vacuous: a default that differs from the schema is caught."""
    rows = documented_rows()
    default, _ = rows["sim_bridge"]["command_timeout"]
    assert same_default(default, 0.1) and not same_default(default, 0.2)
    assert set(rows) >= {"every node", *NODES}  # every node's table was found


@pytest.mark.parametrize("node", list(NODES))
def test_every_default_satisfies_its_own_declaration(node):
    for spec in NODES[node]:
        if spec.type in ("numbers", "names") and not spec.default:
            continue  # empty: "not given" (the URDF's limits, every topic, ...)
        spec.check(spec.default, 3)


@pytest.mark.parametrize("node", list(NODES))
def test_a_value_outside_the_declared_range_is_refused_with_its_name(node):
    """The range is enforced where it is declared: below the minimum (or at it, when
    exclusive) and non-finite values are refused, one value or per joint."""
    checked = 0
    for spec in NODES[node]:
        if spec.minimum is None:
            continue
        bad = spec.minimum if spec.exclusive else spec.minimum - 1.0
        for value in (bad, float("nan"), [1.0, bad, 1.0] if spec.type == "numbers" else bad):
            with pytest.raises(ValueError, match=f"'{spec.name}'"):
                spec.check(value, 3 if spec.type == "numbers" else None)
        checked += 1
    assert checked > 0  # every node declares ranged parameters


def test_constraints_are_generated_from_the_declaration():
    spec = NODES["sim_bridge"][[s.name for s in SIM_BRIDGE].index("max_torque_rate")]
    assert spec.constraints == ">= 0, <= 1e+07, one value or one per joint, [N·m/s]"
    rate = next(s for s in COMMON_PARAMETERS if s.name == "rate")
    assert rate.constraints == "> 0, <= 100000, [Hz]"
    trigger = next(s for s in COMMON_PARAMETERS if s.name == "trigger")
    assert trigger.constraints == "one of: auto | timer | state"


def documented_ranges() -> dict[str, list[str]]:
    """{parameter: [the meaning cell of each row naming it]} over the parameter tables."""
    rows: dict[str, list[str]] = {}
    for page in ["parameters.md", *PAGES]:
        for line in (DOC.parent / page).read_text().splitlines():
            if line.startswith("| `"):
                cells = [c.strip() for c in line.strip("|").split("|")]
                for name in re.findall(r"`([a-z_]+)`", cells[0]):
                    rows.setdefault(name, []).append(cells[-1])
    return rows


def test_every_declared_range_is_documented_as_the_descriptor_says_it():
    """A parameter with both ends is documented with its range (``range `>= 0, <= 10```,
    the descriptor's constraints text) in every row that names it; no row states another."""
    rows = documented_ranges()
    ranged = {s.name: s for specs in NODES.values() for s in specs if s.ranged}
    assert len(ranged) > 30
    for name, spec in ranged.items():
        assert rows.get(name), name
        for meaning in rows[name]:
            stated = re.findall(r"range `([^`]*)`", meaning)
            assert spec.bound in stated, (name, spec.bound, stated)
    for name, meanings in rows.items():
        for meaning in meanings:
            for stated in re.findall(r"range `([^`]*)`", meaning):
                assert name in ranged and stated == ranged[name].bound, (name, stated)
