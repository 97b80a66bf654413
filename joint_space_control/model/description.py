"""Robot descriptions as robot packages ship them, turned into one URDF file that Pinocchio
(the controller model) and PyBullet (the plant) both read.

A description comes as URDF text (the ``robot_description`` parameter or topic), as a
``.urdf`` file or as a ``.xacro`` file (expanded with the ``xacro`` package, with
``xacro_args``). Whatever its source:

- it is parsed with a maintained URDF parser (yourdfpy); blocks that are not kinematics
  (``<transmission>``, ``<gazebo>``, ``<ros2_control>``, …) are left to the parser, so their
  ``<joint>`` children are never taken for joints;
- mesh URIs ``package://PKG/…`` are resolved through the ament index, then
  ``ROS_PACKAGE_PATH``, then the ``package_paths`` given; ``file://`` URIs and relative paths
  (against the description's own folder) likewise. A mesh that cannot be found is named in a
  warning and its ``<visual>``/``<collision>`` is left out: the dynamics come from the
  ``<inertial>`` blocks and do not need it;
- descriptions with a floating or planar joint are refused: this package controls
  fixed-base arms, and a floating base cannot be fixed without changing the robot. A
  description without such a joint is fixed to the world at its root link, which is how
  URDF describes a fixed-base arm;
- malformed text, a missing file, a description with no movable joint: a
  :class:`DescriptionError` (a ``ValueError``) with one line saying which and where.

When nothing had to be rewritten the original file is used as it is; otherwise the
resolved text is written once to a file named by its content hash in the temporary folder.
"""

from __future__ import annotations

import hashlib
import io
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from urllib.parse import unquote, urlparse

#: Joint types that make the base mobile: refused (module docstring).
FLOATING_JOINT_TYPES = ("floating", "planar")
#: Names of the links a legged robot stands on: a description with several kinematic chains
#: ending in one of these looks like a floating-base robot.
FOOT_WORDS = ("foot", "feet", "toe", "sole")


class DescriptionError(ValueError):
    """A robot description that cannot be used, with the reason in one line."""


def parse_xacro_args(text: str | Sequence[str]) -> dict[str, str]:
    """``"name:=value other:=2"`` (or a list of such items) → {name: value}."""
    items = text.split() if isinstance(text, str) else list(text)
    args = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise DescriptionError(f"xacro_args item '{item}' is not of the form name:=value")
        args[name] = value
    return args


def read_description(path: Path, xacro_args: Mapping[str, str] | None = None) -> str:
    """The URDF text of a ``.urdf`` file, or of a ``.xacro`` file expanded with xacro."""
    if not path.is_file():
        raise DescriptionError(f"robot description file '{path}' is not a file")
    if path.suffix != ".xacro":
        try:
            return path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise DescriptionError(f"cannot read '{path}': {err}") from None
    import xacro  # only for .xacro files: it is a light import, but not needed otherwise

    try:
        doc = xacro.process_file(str(path), mappings=dict(xacro_args or {}))
    except Exception as err:  # xacro raises its own and XML errors, all one line here
        raise DescriptionError(f"xacro failed on '{path}': {_one_line(err)}") from None
    return doc.toxml()


def parse_urdf(text: str, source: str):
    """The description parsed by yourdfpy (``yourdfpy.Robot``); DescriptionError if it is not
    a URDF, has a floating base or no movable joint."""
    import yourdfpy
    from lxml import etree

    try:  # strict first: the URDF parser's own XML parser recovers from broken text
        etree.fromstring(text.encode("utf-8"))
        robot = yourdfpy.URDF.load(
            io.BytesIO(text.encode("utf-8")),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        ).robot
    except Exception as err:  # lxml syntax errors, missing attributes, …
        raise DescriptionError(
            f"malformed robot description ({source}): {_one_line(err)}"
        ) from None
    if robot is None or not robot.links:
        raise DescriptionError(f"robot description ({source}) has no links")
    floating = [j.name for j in robot.joints if j.type in FLOATING_JOINT_TYPES]
    if floating:
        raise DescriptionError(
            f"robot description ({source}) has a floating base (joint '{floating[0]}' is "
            f"{next(j.type for j in robot.joints if j.name == floating[0])}): only fixed-base "
            "arms are supported; remove that joint to fix the robot at its root link"
        )
    if not any(j.type in ("revolute", "continuous", "prismatic") for j in robot.joints):
        raise DescriptionError(f"robot description ({source}) has no movable joint")
    return robot


