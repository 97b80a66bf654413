"""`jsc experiment` end to end: a scenario checked against the theory, two robots in one world
judged each on its own, and every installed scenario in its short (CI) form."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.workbench.experiments.execution.equivalence import compare_experiments
from joint_space_control.workbench.experiments.scenarios.format import available

from .conftest import interrupt_once_running

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


@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_two_robots_in_one_world_are_each_analysed_and_checked(tmp_path):
    """One world, one bag, one report: each robot's controller analysed as a run of its own,
    the checks per robot (the iiwa's PD + g at its set-point, the arm's inverse dynamics the
    second order of its gains), both on the results page."""
    docs = tmp_path / "docs"
    # in process (a world of two robots over ROS: test_two_robots.py, and make test-long
    # runs this scenario on both engines)
    result = jsc(
        "two_robots", "--out", str(tmp_path), "--report", str(docs),
        "--engine", "inprocess", "--scheduler", "threads", "--jobs", "1", timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    out = tmp_path / "two_robots"
    verdict = json.loads((out / "result.json").read_text())
    assert verdict["passed"] is True and verdict["errors"] == []
    assert [(r["label"], r["robot"], r["controller"]) for r in verdict["runs"]] == [
        ("iiwa", "iiwa", "pd_gravity_controller"),
        ("arm", "planar_2dof", "inverse_dynamics_controller"),
    ]
    metrics = json.loads((out / "report" / "metrics.json").read_text())
    nodes = {"iiwa": "/iiwa/pd_gravity_controller", "arm": "/arm/inverse_dynamics_controller"}
    assert set(metrics["controllers"]) == set(nodes.values())
    final = {c["text"].split(":")[0]: c for c in verdict["checks"] if c["check"] == "final_error"}
    assert set(final) == set(nodes)
    for robot, node in nodes.items():
        controller = metrics["controllers"][node]
        assert len(controller["joints"]) == {"iiwa": 7, "arm": 2}[robot]
        assert controller["time"]["end"] == 4.0
        # the check judged this robot's own numbers, and they agree
        largest = max(abs(e) for e in controller["final_error"].values())
        assert final[robot]["numbers"]["max_abs_final_error"] == largest
        assert final[robot]["passed"] is True and largest < 1e-3
        for topic in ("joint_states", "effort_command", "reference"):
            assert metrics["message_counts"][f"/{robot}/{topic}"] >= 1
        # 0 … 4 s at 1 kHz, each state answered; a state left unanswered 0.5 s of wall time
        # is sent again (republish_period), so the bag may hold a state twice
        assert controller["samples"]["analysed"] == 4001
        assert metrics["message_counts"][f"/{robot}/joint_states"] >= 4001
    second = [c for c in verdict["checks"] if c["check"] == "second_order"]
    assert [c["numbers"]["joint"] for c in second] == ["joint1", "joint2"]
    assert all(c["passed"] and c["text"].startswith("arm ") for c in second)
    events = json.loads((out / "events.json").read_text())
    assert set(events) == set(nodes) and len(events["iiwa"][-1]["q"]) == 7
    page = (docs / "results.md").read_text()
    assert "## In practice: several robots in one world" in page and "### 15. " in page
    links = [
        line[line.index("](") + 2 : -1] for line in page.splitlines() if line.startswith("![")
    ]
    assert [Path(link).name for link in links] == [
        "two_robots_iiwa_pd_gravity_controller_positions.png",
        "two_robots_arm_inverse_dynamics_controller_positions.png",
    ]
    assert all((docs / link).is_file() for link in links)


#: §5's and §4's checks on a real plant, each engine: the pure-PD offset, PD + g at its
#: set-point, the disturbance offsets, the inverse-dynamics step (second order), and two
#: robots in one world.
ON_BOTH_ENGINES = [
    "q1_pd_gravity_setpoint",
    "q2_pd_without_gravity",
    "q6_inverse_dynamics_nominal",
    "disturbance",
    "two_robots",
]


@pytest.mark.long  # ten full runs, 120 s of a worker: make test-long (make test's budget)
def test_the_theory_holds_on_both_plant_engines_and_the_page_compares_them(tmp_path):
    """`--plant-engine pybullet,mujoco` (issue 26): every scenario's full run on each engine,
    judged by the same checks to the same tolerances (all agree), in OUT/<engine>/, and the
    results page's engine-by-engine table: a row per check, and the engines' largest
    position difference, which on these frictionless plants is rounding (the same scheme,
    the same model: 1e-9 rad bounds it with room; ~1e-15 seen)."""
    docs = tmp_path / "docs"
    result = jsc(
        *ON_BOTH_ENGINES, "--out", str(tmp_path), "--report", str(docs),
        "--engine", "inprocess", "--plant-engine", "pybullet,mujoco",
        "--scheduler", "threads", "--jobs", "2", timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    assert "plant pybullet, mujoco" in result.stdout
    checks = {}
    for engine in ("pybullet", "mujoco"):
        for name in ON_BOTH_ENGINES:
            verdict = json.loads((tmp_path / engine / name / "result.json").read_text())
            assert verdict["passed"] is True and verdict["errors"] == [], (engine, name)
            checks[engine, name] = [c["check"] for c in verdict["checks"]]
    for name in ON_BOTH_ENGINES:
        assert checks["pybullet", name] == checks["mujoco", name] != []
    page = (docs / "results.md").read_text()
    table = page[page.index("## Engine by engine") :].split("\n\n")[2].splitlines()
    assert table[0] == "| Experiment | PyBullet | MuJoCo | max \\|q_MuJoCo − q_PyBullet\\| |"
    rows = [row for row in table[2:] if row.startswith("| Q")]
    assert len(rows) == len(ON_BOTH_ENGINES)
    assert len(table) - 2 == sum(len(c) for (e, _), c in checks.items() if e == "mujoco")
    for row in rows:
        apart = float(row.rstrip(" |").rsplit("|", 1)[1])
        assert apart < 1e-9, row
    assert result.stdout.count("DISAGREES") == 0


def _chunks(parts: int = 3) -> list[list[str]]:
    """The installed scenarios in ``parts`` chunks of about equal size (one jsc call each:
    the chunks spread over the test workers and stay within the per-test timeout)."""
    names = list(available())
    return [names[k::parts] for k in range(parts)]


@pytest.mark.long  # seven minutes of a worker: make test-long
@pytest.mark.timeout(900)
@pytest.mark.parametrize("names", _chunks(), ids=lambda names: f"{names[0]}..")
def test_every_scenario_runs_in_its_short_form_and_both_engines_agree(tmp_path, names):
    """Every scenario's short form on the ROS engine (the nodes as processes, its results
    page), then on the in-process engine: the same check texts and verdicts, and every
    run's metrics bit for bit, apart from what only the recording's clock decides
    (equivalence.RECORDING_KEYS)."""
    docs = tmp_path / "docs"
    ros, local = tmp_path / "ros", tmp_path / "inprocess"
    result = jsc(*names, "--short", "--out", str(ros), "--report", str(docs), timeout=900)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    for name in names:
        verdict = json.loads((ros / name / "result.json").read_text())
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

    result = jsc(
        *names, "--short", "--out", str(local), "--engine", "inprocess",
        "--scheduler", "threads", "--jobs", "1", timeout=900,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    assert "engine inprocess" in result.stdout
    for name in names:
        assert compare_experiments(ros / name, local / name) == [], name


@pytest.mark.long  # about a minute and a half: make test-long
@pytest.mark.timeout(900)
def test_every_scenario_runs_on_mujoco_as_on_pybullet(tmp_path):
    """Every installed scenario (every imperfection, sweep and world of several robots) in
    its short form on the MuJoCo plant and on PyBullet's, in process: no run fails on
    either, and every check of one is a check of the other with the same verdict, except
    where the engines' constraints differ (Coulomb friction, stiction, brakes: MuJoCo's are
    soft, docs/plant.md Engines), whose texts are compared but not required equal."""
    result = jsc(
        *available(), "--short", "--out", str(tmp_path), "--engine", "inprocess",
        "--plant-engine", "pybullet,mujoco", "--scheduler", "threads", "--jobs", "2",
        timeout=900,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    for name in available():
        verdicts = {
            e: json.loads((tmp_path / e / name / "result.json").read_text())
            for e in ("pybullet", "mujoco")
        }
        for engine, verdict in verdicts.items():
            assert verdict["errors"] == [], (engine, name, verdict["errors"])
        checks = {e: [(c["check"], c["passed"]) for c in v["checks"]] for e, v in verdicts.items()}
        assert checks["mujoco"] == checks["pybullet"], name


@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_ctrl_c_stops_every_node_of_a_running_experiment(tmp_path):
    proc, output, leftovers = interrupt_once_running(
        ["experiment", "q4_sinusoid_tracking", "--out", str(tmp_path)],
        "q4_sinusoid_tracking/*/bag/*.mcap",
        tmp_path,
        running=2.0,
    )
    assert proc.returncode == 130, output
    assert "interrupted" in output
    assert leftovers == [], f"node processes still running: {leftovers}"
