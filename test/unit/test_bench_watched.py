"""The bench's ``watched`` section from its runs (no ROS, no browser): the goals judge the
nodes' default middleware scheduling on its worst run, and say when nothing was measured."""

from __future__ import annotations

from joint_space_control.lab.bench.watched import format_watched, goals


def section(page_default, hogs_default, page_missing=None):
    def row(on_time, brakes):
        return {
            "runs": 3,
            "worst_on_time_fraction": on_time,
            "median_on_time_fraction": on_time,
            "brakes": brakes,
        }

    summary = {"hogs": {"normal": row(0.990, 2), "default": row(*hogs_default)}}
    if page_default is not None:
        summary["page"] = {"normal": row(0.995, 1), "default": row(*page_default)}
    return {
        "robot": "iiwa",
        "law": "inverse_dynamics",
        "seconds": 20.0,
        "hogs": 3,
        "page_missing": page_missing,
        "summary": summary,
        "runs": [{"pair": 0, "page_connected": False, "page_not_connected": "timed out"}],
    }


def met(rows):
    return [None if value is None else ok(value) for _name, value, ok in rows]


def test_the_goals_are_judged_on_the_default_middleware_scheduling():
    assert met(goals(section((0.9985, 0), (0.9990, 0)))) == [True, True, True, True]
    assert met(goals(section((0.9975, 1), (0.9990, 0)))) == [False, False, True, True]
    assert met(goals(section((0.9985, 0), (0.9979, 2)))) == [True, True, False, False]


def test_nothing_measured_is_no_goal_met_or_missed():
    assert met(goals(None)) == [None] * 4
    assert met(goals({"skipped": "--quick"})) == [None] * 4
    assert met(goals(section(None, (0.999, 0), "no chromium"))) == [None, None, True, True]


def test_the_table_names_both_settings_and_a_page_that_did_not_connect():
    lines = format_watched(section((0.9985, 0), (0.9990, 0)))
    assert any("Chromium started on the page" in line and "99.50 %" in line for line in lines)
    assert any("3 CPU hogs" in line and "99.90 %" in line for line in lines)
    assert any("PAGE NOT CONNECTED: pair 1: timed out" in line for line in lines)
    assert format_watched({"skipped": "--quick"})[0] == "watched: skipped (--quick)"
