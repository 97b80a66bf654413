"""The launch files (launch/*.launch.py) and the executables `ros2 run` and launch files find
in a pip install (resource/launchers/*, installed into <prefix>/lib/joint_space_control/ by a
wheel only: setup.py).

The launch files compile everywhere; their LaunchDescription is built only where launch_ros
is importable (a ROS install: it is not on PyPI). How they were tried by hand with the real
`ros2 launch`: docs/install.md, "Launch files"."""

from __future__ import annotations

import os
import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest
import setuptools

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "joint_space_control"
LAUNCH_FILES = sorted((ROOT / "launch").glob("*.launch.py"))
LAUNCHERS = ROOT / "resource" / "launchers"

#: The arguments users pass (docs/install.md, "Launch files").
SIM_ARGUMENTS = {
    "robot",
    "urdf_path",
    "engine",
    "mode",
    "initial_positions",
    "controller",
    "reference",
    "record",
    "output",
    "view",
}
CONTROLLERS_ARGUMENTS = {"controller", "robot", "urdf_path", "forward_controller"}


def _setup_kwargs(monkeypatch: pytest.MonkeyPatch, *argv: str) -> dict:
    """What setup.py hands to setuptools.setup() when run with ``argv``."""
    captured: dict = {}
    monkeypatch.setattr(setuptools, "setup", lambda **kwargs: captured.update(kwargs))
    monkeypatch.setattr(sys, "argv", ["setup.py", *argv])
    monkeypatch.chdir(ROOT)
    runpy.run_path(str(ROOT / "setup.py"), run_name="__main__")
    return captured


def _console_scripts(kwargs: dict) -> dict[str, str]:
    """Console script name -> module, from setup.py's entry points."""
    entries = kwargs["entry_points"]["console_scripts"]
    return dict(
        (name.strip(), target.split(":")[0].strip())
        for name, target in (e.split("=") for e in entries)
    )


def _installed(kwargs: dict, destination: str) -> list[str]:
    return [f for dest, files in kwargs["data_files"] if dest == destination for f in files]


def test_the_launch_files_exist_and_compile():
    assert [p.name for p in LAUNCH_FILES] == ["controllers.launch.py", "sim.launch.py"]
    for path in LAUNCH_FILES:
        compile(path.read_text(encoding="utf-8"), str(path), "exec")


def test_setup_installs_the_launch_files_in_share(monkeypatch):
    kwargs = _setup_kwargs(monkeypatch, "install")
    installed = _installed(kwargs, f"share/{PACKAGE}/launch")
    assert sorted(installed) == [str(p.relative_to(ROOT)) for p in LAUNCH_FILES]


def test_only_a_wheel_carries_the_launchers(monkeypatch):
    """In a colcon build (setup.py install/develop) the console scripts themselves land in
    lib/joint_space_control (setup.cfg): a launcher there would take their path."""
    for argv in (("bdist_wheel", "--dist-dir", "x"), ("editable_wheel", "--dist-dir", "x")):
        kwargs = _setup_kwargs(monkeypatch, *argv)
        launchers = [Path(f).name for f in _installed(kwargs, f"lib/{PACKAGE}")]
        assert sorted(launchers) == sorted(_console_scripts(kwargs)), argv
    for argv in (("install",), ("develop",), ("egg_info",), ()):
        kwargs = _setup_kwargs(monkeypatch, *argv)
        assert not _installed(kwargs, f"lib/{PACKAGE}"), argv


def test_each_launcher_is_an_executable_shell_script_for_its_console_script(monkeypatch):
    scripts = _console_scripts(_setup_kwargs(monkeypatch, "bdist_wheel"))
    assert sorted(p.name for p in LAUNCHERS.iterdir()) == sorted(scripts)
    for name in scripts:
        launcher = LAUNCHERS / name
        text = launcher.read_text(encoding="utf-8")
        assert os.access(launcher, os.X_OK), f"{launcher} is not executable (git: mode 755)"
        assert text.startswith("#!/bin/sh\n"), launcher
        subprocess.run(["sh", "-n", str(launcher)], check=True)
        # The console script of the same name, next to it in the install: <prefix>/bin/<name>
        assert re.search(rf'/\.\./\.\./bin" .*\)/{name}"$', text, re.M), launcher
        assert text.rstrip().endswith('exec "$bin" "$@"'), launcher


