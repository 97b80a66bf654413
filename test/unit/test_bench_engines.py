"""jsc bench's two physics engines (issue 26, item 6): the physics step per robot and engine
in process, the lockstep loop on MuJoCo against PyBullet, their ratios and their lines in
the table. Structure only: the timings of a shared machine are never judged."""

from __future__ import annotations

import math

import pytest

from joint_space_control.lab.bench import compute
from joint_space_control.lab.bench.run import (
    ENGINES,
    LAWS,
    ROBOTS,
    format_table,
    median_row,
    physics_ratios,
    ratios,
)
from sim_bridge.engines import ENGINES as PLANT_ENGINES


def test_the_bench_engines_are_the_plants():
    assert ENGINES == PLANT_ENGINES


def test_physics_step_per_robot_and_engine():
    steps, repeats = 40, 3
    section = compute.physics_steps(("planar_2dof", "iiwa", "ur5"), ENGINES, steps, repeats)
    assert section["skipped"] == []
    rows = section["rows"]
    assert [(r["robot"], r["engine"]) for r in rows] == [
        (robot, engine) for robot in ("planar_2dof", "iiwa", "ur5") for engine in ENGINES
    ]
    joints = {"planar_2dof": 2, "iiwa": 7, "ur5": 6}
    for row in rows:
        assert row["joints"] == joints[row["robot"]]
        assert (row["steps"], row["repeats"]) == (steps, repeats)
        each = row["us_per_step_repeats"]
        assert len(each) == repeats
        assert all(math.isfinite(x) and x > 0 for x in each)
        assert row["us_per_step"] == sorted(each)[1]  # the median of three
        assert row["per_step"]["samples"] == steps * repeats
        assert 0 < row["per_step"]["p50_us"] <= row["per_step"]["max_us"]


def test_what_is_not_installed_is_left_out_with_the_reason(monkeypatch):
    monkeypatch.setattr(compute, "example_robot_data_share", lambda: None)
    real = compute.engine_missing
    monkeypatch.setattr(
        compute,
        "engine_missing",
        lambda engine: "not here" if engine == "mujoco" else real(engine),
    )
    section = compute.physics_steps(("planar_2dof", "ur5"), ENGINES, 5, 1)
    assert [(r["robot"], r["engine"]) for r in section["rows"]] == [("planar_2dof", "pybullet")]
    assert section["skipped"] == [
        "mujoco: not here",
        "ur5: example-robot-data is not installed",
    ]
    assert physics_ratios(section["rows"]) == []


def test_robot_parameters_find_example_robot_data():
    assert compute.robot_parameters("iiwa") == {"robot": "iiwa"}
    ur5 = compute.robot_parameters("ur5")
    share = compute.example_robot_data_share()
    assert ur5 == {
        "urdf_path": str(share / "example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"),
        "package_paths": [str(share)],
    }


def test_engine_missing():
    assert compute.engine_missing("pybullet") is None
    assert compute.engine_missing("mujoco") is None
    assert "must be one of" in compute.engine_missing("ode")


def _physics_row(robot, engine, us):
    return {
        "robot": robot,
        "engine": engine,
        "joints": 7,
        "steps": 100,
        "repeats": 1,
        "us_per_step": us,
        "us_per_step_repeats": [us],
        "per_step": {"p50_us": us, "p99_us": 2 * us, "max_us": 3 * us, "samples": 100},
    }


def test_physics_ratio_is_mujoco_over_pybullet():
    rows = [
        _physics_row("iiwa", "pybullet", 8.0),
        _physics_row("iiwa", "mujoco", 6.0),
        _physics_row("panda", "mujoco", 6.5),  # no PyBullet row: no ratio
    ]
    assert physics_ratios(rows) == [{"robot": "iiwa", "mujoco_over_pybullet": 0.75}]


def _loops(values, engine):
    return [
        {
            "robot": "iiwa",
            "law": "inverse_dynamics",
            "engine": engine,
            "steps_per_s": v,
            "round": k,
        }
        for k, v in enumerate(values)
    ]


