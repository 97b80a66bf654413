"""Package data (parameter files, scenarios, URDFs) is found through importlib.resources and
ships with the package, so a wheel install works without the source tree or a sourced ROS
workspace (issue 12: `pip install '.[pypi]'` broke every scenario). `make wheel-check` runs
the real wheel end to end; these tests catch the same mistakes in a second."""

from __future__ import annotations

import importlib.resources
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from joint_space_control import paths
from joint_space_control.model.robots import builtin_robots
from joint_space_control.workbench.experiments.scenarios import format as scenarios

ROOT = Path(__file__).resolve().parents[2]
PACKAGE_DIR = ROOT / "joint_space_control"
# The parameter files `jsc demo` reads.
DEMO_CONFIGS = ("pd_gravity_controller.yaml", "sim_bridge.yaml")


def _data_files(package_dir: Path) -> set[str]:
    """Every file under the package that is not Python code, relative to it."""
    return {
        p.relative_to(package_dir).as_posix()
        for p in package_dir.rglob("*")
        if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts
    }


def test_the_source_tree_has_the_data_the_commands_need():
    files = _data_files(PACKAGE_DIR)
    assert {f"config/{name}" for name in DEMO_CONFIGS} <= files
    assert "config/experiments/q6_inverse_dynamics_nominal.yaml" in files
    assert "robots/urdf/planar_2dof.urdf" in files
    # The README's `config/...` paths go through the root symlink to the one copy.
    assert (ROOT / "config").resolve() == (PACKAGE_DIR / "config").resolve()


def test_lookup_goes_through_importlib_resources_not_the_source_tree_or_ament(
    tmp_path, monkeypatch
):
    """With importlib.resources pointed at a copy of the data, every file `jsc experiment
    --list` and `jsc demo` need comes from the copy: nothing falls back to paths relative to
    the source files, and nothing needs AMENT_PREFIX_PATH."""
    copy = tmp_path / "site-packages" / "joint_space_control"
    for relative in _data_files(PACKAGE_DIR):
        (copy / relative).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(PACKAGE_DIR / relative, copy / relative)
    real_files = importlib.resources.files

    def files(anchor):
        return copy if anchor == "joint_space_control" else real_files(anchor)

    monkeypatch.setattr(importlib.resources, "files", files)
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)

    assert paths.data_dir() == copy
    found = scenarios.available()
    assert set(found) == {p.stem for p in (PACKAGE_DIR / "config/experiments").glob("*.yaml")}
    assert all(p.parent == copy / "config" / "experiments" for p in found.values())
    for name in found:  # what `jsc experiment --list` does with each
        assert scenarios.load(name).path.is_relative_to(copy)
    for name in DEMO_CONFIGS:
        assert paths.config_file(name) == copy / "config" / name
    assert builtin_robots()["planar_2dof"].urdf_path == copy / "robots/urdf/planar_2dof.urdf"


def test_a_broken_install_says_what_is_missing(tmp_path, monkeypatch):
    empty = tmp_path / "joint_space_control"
    empty.mkdir()
    monkeypatch.setattr(importlib.resources, "files", lambda anchor: empty)
    with pytest.raises(FileNotFoundError, match="installed without its data"):
        scenarios.available()
    with pytest.raises(FileNotFoundError, match="installed without its data"):
        paths.config_file("sim_bridge.yaml")


def test_the_built_package_carries_every_data_file_and_lists_the_scenarios(tmp_path):
    """setup.py's build step (what a wheel is made of) copies every data file, and the built
    package alone, imported from outside the source tree, lists every scenario."""
    lib = tmp_path / "lib"
    build = subprocess.run(
        [sys.executable, "setup.py", "-q", "build_py", "--build-lib", str(lib)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert build.returncode == 0, build.stderr
    assert _data_files(lib / "joint_space_control") == _data_files(PACKAGE_DIR)

    probe = textwrap.dedent(
        """
        import contextlib, io, json
        import joint_space_control
        from joint_space_control.cli.main import main
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = main(["experiment", "--list"])
        print(json.dumps({"file": joint_space_control.__file__, "code": code,
                          "lines": out.getvalue().splitlines()}))
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "AMENT_PREFIX_PATH"}
    env["PYTHONPATH"] = str(lib)  # instead of the checkout (tests run with it on the path)
    result = subprocess.run(
        [sys.executable, "-c", probe],
        cwd=tmp_path,  # not the checkout: it must not be importable from the working dir
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    listed = json.loads(result.stdout.splitlines()[-1])
    assert Path(listed["file"]).is_relative_to(lib)
    assert listed["code"] == 0
    names = [line.split()[0] for line in listed["lines"]]
    assert names == sorted(p.stem for p in (PACKAGE_DIR / "config/experiments").glob("*.yaml"))
    assert not [line for line in listed["lines"] if "INVALID" in line]