def test_a_launcher_runs_the_console_script_beside_it_with_the_arguments(tmp_path):
    """A pip install's layout: <prefix>/lib/joint_space_control/<exe> and <prefix>/bin/<exe>;
    the launcher replaces itself with the console script (exec: the same process, so the
    signals launch sends reach the node), from any working directory and through a symlink
    to <prefix>."""
    prefix = tmp_path / "venv"
    (prefix / "lib" / PACKAGE).mkdir(parents=True)
    (prefix / "bin").mkdir()
    launcher = prefix / "lib" / PACKAGE / "sim_bridge"
    launcher.write_bytes((LAUNCHERS / "sim_bridge").read_bytes())
    launcher.chmod(0o755)
    script = prefix / "bin" / "sim_bridge"
    script.write_text('#!/bin/sh\necho "console script $$: $*"\n', encoding="utf-8")
    script.chmod(0o755)
    (tmp_path / "link").symlink_to(prefix)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    for path in (launcher, tmp_path / "link" / "lib" / PACKAGE / "sim_bridge"):
        out = subprocess.run(
            [
                "sh",
                "-c",
                'echo "shell $$"; exec "$0" "$@"',
                str(path),
                "--ros-args",
                "-p",
                "a:=b c",
            ],
            cwd=elsewhere,
            capture_output=True,
            text=True,
            check=True,
            timeout=30,
        ).stdout.split("\n")
        shell_pid = out[0].split()[1]
        assert out[1] == f"console script {shell_pid}: --ros-args -p a:=b c", out


def test_a_launcher_without_its_console_script_says_so(tmp_path):
    (tmp_path / "lib" / PACKAGE).mkdir(parents=True)
    launcher = tmp_path / "lib" / PACKAGE / "recorder"
    launcher.write_bytes((LAUNCHERS / "recorder").read_bytes())
    launcher.chmod(0o755)
    done = subprocess.run([str(launcher)], capture_output=True, text=True, timeout=30)
    assert done.returncode == 127
    assert "recorder: console script" in done.stderr and "not found" in done.stderr


def _text(substitution) -> str:
    """A substitution as text: a launch argument as <name>."""
    from launch.substitutions import LaunchConfiguration, TextSubstitution

    if isinstance(substitution, TextSubstitution):
        return substitution.text
    if isinstance(substitution, LaunchConfiguration):
        return "<" + "".join(_text(s) for s in substitution.variable_name) + ">"
    return substitution.describe()


def _description(path: Path):
    from launch.launch_description_sources import get_launch_description_from_python_launch_file

    return get_launch_description_from_python_launch_file(str(path))


@pytest.mark.parametrize(
    "name, arguments, executables",
    [
        (
            "sim.launch.py",
            SIM_ARGUMENTS,
            [
                "sim_bridge",
                "<controller>_controller",
                "trajectory_generator",
                "recorder",
                "dashboard",
            ],
        ),
        ("controllers.launch.py", CONTROLLERS_ARGUMENTS, ["<controller>_controller"]),
    ],
)
def test_the_launch_descriptions_build(name, arguments, executables):
    pytest.importorskip(
        "launch_ros", reason="launch_ros is not installed (a ROS 2 install; not on PyPI)"
    )
    from launch.actions import DeclareLaunchArgument
    from launch.utilities import normalize_to_list_of_substitutions
    from launch_ros.actions import Node

    description = _description(ROOT / "launch" / name)
    declared = {e.name: e for e in description.entities if isinstance(e, DeclareLaunchArgument)}
    assert arguments <= set(declared), sorted(declared)
    assert set(declared["controller"].choices) >= {"pd_gravity", "inverse_dynamics"}
    nodes = [e for e in description.entities if isinstance(e, Node)]
    shown = []
    for node in nodes:
        assert node.node_package == PACKAGE
        executable = normalize_to_list_of_substitutions(node.node_executable)
        shown.append("".join(_text(s) for s in executable))
    assert shown == executables, shown
