"""The parameters as the nodes declare them (their ParamSpec lists, the one place each is
declared) agree with what the documentation says and with the parameter files in config/:

- the node reference (docs/reference/<node>.md, generated: test_node_reference.py checks the
  pages are what the declarations render) lists every parameter of its node, and no other,
  with its declared default, read-only mark and range or choices;
- every hand-written parameter table of the docs (the guide docs/parameters.md,
  references.md, recording.md) names only declared parameters, with their declared default,
  read-only mark and range;
- every key of a parameter file is a parameter of that node, and every file is some node's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from joint_space_control.control.configure import COMMON_PARAMETERS, INVERSE_DYNAMICS, PD_GRAVITY
from joint_space_control.nodes.dashboard import PARAMETERS as DASHBOARD
from joint_space_control.nodes.recorder import PARAMETERS as RECORDER
from joint_space_control.nodes.reference import parameter_files
from joint_space_control.nodes.trajectory_generator import PARAMETERS as GENERATOR
from joint_space_control.ros.parameters import ParamSpec
from sim_bridge.node import PARAMETERS as SIM_BRIDGE
from sim_bridge.parameters import prefixed

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
REFERENCE = DOCS / "reference"
CONFIG = ROOT / "joint_space_control" / "config"

NODES: dict[str, tuple[ParamSpec, ...]] = {
    "sim_bridge": SIM_BRIDGE,
    "pd_gravity_controller": PD_GRAVITY.parameters,
    "inverse_dynamics_controller": INVERSE_DYNAMICS.parameters,
    "trajectory_generator": GENERATOR,
    "recorder": RECORDER,
    "dashboard": DASHBOARD,
}
#: Every declared parameter by name (a name means the same on every node that has it).
DECLARED: dict[str, ParamSpec] = {s.name: s for specs in NODES.values() for s in specs}

#: Pages with hand-written parameter tables (``| parameter ... |`` headers).
HAND_WRITTEN = ("parameters.md", "references.md", "recording.md")


@dataclass(frozen=True)
class Row:
    page: str
    name: str
    default: str
    read_only: bool
    range: str  # the reference's range cell; a hand table's meaning cell


def cells(line: str) -> list[str]:
    """The cells of a table row; an escaped pipe (``\\|``) stays inside its cell."""
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]


def reference_rows() -> dict[str, dict[str, Row]]:
    """{node: {parameter: row}} from the parameter tables of the node reference, whose
    columns are parameter | type | default | range | unit | set | description."""
    out: dict[str, dict[str, Row]] = {}
    for node in NODES:
        page = REFERENCE / f"{node}.md"
        rows = out[node] = {}
        if not page.exists():
            continue
        in_parameters = False
        for line in page.read_text(encoding="utf-8").splitlines():
            if line.startswith("## "):
                in_parameters = line == "## Parameters"
            if in_parameters and line.startswith("| `"):
                c = cells(line)
                name = c[0].strip("`")
                rows[name] = Row(page.name, name, c[2], c[5] == "start (RO)", c[3])
    return out


def hand_written_rows() -> list[Row]:
    """Every row of a hand-written parameter table: one per parameter it names."""
    rows = []
    for page in HAND_WRITTEN:
        all_ro = False
        for line in (DOCS / page).read_text(encoding="utf-8").splitlines():
            if line.startswith("| parameter"):
                all_ro = "RO" in line
                continue
            if not line.startswith("| `"):
                continue
            c = cells(line)
            names = re.findall(r"`([a-z_]+)`", c[0])
            ro = "(RO)" in c[0] or all_ro
            defaults = [d.strip() for d in c[1].split(",")] if len(names) > 1 else [c[1]]
            for name, default in zip(names, defaults, strict=False):
                rows.append(Row(page, name, default, ro, c[-1]))
    return rows


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


@pytest.mark.parametrize("node", list(NODES))
def test_the_reference_lists_every_parameter_with_its_default_mark_and_range(node):
    rows = reference_rows()[node]
    assert rows, f"no parameter table in docs/reference/{node}.md"
    assert set(rows) == {spec.name for spec in NODES[node]}, node
    for spec in NODES[node]:
        row = rows[spec.name]
        assert same_default(row.default, spec.default), (node, spec.name, row.default)
        assert row.read_only == spec.read_only, (node, spec.name, "RO mark")
        if spec.choices:
            assert re.findall(r"`([^`]*)`", row.range) == list(spec.choices), (node, spec.name)
        else:
            assert row.range == (f"`{spec.bound}`" if spec.bound else ""), (node, spec.name)


def test_hand_written_tables_agree_with_the_declarations():
    rows = hand_written_rows()
    assert len(rows) >= 10, "the hand-written tables were not found: parser broken?"
    for row in rows:
        assert row.name in DECLARED, f"{row.page}: '{row.name}' is no parameter of any node"
        spec = DECLARED[row.name]
        assert same_default(row.default, spec.default), (row.page, row.name, row.default)
        assert row.read_only == spec.read_only, (row.page, row.name, "RO mark")


def test_every_range_a_hand_written_table_states_is_the_declared_one():
    """A hand-written row of a parameter with both ends states its range (``range `>= 0,
    <= 10```, the descriptor's constraints text); no row states another."""
    checked = 0
    for row in hand_written_rows():
        spec = DECLARED[row.name]
        stated = re.findall(r"range `([^`]*)`", row.range)
        if spec.ranged:
            assert spec.bound in stated, (row.page, row.name, spec.bound, stated)
            checked += 1
        assert all(s == spec.bound for s in stated), (row.page, row.name, stated)
    assert checked >= 5


@pytest.mark.parametrize("node", list(NODES))
def test_parameter_files_set_only_declared_parameters(node):
    for name in parameter_files(node):
        for entry in yaml.safe_load((CONFIG / name).read_text()).values():
            values = entry["ros__parameters"]
            robots = values.get("robots", []) if node == "sim_bridge" else []
            declared = {s.name for s in NODES[node]} | {"use_sim_time"}
            declared |= {s.name for robot in robots for s in prefixed(robot)}
            keys = set(flat(values))
            assert keys <= declared, (name, keys - declared)
            assert set(robots) <= set(values), (name, "a robot without its parameters")


def test_every_parameter_file_belongs_to_a_node():
    claimed = {name for node in NODES for name in parameter_files(node)}
    assert {p.name for p in CONFIG.glob("*.yaml")} == claimed
    assert "two_robots.yaml" in parameter_files("sim_bridge")


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
    row = reference_rows()["sim_bridge"]["command_timeout"]
    assert same_default(row.default, 0.1) and not same_default(row.default, 0.2)
    model = next(r for r in hand_written_rows() if r.name == "model_payload_mass")
    assert same_default(model.default, 0.0) and not same_default(model.default, 1.0)


def test_the_table_parser_keeps_escaped_pipes_in_their_cell():
    assert cells("| `a` | `x` \\| `y` | z |") == ["`a`", "`x` | `y`", "z"]


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
