"""Built-in robots and URDF facts shared by the controller model and the simulator.

A robot is resolved from the ``robot`` parameter (a built-in name) or from ``urdf_path``
(any URDF). The same file feeds Pinocchio (controller model) and PyBullet (plant), so the
two only differ where a user asks them to (friction, payload, mass scale).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from joint_space_control.paths import data_dir

#: Joint types that carry one actuated degree of freedom.
ACTUATED_JOINT_TYPES = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class RobotSpec:
    """Where a robot's URDF lives and which joints are controlled by default."""

    name: str
    urdf_path: Path
    default_joints: tuple[str, ...]


def _pybullet_data(relative: str) -> Path:
    import pybullet_data  # data-only package shipped with pybullet; does not start PyBullet

    return Path(pybullet_data.getDataPath()) / relative


def _packaged_urdf(file_name: str) -> Path:
    """A URDF shipped as package data (found through importlib.resources, see paths.py)."""
    return data_dir() / "robots" / "urdf" / file_name


def builtin_robots() -> dict[str, RobotSpec]:
    """The robots selectable with the ``robot`` parameter (shared INTERFACES.md)."""
    return {
        "planar_2dof": RobotSpec(
            "planar_2dof", _packaged_urdf("planar_2dof.urdf"), ("joint1", "joint2")
        ),
        "iiwa": RobotSpec(
            "iiwa",
            _pybullet_data("kuka_iiwa/model.urdf"),
            tuple(f"lbr_iiwa_joint_{i}" for i in range(1, 8)),
        ),
        "panda": RobotSpec(
            "panda",
            _pybullet_data("franka_panda/panda.urdf"),
            tuple(f"panda_joint{i}" for i in range(1, 8)),
        ),
    }


def resolve_robot(robot: str = "", urdf_path: str = "") -> RobotSpec:
    """Resolve a built-in robot name or a URDF path (exactly one of them) to a spec.

    Raises ``ValueError`` with a reason for an unknown name, a missing file or both given.
    """
    if robot and urdf_path:
        raise ValueError("give either 'robot' or 'urdf_path', not both")
    if urdf_path:
        path = Path(urdf_path).expanduser()
        if not path.is_file():
            raise ValueError(f"urdf_path '{urdf_path}' is not a file")
        return RobotSpec(path.stem, path.resolve(), actuated_joints(path))
    robots = builtin_robots()
    if robot not in robots:
        raise ValueError(f"unknown robot '{robot}'; built-in robots: {', '.join(robots)}")
    return robots[robot]


@dataclass(frozen=True)
class UrdfJoint:
    name: str
    type: str
    parent: str
    child: str
    mimic: bool


@dataclass(frozen=True)
class UrdfInertial:
    """A link's ``<inertial>``: mass [kg], centre of mass [m] and inertia at the COM [kg m²]
    expressed in the link frame."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


@dataclass(frozen=True)
class UrdfFacts:
    joints: tuple[UrdfJoint, ...]
    inertials: dict[str, UrdfInertial]


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _floats(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


@lru_cache(maxsize=16)
def urdf_facts(urdf_path: Path) -> UrdfFacts:
    """Joints (in file order) and link inertials read straight from the URDF XML."""
    root = ET.parse(urdf_path).getroot()
    joints = tuple(
        UrdfJoint(
            name=j.get("name"),
            type=j.get("type"),
            parent=j.find("parent").get("link"),
            child=j.find("child").get("link"),
            mimic=j.find("mimic") is not None,
        )
        for j in root.iter("joint")
    )
    inertials = {}
    for link in root.iter("link"):
        node = link.find("inertial")
        if node is None:
            continue
        origin = node.find("origin")
        xyz = _floats(origin.get("xyz") if origin is not None else None, "0 0 0")
        rpy = _floats(origin.get("rpy") if origin is not None else None, "0 0 0")
        mass_node, i = node.find("mass"), node.find("inertia")
        mass = float(mass_node.get("value")) if mass_node is not None else 0.0
        attrs = i.attrib if i is not None else {}

        def get(key: str, attrs: dict = attrs) -> float:
            return float(attrs.get(key, 0.0))

        tensor = np.array(
            [
                [get("ixx"), get("ixy"), get("ixz")],
                [get("ixy"), get("iyy"), get("iyz")],
                [get("ixz"), get("iyz"), get("izz")],
            ]
        )
        rot = _rpy_matrix(rpy)
        inertials[link.get("name")] = UrdfInertial(mass, xyz, rot @ tensor @ rot.T)
    return UrdfFacts(joints, inertials)


def actuated_joints(urdf_path: Path) -> tuple[str, ...]:
    """All one-DoF, non-mimic joints of a URDF, in file order."""
    return tuple(
        j.name
        for j in urdf_facts(Path(urdf_path)).joints
        if j.type in ACTUATED_JOINT_TYPES and not j.mimic
    )


def inertia_is_physical(inertia: np.ndarray, tol: float = 1e-12) -> bool:
    """True when a 3×3 inertia tensor is symmetric positive semi-definite and its principal
    moments satisfy the triangle inequality (the test PyBullet applies before it silently
    replaces a link's inertia)."""
    moments = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    if np.any(moments < -tol):
        return False
    a, b, c = moments
    return a + b >= c - tol and a + c >= b - tol and b + c >= a - tol
