"""Robot descriptions nobody here wrote: the arms of ``example-robot-data`` (PyPI) and one of
``pybullet_data``, as the tests load them.

The registry package installs its robots under ``<site-packages>/cmeel.prefix/share``
(``package://example-robot-data/...`` URIs); that folder is given as ``package_paths``,
as a user without a ROS install would.
"""

from __future__ import annotations

import sysconfig
from dataclasses import dataclass
from pathlib import Path

import pybullet_data

SHARE = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share"
ROBOTS = SHARE / "example-robot-data" / "robots"
PACKAGE_PATHS = [str(SHARE)]


@dataclass(frozen=True)
class CorpusRobot:
    name: str
    path: Path
    #: |PyBullet inverse dynamics − Pinocchio rnea| allowed [N·m], and why when not rounding.
    id_tolerance: float = 1e-9
    why: str = ""

    def params(self) -> dict[str, object]:
        """Node parameters that load it."""
        return {"urdf_path": str(self.path), "package_paths": PACKAGE_PATHS}


CORPUS = [
    CorpusRobot("ur3", ROBOTS / "ur_description/urdf/ur3_robot.urdf"),
    CorpusRobot("ur5", ROBOTS / "ur_description/urdf/ur5_robot.urdf"),
    CorpusRobot("ur10", ROBOTS / "ur_description/urdf/ur10_robot.urdf"),
    CorpusRobot("panda", ROBOTS / "panda_description/urdf/panda.urdf"),
    CorpusRobot("xarm7", ROBOTS / "xarm_description/urdf/xarm7.urdf"),
    CorpusRobot("kinova", ROBOTS / "kinova_description/robots/kinova.urdf"),
    CorpusRobot("z1", ROBOTS / "z1_description/urdf/z1.urdf"),
    CorpusRobot("so100", ROBOTS / "so_arm_description/urdf/so100.urdf"),
    CorpusRobot("so101", ROBOTS / "so_arm_description/urdf/so101.urdf"),
    CorpusRobot(
        "xarm6",
        Path(pybullet_data.getDataPath()) / "xarm/xarm6_robot.urdf",
        0.1,
        "link2 and link3 have inertias that violate the triangle inequality: PyBullet "
        "replaces them with zero (the plant warns), the controller model keeps the URDF's",
    ),
]
BY_NAME = {robot.name: robot for robot in CORPUS}
#: Effort "0" on every joint (an exporter placeholder).
DOUBLE_PENDULUM = ROBOTS / "double_pendulum_description/urdf/double_pendulum.urdf"
#: A humanoid whose floating root joint is commented out in the file ("uncomment when
#: convert to mujoco"): :func:`floating_g1` uncomments it.
G1 = ROBOTS / "g1_description/urdf/g1_29dof_rev_1_0.urdf"


def floating_g1() -> str:
    """The G1 humanoid with its own floating base joint (the file's commented block)."""
    text = G1.read_text()
    start = text.index('<!-- <link name="world">')
    end = text.index("-->", start)
    block = text[start + len("<!--") : end]
    assert 'type="floating"' in block
    return text[:start] + block + text[end + len("-->") :]
