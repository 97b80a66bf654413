"""`jsc experiment` end to end: a scenario checked against the theory, and every installed
scenario in its short (CI) form."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.experiments.scenario import available

pytestmark = pytest.mark.integration


def jsc(*args: str, timeout: float) -> subprocess.CompletedProcess:
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    return subprocess.run(
        [sys.executable, "-m", "joint_space_control.cli.main", "experiment", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


def test_inverse_dynamics_scenario_end_to_end_agrees_with_the_theory(tmp_path):
    result = jsc("q6_inverse_dynamics_nominal", "--out", str(tmp_path), timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    out = tmp_path / "q6_inverse_dynamics_nominal"
    verdict = json.loads((out / "result.json").read_text())
    assert verdict["passed"] is True
    assert {c["check"] for c in verdict["checks"]} == {"second_order"}
    # The report's own metrics, against the analytic second order (same tolerances as the
    # closed-loop tests): overshoot within 1 point, 2 % settling within 5 %, e_ss < 1e-4.
    metrics = json.loads((out / "report" / "metrics.json").read_text())
    controller = metrics["controllers"]["/inverse_dynamics_controller"]
    theory = second_order_prediction([8.0, 12.0], [0.5, 0.8])
    (step,) = controller["steps"]
    for j, name in enumerate(["joint1", "joint2"]):
        m = step["joints"][name]
        assert abs(m["overshoot_percent"] - theory["overshoot_percent"][j]) < 1.0
        assert abs(m["settling_time_2"] - theory["settling_time_2"][j]) <= max(
            0.05 * theory["settling_time_2"][j], 1e-3
        )
        assert abs(m["steady_state_error"]) < 1e-4
    summary = (out / "summary.md").read_text()
    assert "agrees" in summary and "positions.png" in summary
    assert (out / "bag" / "metadata.yaml").is_file()


def _chunks(parts: int = 3) -> list[list[str]]:
    """The installed scenarios in ``parts`` chunks of about equal size (one jsc call each:
    the chunks spread over the test workers and stay within the per-test timeout)."""
    names = list(available())
    return [names[k::parts] for k in range(parts)]


@pytest.mark.timeout(900)
@pytest.mark.parametrize("names", _chunks(), ids=lambda names: f"{names[0]}..")
def test_every_scenario_runs_in_its_short_form(tmp_path, names):
    docs = tmp_path / "docs"
    result = jsc(*names, "--short", "--out", str(tmp_path), "--report", str(docs), timeout=900)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    for name in names:
        verdict = json.loads((tmp_path / name / "result.json").read_text())
        assert verdict["errors"] == [], (name, verdict["errors"])
        for run in verdict["runs"]:
            report = Path(run["dir"]) / "report"
            assert (report / "report.md").is_file() and (report / "metrics.json").is_file()
        assert verdict["checks"], f"{name}: no check evaluated"
    page = (docs / "results.md").read_text()
    assert page.count("### ") == len(names)
    for link in [line for line in page.splitlines() if line.startswith("![")]:
        target = link[link.index("](") + 2 : -1]
        assert (docs / target).is_file(), target


def test_ctrl_c_stops_every_node_of_a_running_experiment(tmp_path):
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    cmd = [sys.executable, "-m", "joint_space_control.cli.main", "experiment"]
    proc = subprocess.Popen(
        [*cmd, "q4_sinusoid_tracking", "--out", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
    )
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob("q4_sinusoid_tracking/*/bag/*.mcap")):
            assert proc.poll() is None and time.monotonic() < deadline, "no run started"
            time.sleep(0.2)
        time.sleep(2.0)  # running
        proc.send_signal(signal.SIGINT)
        output, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        # what jsc experiment left running (none, if it works): found, then stopped, also
        # when the test fails
        leftovers = subprocess.run(
            ["pgrep", "-f", str(tmp_path)], capture_output=True, text=True
        ).stdout.split()
        for pid in leftovers:
            with contextlib.suppress(ProcessLookupError, ValueError):
                os.kill(int(pid), signal.SIGKILL)
    assert proc.returncode == 130, output
    assert "interrupted" in output
    assert leftovers == [], f"node processes still running: {leftovers}"
