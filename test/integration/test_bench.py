"""``jsc bench --quick`` end to end: every section in the JSON, every process stopped. The
values are timings of a shared machine and are not checked, only that they are there."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import pytest

from joint_space_control.lab.bench.compute import PHYSICS_ROBOTS
from joint_space_control.lab.bench.run import ENGINES, ROBOTS, SECTIONS
from joint_space_control.lab.bench.watched import goals as watched_goals

# realtime: run alone after the parallel part, since its CPU hogs would load the machine
# under another worker's test
# Each a whole bench of a minute or more: make test-long (the sections' maths: test/unit).
pytestmark = [pytest.mark.integration, pytest.mark.realtime, pytest.mark.long]

LAWS = ("pd_gravity", "inverse_dynamics")


#: Sections with a test of their own below (they start a browser: minutes, not seconds).
APART = ("dashboard",)


def _bench(out, *args, timeout=240):
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    return subprocess.run(
        [sys.executable, "-m", "joint_space_control.cli.main", "bench", "--quick", "--out", out]
        + list(args),
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


def test_quick_bench_writes_every_section(tmp_path):
    out = tmp_path / "bench"
    sections = [s for s in SECTIONS if s not in APART]
    result = _bench(out, "--sections", ",".join(sections))
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "goals:" in result.stdout and (out / "bench.txt").read_text() in result.stdout

    data = json.loads((out / "bench.json").read_text())
    derived = {"machine", "versions", "ratios", "goals", "realtime_floor", "cpu_steal_fraction"}
    assert set(sections) | derived <= set(data)
    assert data["machine"]["cpu"] and data["machine"]["cores"] >= 1
    for package in ("python", "rclpy", "pinocchio", "pybullet", "numpy"):
        assert data["versions"][package], package

    pairs = {(robot, law) for robot in ROBOTS for law in LAWS}
    assert {(r["robot"], r["law"]) for r in data["compute"]} == pairs
    for row in data["compute"]:
        for part in ("law_per_tick", "pinocchio_per_tick"):
            assert {"p50_us", "p99_us", "max_us", "samples"} <= set(row[part])
    assert {(r["robot"], r["law"]) for r in data["in_process"]} == pairs
    # the physics step of every robot on both engines (example-robot-data is a test extra)
    physics = data["physics"]
    assert physics["skipped"] == []
    assert {(r["robot"], r["engine"]) for r in physics["rows"]} == {
        (robot, engine) for robot in PHYSICS_ROBOTS for engine in ENGINES
    }
    us = {(r["robot"], r["engine"]): r["us_per_step"] for r in physics["rows"]}
    assert all(math.isfinite(v) and v > 0 for v in us.values())
    assert {r["robot"]: r["mujoco_over_pybullet"] for r in physics["ratios"]} == pytest.approx(
        {robot: us[robot, "mujoco"] / us[robot, "pybullet"] for robot in PHYSICS_ROBOTS}
    )
    assert "physics step in process" in result.stdout
    assert {r["robot"] for r in data["pingpong"]} == set(ROBOTS)
    assert all(r["round_trips_per_s"] > 0 for r in data["pingpong"])
    assert {(r["robot"], r["law"]) for r in data["lockstep"]} == pairs
    for row in data["lockstep"]:
        assert row["steps"] > 0 and row["steps_per_s"] > 0
        assert {"p50_us", "p99_us", "max_us"} <= set(row["callback"]) & set(row["latency"])
    # the same loop as users run it: use_sim_time and a recorder, whose bag holds the run
    assert {(r["robot"], r["law"]) for r in data["lockstep_as_used"]} == pairs
    assert all(r["steps"] > 0 and r["steps_per_s"] > 0 for r in data["lockstep_as_used"])
    bags = list((out / "runs").glob("lockstep_as_used_*/bag_*/metadata.yaml"))
    assert len(bags) == len(pairs), bags
    assert {(r["robot"], r["law"]) for r in data["ratios"]} == pairs
    assert all(r["as_used_over_pingpong"] > 0 for r in data["ratios"])
    # the bench's loop again with sim_bridge engine:=mujoco, in the same round (one: --quick)
    assert {(r["robot"], r["law"], r["engine"]) for r in data["lockstep"]} == {
        (robot, law, "pybullet") for robot, law in pairs
    }
    assert {(r["robot"], r["law"], r["engine"]) for r in data["lockstep_mujoco"]} == {
        (robot, law, "mujoco") for robot, law in pairs
    }
    assert all(r["steps"] > 0 and r["steps_per_s"] > 0 for r in data["lockstep_mujoco"])
    for ratio in data["ratios"]:
        on = {
            key: next(
                r["steps_per_s"]
                for r in data[key]
                if (r["robot"], r["law"]) == (ratio["robot"], ratio["law"])
            )
            for key in ("lockstep", "lockstep_mujoco")
        }
        assert ratio["mujoco_over_pybullet"] == pytest.approx(
            on["lockstep_mujoco"] / on["lockstep"]
        )
    assert "engine:=mujoco against engine:=pybullet" in result.stdout
    assert "as users run it" in result.stdout
    cases = {(r["load"], r["thread_priority"]) for r in data["realtime"]}
    assert cases == {("quiet", 0), ("quiet", 50), ("hog", 0), ("hog", 50)}
    for realtime in data["realtime"]:
        for key in ("rate_hz", "on_time_fraction", "late_fraction", "too_late_fraction"):
            assert realtime[key] is not None, key
        for part in ("jitter", "latency", "lateness"):
            assert {"p50_us", "p99_us", "max_us"} <= set(realtime[part]), part
        # what the threads ran with, as the plant reported it
        fifo = data["fifo_permitted"] and realtime["thread_priority"] > 0
        assert realtime["policy"] == ("SCHED_FIFO" if fifo else "SCHED_OTHER")
        assert realtime["brakes"] >= 0
    assert {(f["load"], f["thread_priority"]) for f in data["realtime_floor"]} == cases
    for floor in data["realtime_floor"]:
        assert {"lateness", "on_time_fraction", "policy"} <= set(floor)
    assert data["analyze"]["messages"] > 0 and data["analyze"]["seconds_per_million_messages"]
    assert {r["engine"] for r in data["simulate"]} == {"pybullet", "mujoco"}
    for row in data["simulate"]:  # simulate() of 1 s: its parts add up to the whole
        assert row["total_ms"] > 0 and row["loop_ms"] > 0 and row["runs_per_minute"] > 0
        parts = row["build_ms"] + row["loop_ms"] + row["response_ms"]
        assert parts == pytest.approx(row["total_ms"], rel=0.5)
    assert len(data["goals"]) == 17
    # the dashboard's section has a test of its own; --quick skips the sweep and the loop
    # watched (minutes: measured by `jsc bench --sections watched`)
    watched = {name for name, _value, _met in watched_goals(None)}
    assert data["watched"] == {"skipped": "--quick: run `jsc bench --sections watched`"}
    apart = [
        g
        for g in data["goals"]
        if g["goal"].startswith(("dashboard", "sweep")) or g["goal"] in watched
    ]
    assert len(apart) == 7 and all(g["met"] is None for g in apart)
    under_hog = [g for g in data["goals"] if "CPU hog" in g["goal"] and g not in apart]
    assert all(g["met"] is not None for g in data["goals"] if g not in under_hog + apart)
    # measured exactly when the prioritised case ran at SCHED_FIFO
    assert all((g["met"] is not None) == data["fifo_permitted"] for g in under_hog)

    # every process the bench started is gone
    ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert str(out) not in ps  # node processes (their parameter files are under out/)
    assert "parent = int(sys.argv[1])" not in ps  # the CPU hogs


def test_quick_dashboard_section_pairs_the_loop_without_and_with_the_page(tmp_path):
    out = tmp_path / "bench"
    result = _bench(out, "--sections", "dashboard", timeout=400)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "dashboard beside the loop" in result.stdout

    data = json.loads((out / "bench.json").read_text())
    section = data["dashboard"]
    page = section["page"]
    assert page == (section["page_missing"] is None)
    assert section["pairs"] == 1
    runs = section["runs"]
    assert [(r["kind"], r["dashboard"]) for r in runs] == [
        ("lockstep", False),
        ("lockstep", True),
        ("realtime", False),
        ("realtime", True),
    ]
    # with a page: plotting before the measurement, or why not (a realtime loop that left
    # the browser no CPU on a slow machine: reported, and its page goal not met)
    for r in runs:
        assert (r["plotting"] is None) == (not (r["dashboard"] and page)), r
        assert (r["plotting"] is False) == bool(r["not_plotting"]), r
    starved = [kind for kind, _, _ in section["not_plotting"]]
    assert "lockstep" not in starved  # lockstep waits for its controller: the page plots
    if starved:
        assert "NOT PLOTTING: realtime pair 1: the page at" in result.stdout
        realtime_goal = [g for g in data["goals"] if "realtime on-time" in g["goal"]]
        assert [g["met"] for g in realtime_goal] == [False]
    ls, rt = section["lockstep"], section["realtime"]
    assert (ls["robot"], ls["law"], ls["use_sim_time"]) == ("planar_2dof", "pd_gravity", True)
    assert ls["without_steps_per_s"] > 0 and ls["with_steps_per_s"] > 0
    assert ls["ratio"] == pytest.approx(ls["with_steps_per_s"] / ls["without_steps_per_s"])
    for key in ("without_on_time_fraction", "with_on_time_fraction"):
        assert 0.0 <= rt[key] <= 1.0, key
    assert rt["drop_points"] == pytest.approx(
        100 * (rt["without_on_time_fraction"] - rt["with_on_time_fraction"])
    )
    # the CPU of every process over each measurement: the loop's two, and beside it the
    # dashboard and (with a page) Chromium and playwright
    for kind, loop in (("lockstep", "pd_gravity_controller"), ("realtime", "inverse_dynamics")):
        without, with_ = (section["cpu_seconds"][kind][k] for k in ("without", "with"))
        assert without["wall_s"] > 0 and with_["wall_s"] > 0
        assert "dashboard_s" not in without and "chromium_s" not in without
        assert with_["dashboard_s"] > 0
        assert ("chromium_s" in with_) == page and ("playwright_s" in with_) == page
        assert any(k.startswith(loop) for k in with_) and "sim_bridge_s" in with_
    goals = [g for g in data["goals"] if g["goal"].startswith("dashboard")]
    assert len(goals) == 2 and all((g["met"] is not None) == page for g in goals)

    ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert str(out) not in ps  # node processes (their parameter files are under out/)
    assert "joint_space_control.lab.bench.browser" not in ps  # the page's process