def test_engines_ratio_is_the_median_of_ratios_of_the_same_round():
    # the machine slows down by 2× in round 1: the paired ratios stay 0.9
    bullet, mujoco = _loops([1000, 500, 1000], "pybullet"), _loops([900, 450, 900], "mujoco")
    result = {
        "lockstep": [median_row(bullet, "steps_per_s")],
        "lockstep_mujoco": [median_row(mujoco, "steps_per_s")],
        "rounds": {"lockstep": bullet, "lockstep_mujoco": mujoco},
    }
    (ratio,) = ratios(result)
    assert [round(x, 12) for x in ratio["mujoco_over_pybullet_rounds"]] == [0.9, 0.9, 0.9]
    assert ratio["mujoco_over_pybullet"] == pytest.approx(0.9)


def test_engines_ratio_of_one_round_is_the_quotient_and_nan_without_mujoco():
    bullet, mujoco = _loops([1200.0], "pybullet"), _loops([1000.0], "mujoco")
    result = {
        "lockstep": [median_row(bullet, "steps_per_s")],
        "lockstep_mujoco": [median_row(mujoco, "steps_per_s")],
        "rounds": {"lockstep": bullet, "lockstep_mujoco": mujoco},
    }
    assert ratios(result)[0]["mujoco_over_pybullet"] == 1000.0 / 1200.0
    alone = {"lockstep": result["lockstep"], "rounds": {"lockstep": bullet}}
    (ratio,) = ratios(alone)
    assert math.isnan(ratio["mujoco_over_pybullet"]) and ratio["mujoco_over_pybullet_rounds"] == []


def _result():
    """A bench result with the physics section and the lockstep loop on both engines."""
    physics = [
        _physics_row(robot, engine, us)
        for robot, per_engine in (("iiwa", (8.0, 6.0)), ("ur5", (10.0, 5.0)))
        for engine, us in zip(ENGINES, per_engine, strict=True)
    ]
    loops = {
        key: [
            {
                "robot": robot,
                "law": law,
                "engine": engine,
                "steps_per_s": rate,
                "sim_step_p50_us": 40.0 if engine == "pybullet" else 30.0,
                "round": 0,
            }
            for robot in ROBOTS
            for law in LAWS
        ]
        for key, engine, rate in (
            ("lockstep", "pybullet", 1600.0),
            ("lockstep_mujoco", "mujoco", 1700.0),
        )
    }
    result = {
        "started": "2026-12-06T00:00:00+00:00",
        "machine": {"cpu": "test", "cores": 2, "load_average_1_5_15": [0, 0, 0]},
        "versions": {},
        "physics": {"rows": physics, "skipped": ["ur10: not here"]},
        **{key: [median_row([r], "steps_per_s") for r in rows] for key, rows in loops.items()},
        "rounds": loops,
    }
    result["physics"]["ratios"] = physics_ratios(physics)
    result["ratios"] = ratios(result)
    return result


def test_table_lines_of_both_engines():
    lines = format_table(_result()).splitlines()
    top = lines.index(next(line for line in lines if line.startswith("physics step")))
    assert "the median of 1 rounds' mean of 100 steps" in lines[top]
    assert lines[top + 2].split() == ["iiwa", "7", "8.0", "6.0", "0.75", "8.0", "/", "6.0"]
    assert lines[top + 3].split() == ["ur5", "7", "10.0", "5.0", "0.50", "10.0", "/", "5.0"]
    assert lines[top + 4] == "  left out: ur10: not here"

    start = lines.index(next(line for line in lines if "engine:=mujoco against" in line))
    rows = [line.split() for line in lines[start + 2 : start + 2 + len(ROBOTS) * len(LAWS)]]
    assert [row[:2] for row in rows] == [[robot, law] for robot in ROBOTS for law in LAWS]
    ratio = f"{1700 / 1600:.2f}"
    assert all(row[2:] == ["1,600", "1,700", ratio, "40", "/", "30", ratio] for row in rows)


def test_table_says_which_loop_was_left_out():
    result = {**_result(), "skipped": {"lockstep_mujoco": "engine 'mujoco': not installed"}}
    del result["lockstep_mujoco"]
    text = format_table(result)
    assert "engine:=mujoco against" not in text
    assert "  lockstep_mujoco left out: engine 'mujoco': not installed" in text
