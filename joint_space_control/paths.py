"""Where the package's data files (parameter files, scenarios, URDFs) are, however it was
installed.

They ship inside the Python package (``joint_space_control/config/``,
``joint_space_control/robots/urdf/``, setup.py ``package_data``) and are found with
``importlib.resources``, so one lookup serves every install: a wheel (``pip install
'.[pypi]'``), the editable install, a checkout on ``PYTHONPATH`` and a colcon workspace
(``setup.py install`` puts the package data into site-packages too). The ament index is
deliberately not consulted: it needs ``AMENT_PREFIX_PATH``, which only a sourced ROS
workspace sets, and a pip install has none. colcon
still copies the parameter files to ``share/joint_space_control/config`` for
``ros2 run ... --params-file`` (README), but the code never reads them from there.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

PACKAGE = "joint_space_control"


def data_dir() -> Path:
    """The installed package's directory, as ``importlib.resources`` finds it.

    A real directory is required (not a zip archive): the URDF paths are handed to PyBullet
    and Pinocchio, and scenario paths to the node processes, as file names.
    """
    root = resources.files(PACKAGE)
    if not isinstance(root, Path) or not root.is_dir():
        raise FileNotFoundError(
            f"the data files of {PACKAGE} are not in a directory ({root!r}): "
            "install it unpacked (pip install, colcon build), not as a zip"
        )
    return root


def config_dir() -> Path:
    """``config/``: the nodes' parameter files (``--params-file``)."""
    return _existing_dir(data_dir() / "config")


def experiments_dir() -> Path:
    """``config/experiments/``: the scenario files of ``jsc experiment``."""
    return _existing_dir(data_dir() / "config" / "experiments")


def config_file(name: str) -> Path:
    path = config_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"no config file {path}")
    return path


def _existing_dir(path: Path) -> Path:
    # A missing directory means a broken install (package_data not shipped); saying so beats
    # an empty scenario list.
    if not path.is_dir():
        raise FileNotFoundError(f"{path} is missing: {PACKAGE} was installed without its data")
    return path
