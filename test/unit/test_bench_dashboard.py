"""The bench's dashboard section from its runs (no ROS, no browser): a page that did not
show its plots beside the loop is reported, and the page goal of that loop is not met."""

from __future__ import annotations

import pytest

from joint_space_control.lab.bench.dashboard import format_dashboard, goals, summarise


def _runs(realtime_plotting: bool) -> list[dict]:
    runs = []
    for kind in ("lockstep", "realtime"):
        for beside in (False, True):
            plotting = None if not beside else (realtime_plotting or kind == "lockstep")
            runs.append(
                {
                    "kind": kind,
                    "pair": 0,
                    "dashboard": beside,
                    "page": True,
                    "plotting": plotting,
                    "not_plotting": "" if plotting is not False else "shows no plots: Timeout",
                    "steps_per_s": 1000.0 if not beside else 990.0,
                    "on_time_fraction": 0.999 if not beside else 0.9985,
                    "wall_s": 1.0,
                    "cpu_seconds": {"sim_bridge": 0.5},
                }
            )
    return runs


def _met(section: dict) -> list[bool]:
    return [met(value) for _, value, met in goals(section)]


def test_both_goals_are_judged_when_the_page_plotted_beside_both_loops():
    section = summarise(_runs(True), True, None, "iiwa", "inverse_dynamics")
    assert section["not_plotting"] == []
    assert section["realtime"]["drop_points"] == pytest.approx(0.05)
    assert _met(section) == [True, True]
    assert not any("NOT PLOTTING" in line for line in format_dashboard(section))


def test_a_page_starved_by_the_realtime_loop_is_named_and_its_goal_not_met():
    section = summarise(_runs(False), True, None, "iiwa", "inverse_dynamics")
    assert section["not_plotting"] == [("realtime", 0, "shows no plots: Timeout")]
    # the drop alone would meet the goal: the page did nothing, so it is not met
    assert section["realtime"]["drop_points"] == pytest.approx(0.05)
    assert _met(section) == [True, False]
    lines = format_dashboard(section)
    assert "  NOT PLOTTING: realtime pair 1: shows no plots: Timeout" in lines


def test_no_page_no_goal_measured():
    section = summarise(_runs(True), False, "chromium is not installed", "iiwa", "x")
    assert [value for _, value, _ in goals(section)] == [None, None]