def floating_base_hint(robot) -> str:
    """A warning when the description (a ``yourdfpy.Robot`` without a floating joint) looks
    like a floating-base robot: several kinematic chains ending in feet (leaf links named
    foot, feet, toe or sole). It is loaded fixed at its root link all the same; "" for an
    arm."""
    parents = {j.parent for j in robot.joints}
    children = {j.child for j in robot.joints}
    feet = [
        link.name
        for link in robot.links
        if link.name not in parents and any(w in link.name.lower() for w in FOOT_WORDS)
    ]
    if len(feet) < 2:
        return ""
    root = next((link.name for link in robot.links if link.name not in children), "?")
    shown = ", ".join(feet[:4]) + (", ..." if len(feet) > 4 else "")
    return (
        f"the description looks like a floating-base robot ({len(feet)} kinematic chains end "
        f"in feet: {shown}) but has no floating joint: it is loaded with its root link "
        f"'{root}' fixed in the world, its feet in the air. This package controls fixed-base "
        "arms: to have such a description refused instead, give its root a floating joint "
        "(a floating base is refused at start)"
    )


# -- package:// and file:// URIs ---------------------------------------------------------


def package_search_roots(package_paths: Iterable[str] = ()) -> list[Path]:
    """Folders that may hold packages, in the order they are searched after the ament index:
    ``ROS_PACKAGE_PATH``, then ``package_paths``."""
    roots = [p for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    return [Path(p).expanduser() for p in (*roots, *package_paths)]


def find_package(name: str, package_paths: Iterable[str] = ()) -> Path | None:
    """The folder of package ``name``: ament index, then each search root (the root itself
    when its name is the package's, else its sub-folder of that name)."""
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(name))
    except (ImportError, LookupError, ValueError, OSError):
        pass  # not installed, not indexed, or no AMENT_PREFIX_PATH at all
    for root in package_search_roots(package_paths):
        for candidate in (root, root / name, root / "share" / name):
            if candidate.name == name and candidate.is_dir():
                return candidate
    return None


def resolve_uri(
    uri: str,
    base_dir: Path | None,
    package_paths: Iterable[str] = (),
    packages: dict[str, Path | None] | None = None,
) -> Path | None:
    """The file a mesh URI names, or None when it cannot be found (``packages``: package
    folders already looked up, filled as it goes)."""
    parsed = urlparse(uri)
    if parsed.scheme == "package":
        packages = {} if packages is None else packages
        if parsed.netloc not in packages:
            packages[parsed.netloc] = find_package(parsed.netloc, package_paths)
        root = packages[parsed.netloc]
        path = root / unquote(parsed.path).lstrip("/") if root is not None else None
    elif parsed.scheme == "file":
        path = Path(unquote(parsed.netloc + parsed.path))
    elif parsed.scheme == "":
        path = Path(uri)
        if not path.is_absolute():
            if base_dir is None:
                return None
            path = base_dir / path
    else:
        return None
    return path if path is not None and path.is_file() else None


def resolve_meshes(
    text: str, base_dir: Path | None, package_paths: Iterable[str] = ()
) -> tuple[str, list[str], bool]:
    """Rewrite every mesh ``filename`` to an absolute path.

    Returns the new text, the URIs that were not found (their visual/collision blocks are
    removed) and whether anything changed."""
    from lxml import etree

    root = etree.fromstring(text.encode("utf-8"))
    missing: list[str] = []
    changed = False
    packages: dict[str, Path | None] = {}  # one look-up per package, not per mesh
    for mesh in root.iter("mesh"):
        uri = mesh.get("filename", "")
        path = resolve_uri(uri, base_dir, package_paths, packages)
        if path is None:
            missing.append(uri)
            block = mesh.getparent()
            while block is not None and block.tag not in ("visual", "collision"):
                block = block.getparent()
            if block is not None and block.getparent() is not None:
                block.getparent().remove(block)
            changed = True
        elif str(path) != uri:
            mesh.set("filename", str(path.resolve()))
            changed = True
    if not changed:
        return text, missing, False
    return etree.tostring(root, encoding="unicode"), missing, True


def materialize(text: str) -> Path:
    """A file holding ``text``, named by its hash (written once, atomically)."""
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()[:20]
    folder = Path(tempfile.gettempdir()) / "joint_space_control-urdf"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{digest}.urdf"
    if not path.is_file():
        tmp = folder / f".{digest}.{os.getpid()}.tmp"
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    return path


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
