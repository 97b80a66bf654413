"""Packaging of the `joint_space_control` ROS 2 package (ament_python).

One setup.py serves both supported installs (see INTERFACES.md, "Package"):

- colcon build in a ROS 2 workspace: data_files put package.xml, the ament index marker,
  configs and URDFs under share/, and setup.cfg sends the console scripts to
  lib/joint_space_control/ where `ros2 run` looks for them;
- pip into a virtual environment: `pip install -e '.[pypi,test]'` (what `make venv` does)
  or a regular `pip install '.[pypi]'` / a wheel (`make wheel-check`) pulls ROS 2 Jazzy and
  the other runtime dependencies from PyPI through the `pypi` extra.

The data files the code reads (config/*.yaml, config/experiments/*.yaml, robots/urdf/*.urdf)
live inside the Python package and ship as package_data, so every install finds them with
importlib.resources (joint_space_control/paths.py); the share/ copies are only for users'
`--params-file` paths in a ROS workspace.

install_requires holds only setuptools on purpose: in a ROS install rclpy, the message
packages and most Python deps come from apt/rosdep and carry no PyPI metadata, so any
requirement listed there would make the colcon build's requirement checks fail.
"""

import sys
from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = "joint_space_control"
# Parameter and scenario files: package data (read by the code) and share/ (for users).
CONFIG = f"{PACKAGE_NAME}/config"

# `ros2 run joint_space_control <exe>` and launch files' Node(package=..., executable=...)
# look for executables in <prefix>/lib/joint_space_control/. `setup.py install/develop` (colcon)
# write the console scripts there (setup.cfg); a wheel cannot (pip writes them into bin/), so
# a wheel, and only a wheel (pip install, pip install -e, pip wheel, python -m build: the
# bdist_wheel / editable_wheel commands), also carries resource/launchers/<exe>, one small
# script per console script that runs it; never in a colcon build, where it would land on the
# console script's own path.
WHEEL_BUILD = bool({"bdist_wheel", "editable_wheel", "install_data"} & set(sys.argv[1:]))
LAUNCHERS = sorted(glob("resource/launchers/*")) if WHEEL_BUILD else []

# Runtime dependencies when installing from PyPI (no ROS apt packages on the machine).
PYPI_REQUIRES = [
    "ros-jazzy-rclpy[fastrtps]>=7.1,<8",
    "ros-jazzy-common-interfaces>=5.3,<6",
    "pin>=3,<5",
    "numpy>=1.26,<3",
    "pybullet>=3.2.5,<4",
    # The second physics engine (sim_bridge/mujoco_plant.py): the engine and its bindings
    # only, imported as `mujoco` (the `mujoco` package adds Studio, GLFW and PyOpenGL on top
    # and satisfies this too). 4.x: MjData.M, damping as a vector, MjSpec throughout.
    "mujoco-core>=4,<5",
    "rosbags>=0.10,<1",
    # `jsc recover`: reads a killed MCAP bag record by record (no summary needed)
    "mcap>=1.2,<2",
    "matplotlib>=3.8,<4",
    "pyyaml>=6,<7",
    # Robot descriptions as robot packages ship them (model/description.py): the URDF
    # parser for what Pinocchio does not expose (link inertials, mimic, joint blocks),
    # lxml to resolve mesh URIs, xacro to expand .xacro files.
    "yourdfpy>=0.0.56,<0.1",
    "lxml>=4.9,<7",
    "xacro>=2,<3",
    # The dashboard's web page: viser ships its built web client inside its wheel, so the
    # page works with no internet; 3D robots from a URDF (viser.extras.ViserUrdf, on
    # yourdfpy), uPlot plots and GUI controls.
    "viser>=1.1.1,<2",
]

