"""Built-in robots and URDF facts shared by the controller model and the simulator.

A robot is resolved from the ``robot`` parameter (a built-in name), from ``urdf_path`` (any
URDF or xacro file) or from ``robot_description`` (URDF text); see
:mod:`~joint_space_control.model.description` for what is accepted. The same file
feeds Pinocchio (controller model) and PyBullet (plant), so the two only differ where a
user asks them to (friction, payload, mass scale).
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from joint_space_control.model.description import (
    DescriptionError,
    floating_base_hint,
    materialize,
    parse_urdf,
    parse_xacro_args,
    read_description,
    resolve_meshes,
)
from joint_space_control.paths import data_dir

#: Joint types that carry one actuated degree of freedom.
ACTUATED_JOINT_TYPES = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class RobotSpec:
    """Where a robot's URDF lives and which joints are controlled by default.

    ``urdf_path`` is the file both Pinocchio and PyBullet load (for a description that had
    to be expanded or resolved, the resolved copy: :mod:`~joint_space_control.model.description`);
    ``warnings`` are what loading it found worth saying (meshes not found, say)."""

    name: str
    urdf_path: Path
    default_joints: tuple[str, ...]
    warnings: tuple[str, ...] = field(default=(), compare=False)


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


def example_robot_data_share() -> Path | None:
    """The folder ``example-robot-data`` (PyPI) installs its robots under, None when it is
    not installed: ``<site-packages>/cmeel.prefix/share``, holding
    ``example-robot-data/robots/...``. Its descriptions' meshes are
    ``package://example-robot-data/...`` URIs, so this folder is their ``package_paths``."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    share = Path(str(dist.locate_file("cmeel.prefix/share")))
    return share if (share / "example-robot-data" / "robots").is_dir() else None


#: The arms of ``example-robot-data`` by a short name: their description in its robots folder.
EXAMPLE_ROBOTS = {
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "kinova": "kinova_description/robots/kinova.urdf",
    "z1": "z1_description/urdf/z1.urdf",
    "so100": "so_arm_description/urdf/so100.urdf",
    "so101": "so_arm_description/urdf/so101.urdf",
}


def example_robot(name: str) -> dict[str, Any]:
    """The robot parameters (``urdf_path``, ``package_paths``) that load the arm ``name`` of
    :data:`EXAMPLE_ROBOTS` from ``example-robot-data`` (ValueError when the name is unknown
    or the package is not installed: ``pip install example-robot-data``)."""
    if name not in EXAMPLE_ROBOTS:
        raise ValueError(f"unknown example robot {name!r}; known: {', '.join(EXAMPLE_ROBOTS)}")
    share = example_robot_data_share()
    if share is None:
        raise ValueError("example-robot-data is not installed (pip install example-robot-data)")
    path = share / "example-robot-data" / "robots" / EXAMPLE_ROBOTS[name]
    return {"urdf_path": str(path), "package_paths": [str(share)]}


def resolve_robot(
    robot: str = "",
    urdf_path: str = "",
    *,
    robot_description: str = "",
    xacro_args: str | Sequence[str] = "",
    package_paths: Sequence[str] = (),
) -> RobotSpec:
    """Resolve a built-in robot name, a URDF/xacro file or URDF text (exactly one) to a spec.

    Raises :class:`~joint_space_control.model.description.DescriptionError` (a
    ``ValueError``) with a one-line reason: unknown name, missing or malformed file,
    floating base, no movable joint, more than one source given.
    """
    given = [n for n, v in (("robot", robot), ("urdf_path", urdf_path)) if v]
    given += ["robot_description"] if robot_description else []
    if len(given) > 1:
        raise DescriptionError(f"give either {' or '.join(map(repr, given))}, not both")
    if robot_description:
        return _load(robot_description, "robot_description", None, package_paths)
    if urdf_path:
        path = Path(urdf_path).expanduser().resolve()
        text = read_description(path, parse_xacro_args(xacro_args))
        spec = _load(text, str(path), path, package_paths)
        return replace(spec, name=path.name.split(".")[0])
    robots = builtin_robots()
    if robot not in robots:
        raise DescriptionError(f"unknown robot '{robot}'; built-in robots: {', '.join(robots)}")
    return robots[robot]


def _load(text: str, source: str, path: Path | None, package_paths: Sequence[str]) -> RobotSpec:
    """Parse and check the text, resolve its meshes, and give the file to load."""
    robot = parse_urdf(text, source)
    base_dir = path.parent if path is not None else None
    resolved, missing, changed = resolve_meshes(text, base_dir, package_paths)
    warnings = []
    if missing:
        unique = sorted(set(missing))
        shown = ", ".join(unique[:5]) + (f", +{len(unique) - 5} more" if len(unique) > 5 else "")
        warnings.append(
            f"{len(unique)} mesh file(s) not found ({shown}); "
            "their visual/collision shapes are left out (the dynamics do not use them): set "
            "'package_paths' or ROS_PACKAGE_PATH to the folder holding their package"
        )
    if hint := floating_base_hint(robot):
        warnings.append(hint)
    if path is None or changed or path.suffix == ".xacro":
        path = materialize(resolved)
    return RobotSpec(robot.name or "robot", path, _actuated(robot.joints), tuple(warnings))


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


@lru_cache(maxsize=16)
def urdf_facts(urdf_path: Path) -> UrdfFacts:
    """Joints (in file order, kinematic joints only) and link inertials of a URDF file, as
    the URDF parser reads them."""
    path = Path(urdf_path)
    robot = parse_urdf(read_description(path), str(path))
    joints = tuple(
        UrdfJoint(j.name, j.type, j.parent, j.child, j.mimic is not None) for j in robot.joints
    )
    inertials = {}
    for link in robot.links:
        node = link.inertial
        if node is None:
            continue
        origin = np.eye(4) if node.origin is None else np.asarray(node.origin, dtype=float)
        tensor = np.zeros((3, 3)) if node.inertia is None else np.asarray(node.inertia, float)
        rot = origin[:3, :3]
        mass = float(node.mass) if node.mass is not None else 0.0
        inertials[link.name] = UrdfInertial(mass, origin[:3, 3].copy(), rot @ tensor @ rot.T)
    return UrdfFacts(joints, inertials)


def _actuated(joints: Iterable[Any]) -> tuple[str, ...]:
    return tuple(
        j.name for j in joints if j.type in ACTUATED_JOINT_TYPES and j.mimic in (None, False)
    )


def actuated_joints(urdf_path: Path) -> tuple[str, ...]:
    """All one-DoF, non-mimic joints of a URDF, in file order."""
    return _actuated(urdf_facts(Path(urdf_path)).joints)


def inertia_is_physical(inertia: np.ndarray, tol: float = 1e-12) -> bool:
    """True when a 3×3 inertia tensor is symmetric positive semi-definite and its principal
    moments satisfy the triangle inequality (the test PyBullet applies before it silently
    replaces a link's inertia)."""
    moments = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    if np.any(moments < -tol):
        return False
    a, b, c = moments
    return a + b >= c - tol and a + c >= b - tol and b + c >= a - tol
