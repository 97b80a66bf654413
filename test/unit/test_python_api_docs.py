"""The README's "Use it from Python" example and docs/python.md's World example run as
written, and say what the README says they show."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def python_block(text: str, after: str) -> str:
    """The first ```python block after the line ``after``."""
    start = text.index(after)
    match = re.search(r"```python\n(.*?)```", text[start:], re.S)
    assert match is not None, f"no python block after {after!r}"
    return match.group(1)


def test_the_readme_python_example_runs_as_written(tmp_path, monkeypatch):
    code = python_block((ROOT / "README.md").read_text(), "### From Python")
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "README.md", "exec"), {})
    lines = printed.getvalue().splitlines()
    for controller in ("pd_gravity", "inverse_dynamics"):
        assert (tmp_path / "out" / "python" / controller / "positions.png").stat().st_size > 0
        rows = [line for line in lines if line.startswith(controller + " ")]
        assert len(rows) == 6  # the UR5's six joints
        numbers = [re.findall(r"(\d+\.\d+) ", row + " ") for row in rows]
        overshoot = [float(n[0]) for n in numbers]
        settling = [float(n[1]) for n in numbers]
        if controller == "inverse_dynamics":  # what the README says: 0 %, 5.83/ω_n
            assert max(overshoot) == 0.0
            assert all(abs(ts - 0.583) <= 0.01 for ts in settling)
        else:  # "lets the wrist overshoot by up to 18 %"
            assert 10.0 < max(overshoot) < 18.0


def test_the_world_example_of_the_python_page_runs_as_written():
    code = python_block((ROOT / "docs" / "python.md").read_text(), "## Several robots")
    scope: dict = {}
    exec(compile(code, "docs/python.md", "exec"), scope)
    arm, iiwa = scope["arm"], scope["iiwa"]
    assert arm.t[-1] == 3.0 and iiwa.t[-1] == 3.0
    np.testing.assert_array_equal(arm.config["kp"], [25.0, 25.0])  # ω_n = 5 after 1 s
    assert abs(arm.q[-1] - np.array([0.5, -0.3])).max() < 1e-3
    assert iiwa.joints and np.all(np.isfinite(iiwa.q))