# Test, lint and build-check tools (`make test`, `make colcon-check`, .ci/run).
# The workbench (`jsc experiment`, `jsc tune`) and the lab (`jsc bench`, `jsc soak`): what the
# product alone (the nodes, simulate(), jsc demo/analyze/view/recover) does not need.
WORKBENCH_REQUIRES = [
    # Sweeps and tuning trials as tasks on a cluster (workbench/experiments/execution/
    # distributed.py): a LocalCluster, or any dask.distributed scheduler (SLURM/PBS:
    # dask-jobqueue).
    "dask[distributed]>=2024.8",
    # `jsc tune`: TPE studies with constraints, resumable from an RDB (SQLite) file.
    "optuna>=4,<6",
]
LAB_REQUIRES = WORKBENCH_REQUIRES  # the bench's sweep runs on the workbench's pool

TEST_REQUIRES = [
    "pytest>=8,<10",
    "pytest-timeout>=2.2,<3",
    # Two workers: the lockstep integration tests wait on inter-process messages more
    # than they compute, so two at a time nearly halve the suite's wall time.
    "pytest-xdist>=3.5,<4",
    "hypothesis>=6.100,<7",
    # Pinned to one minor series: `ruff format --check` output changes between minors.
    "ruff>=0.17,<0.18",
    "mcap-ros2-support>=0.5,<1",
    "colcon-common-extensions>=0.3,<1",
    # Real robot descriptions nobody here wrote (UR, Panda, xArm, Kinova, Z1, SO-100/101),
    # with meshes and package:// URIs: the corpus of test/unit/test_corpus.py.
    "example-robot-data>=4.1,<7",
    # The dashboard's browser test drives Debian's Chromium headless (`make system-deps`)
    # by executable_path=/usr/bin/chromium (test/integration/browser.py): no browser is
    # ever downloaded, never run `playwright install`.
    "playwright>=1.45,<2",
]

setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    description="Joint-space control of robot arms on ROS 2 with a PyBullet simulator.",
    license="Apache-2.0",
    maintainer="joint_space_control developers",
    maintainer_email="jsc@example.com",
    python_requires=">=3.10",
    packages=find_packages(exclude=["test", "test.*"]),
    package_data={
        PACKAGE_NAME: ["config/*.yaml", "config/experiments/*.yaml"],
        f"{PACKAGE_NAME}.robots": ["urdf/*.urdf"],
        f"{PACKAGE_NAME}.processes": ["*.xml"],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE_NAME}"]),
        (f"share/{PACKAGE_NAME}", ["package.xml"]),
        (f"share/{PACKAGE_NAME}/config", sorted(glob(f"{CONFIG}/*.yaml"))),
        (f"share/{PACKAGE_NAME}/config/experiments", sorted(glob(f"{CONFIG}/experiments/*.yaml"))),
        (f"share/{PACKAGE_NAME}/urdf", sorted(glob(f"{PACKAGE_NAME}/robots/urdf/*.urdf"))),
        # `ros2 launch joint_space_control <file>` (after colcon and from a pip install)
        (f"share/{PACKAGE_NAME}/launch", sorted(glob("launch/*.launch.py"))),
        *([(f"lib/{PACKAGE_NAME}", LAUNCHERS)] if LAUNCHERS else []),
    ],
    install_requires=["setuptools"],
    extras_require={
        "pypi": PYPI_REQUIRES,
        "workbench": WORKBENCH_REQUIRES,
        "lab": LAB_REQUIRES,
        "test": TEST_REQUIRES,
    },
    # The URDFs and scenario files are handed to PyBullet, Pinocchio and node processes as
    # file names: they must be real files, never inside a zipped egg.
    zip_safe=False,
    entry_points={
        "console_scripts": [
            "sim_bridge = sim_bridge.node:main",
            "pd_gravity_controller = joint_space_control.nodes.pd_gravity_controller:main",
            "inverse_dynamics_controller = "
            "joint_space_control.nodes.inverse_dynamics_controller:main",
            "trajectory_generator = joint_space_control.nodes.trajectory_generator:main",
            "recorder = joint_space_control.nodes.recorder:main",
            "dashboard = joint_space_control.nodes.dashboard:main",
            "jsc = joint_space_control.cli.main:main",
        ],
    },
)
