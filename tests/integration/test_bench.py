"""``jsc bench --quick`` end to end: every section in the JSON, every process stopped. The
values are timings of a shared machine and are not checked, only that they are there."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from joint_space_control.bench.run import ROBOTS, SECTIONS

# realtime: run alone after the parallel part, since its CPU hogs would load the machine
# under another worker's test
pytestmark = [pytest.mark.integration, pytest.mark.realtime]

LAWS = ("pd_gravity", "inverse_dynamics")


def test_quick_bench_writes_every_section(tmp_path):
    out = tmp_path / "bench"
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    result = subprocess.run(
        [sys.executable, "-m", "joint_space_control.cli.main", "bench", "--quick", "--out", out],
        capture_output=True,
        text=True,
        timeout=240,
        env=env,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "goals:" in result.stdout and (out / "bench.txt").read_text() in result.stdout

    data = json.loads((out / "bench.json").read_text())
    derived = {"machine", "versions", "ratios", "goals", "realtime_floor", "cpu_steal_fraction"}
    assert set(SECTIONS) | derived <= set(data)
    assert data["machine"]["cpu"] and data["machine"]["cores"] >= 1
    for package in ("python", "rclpy", "pinocchio", "pybullet", "numpy"):
        assert data["versions"][package], package

    pairs = {(robot, law) for robot in ROBOTS for law in LAWS}
    assert {(r["robot"], r["law"]) for r in data["compute"]} == pairs
    for row in data["compute"]:
        for part in ("law_per_tick", "pinocchio_per_tick"):
            assert {"p50_us", "p99_us", "max_us", "samples"} <= set(row[part])
    assert {(r["robot"], r["law"]) for r in data["in_process"]} == pairs
    assert {r["robot"] for r in data["pingpong"]} == set(ROBOTS)
    assert all(r["round_trips_per_s"] > 0 for r in data["pingpong"])
    assert {(r["robot"], r["law"]) for r in data["lockstep"]} == pairs
    for row in data["lockstep"]:
        assert row["steps"] > 0 and row["steps_per_s"] > 0
        assert {"p50_us", "p99_us", "max_us"} <= set(row["callback"]) & set(row["latency"])
    assert {(r["robot"], r["law"]) for r in data["ratios"]} == pairs
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
    assert len(data["goals"]) == 8
    under_hog = [g for g in data["goals"] if "CPU hog" in g["goal"]]
    assert all(g["met"] is not None for g in data["goals"] if g not in under_hog)
    # measured exactly when the prioritised case ran at SCHED_FIFO
    assert all((g["met"] is not None) == data["fifo_permitted"] for g in under_hog)

    # every process the bench started is gone
    ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert str(out) not in ps  # node processes (their parameter files are under out/)
    assert "parent = int(sys.argv[1])" not in ps  # the CPU hogs
