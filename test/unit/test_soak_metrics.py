"""Soak figures and verdict (no ROS): VmRSS parsing, the least-squares growth slope, the
command audit against the effort limits, the update tally and the pass/fail criteria."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.lab.soaks.soak_metrics import (
    MB,
    STEP_MB,
    STEP_WINDOW_S,
    CommandAudit,
    Thresholds,
    UpdateTally,
    cores_used,
    format_cpu,
    largest_step,
    median_slope_per_minute,
    memory_summary,
    move_targets,
    numeric_values,
    parse_cpu_seconds,
    parse_rss_parts,
    parse_system_cpu,
    parse_vmrss,
    passed,
    plateaus,
    slope_per_minute,
    steady_slope_per_minute,
    verdict,
)

STATUS = """Name:\tpython
VmPeak:\t  400000 kB
VmHWM:\t  180000 kB
VmRSS:\t  171712 kB
RssAnon:\t   90000 kB
RssFile:\t   80000 kB
RssShmem:\t    1712 kB
"""


def test_vmrss_in_bytes():
    assert parse_vmrss(STATUS) == 171712 * 1024
    assert parse_vmrss("Name:\tzombie\nState:\tZ (zombie)\n") is None


def test_the_parts_of_the_resident_memory_in_bytes():
    parts = parse_rss_parts(STATUS)
    assert parts == {"RssAnon": 90000 * 1024, "RssFile": 80000 * 1024, "RssShmem": 1712 * 1024}
    assert sum(parts.values()) == parse_vmrss(STATUS)
    assert parse_rss_parts("Name:\tzombie\n") == {}


def test_slope_of_a_line_is_exact_per_minute():
    t = np.arange(0.0, 600.0, 2.0)
    y = 150.0 + 0.25 * t / 60.0  # 0.25 MB/min
    assert slope_per_minute(t, y) == pytest.approx(0.25, rel=1e-12)
    assert slope_per_minute(t, np.full_like(t, 7.0)) == 0.0


def test_slope_is_the_least_squares_one():
    t = np.array([0.0, 60.0, 120.0, 180.0])
    y = np.array([1.0, 3.0, 2.0, 5.0])
    assert slope_per_minute(t, y) == pytest.approx(np.polyfit(t / 60.0, y, 1)[0], rel=1e-12)


def test_slope_needs_two_distinct_times():
    assert math.isnan(slope_per_minute([], []))
    assert math.isnan(slope_per_minute([3.0], [1.0]))
    assert math.isnan(slope_per_minute([3.0, 3.0], [1.0, 2.0]))


def test_memory_summary_leaves_the_warm_up_out_of_the_fit():
    t = np.arange(0.0, 300.0, 2.0)
    rss = np.where(t < 10.0, 100e6 + t * 2e6, 120e6)  # grows during warm-up, then flat
    rss[-1] += 0.5e6  # one last allocator step
    m = memory_summary(t, rss, warmup_s=10.0)
    assert m["samples"] == t.size and m["samples_after_warmup"] == np.sum(t >= 10.0)
    assert m["first_mb"] == 100.0 and m["start_mb"] == 120.0 and m["end_mb"] == 120.5
    assert m["max_mb"] == 120.5 and m["growth_mb"] == pytest.approx(0.5)
    assert m["span_min"] == pytest.approx((298.0 - 10.0) / 60.0)
    assert 0.0 < m["slope_mb_per_min"] < 0.01
    leak = memory_summary(t, 100e6 + t / 60.0 * 2 * MB, warmup_s=10.0)
    assert leak["slope_mb_per_min"] == pytest.approx(2.0)


def test_memory_summary_without_samples_after_warm_up():
    m = memory_summary([0.0, 1.0], [1e6, 2e6], warmup_s=10.0)
    assert math.isnan(m["start_mb"]) and math.isnan(m["slope_mb_per_min"])
    assert m["span_min"] == 0.0 and m["max_mb"] == 2.0


def test_move_targets_are_inside_the_limits_and_distinct():
    lower = np.array([-2.96, -2.09, -np.inf, 0.0])
    upper = np.array([2.96, 2.09, np.inf, 1.0])
    a, b = move_targets(lower, upper)
    for target in (a, b):
        assert np.all(target > lower) and np.all(target < upper)
    np.testing.assert_allclose(a, [0.888, -0.627, 0.5, 0.35])
    np.testing.assert_allclose(b, [-0.888, 0.627, -0.5, 0.65])


def test_command_audit_checks_limits_by_name():
    audit = CommandAudit(("a", "b"), np.array([10.0, 2.0]))
    assert audit.check(("a", "b"), np.array([10.0, -2.0]))  # on the limit is fine
    assert audit.check(("b", "a"), np.array([-2.0, 9.0]))  # any order, by name
    assert not audit.check(("b", "a"), np.array([3.0, 0.0]))  # b beyond 2 N·m
    assert not audit.check(("a", "b"), np.array([np.nan, 0.0]))
    assert not audit.check(("a", "b"), np.array([0.0, np.inf]))
    assert not audit.check(("a", "c"), np.array([0.0, 0.0]))  # unknown joint
    assert not audit.check(("a",), np.array([0.0, 0.0]))  # sizes differ
    f = audit.figures()
    assert f["commands"] == 7 and f["violations"] == 5
    assert (f["over_limit"], f["non_finite"], f["unknown_joints"]) == (1, 2, 2)
    assert f["max_effort_over_limit"] == pytest.approx(1.5)
    assert len(f["examples"]) == 5


def test_update_tally():
    tally = UpdateTally()
    tally.valid(True)
    tally.valid(False)
    tally.invalid(True, "kp must be > 0", kept=True)
    tally.invalid(True, "kp must be > 0", kept=False)
    tally.invalid(False, "", kept=True)
    f = tally.figures()
    assert (f["valid_sent"], f["valid_accepted"]) == (2, 1)
    assert (f["invalid_sent"], f["invalid_rejected"]) == (3, 2)
    assert f["old_values_kept_after_reject"] == 1
    assert f["reject_reasons"] == ["kp must be > 0"]


def test_numeric_values_keep_every_number_and_only_numbers():
    status = {"level": 0, "message": "ok", "hardware_id": "iiwa", "ticks": 1000.0}
    status |= {"rejected.new_counter": 3.0, "trigger": "state", "flag": True, "x": math.nan}
    values = numeric_values(status)
    assert set(values) == {"level", "ticks", "rejected.new_counter", "x"}
    assert values["rejected.new_counter"] == 3.0


def _report(**changes):
    mem = {"slope_mb_per_min": 0.1, "span_min": 9.8, "node": True}
    report = {
        "memory": {
            "sim_bridge": dict(mem),
            "controller": dict(mem),
            "observer": {**mem, "slope_mb_per_min": 50.0, "node": False},
        },
        "commands": {"commands": 1000, "violations": 0},
        "controller_ticks": 1000.0,
        "parameter_updates": {
            "valid_sent": 600,
            "valid_accepted": 600,
            "invalid_sent": 60,
            "invalid_rejected": 60,
            "old_values_kept_after_reject": 60,
        },
        "diagnostics_received": {"sim_bridge": 600, "controller": 600},
    }
    for key, value in changes.items():
        path = key.split("__")
        target = report
        for part in path[:-1]:
            target = target[part]
        target[path[-1]] = value
    return report


def test_a_clean_run_passes_and_the_observer_is_not_judged():
    criteria = verdict(_report())
    assert passed(criteria) and all(c.met is True for c in criteria)
    assert not any("observer" in c.name for c in criteria)


@pytest.mark.parametrize(
    "change",
    [
        {"memory__controller__slope_mb_per_min": 1.5},
        {"commands__violations": 1},
        {"commands__commands": 0},
        {"controller_ticks": 1001.0},
        {"parameter_updates__valid_accepted": 599},
        {"parameter_updates__invalid_rejected": 59},
        {"parameter_updates__old_values_kept_after_reject": 59},
        {"parameter_updates__invalid_sent": 0},
        {"diagnostics_received__sim_bridge": 0},
    ],
)
def test_each_failure_fails_the_run(change):
    criteria = verdict(_report(**change))
    assert not passed(criteria)
    assert any(c.met is False for c in criteria)


def test_memory_of_a_short_run_is_reported_but_not_judged():
    report = _report(memory__sim_bridge__span_min=0.3, memory__sim_bridge__slope_mb_per_min=5.0)
    criteria = verdict(report)
    (mem,) = [c for c in criteria if c.name == "memory growth of sim_bridge"]
    assert mem.met is None and "not judged" in mem.detail
    assert passed(criteria)


def test_thresholds_are_parameters():
    report = _report(memory__controller__slope_mb_per_min=0.5)
    assert passed(verdict(report))
    assert not passed(verdict(report, Thresholds(max_slope_mb_per_min=0.4)))


def test_the_median_slope_ignores_one_step_but_not_steady_or_recurring_growth():
    """Theil–Sen (the fault soak's memory criterion): a process that grows 40 MB once, at a
    fault (an allocator's high-water mark), is flat; one that grows 40 MB/h steadily, or
    by 10 MB at every one of six faults, grows."""
    t = np.arange(0.0, 3600.0, 2.0)
    step = 200.0 + 40.0 * (t > 1700.0)
    steady = 200.0 + 40.0 * t / 3600.0
    stairs = 200.0 + 10.0 * np.floor(t / 600.0)
    assert median_slope_per_minute(t, step) == 0.0
    assert slope_per_minute(t, step) * 60.0 > 50.0  # least squares counts the step
    assert median_slope_per_minute(t, steady) * 60.0 == pytest.approx(40.0, rel=1e-9)
    assert median_slope_per_minute(t, stairs) * 60.0 > 30.0
    assert largest_step(t, step) == (40.0, 1702.0)
    summary = memory_summary(t, step * MB, warmup_s=60.0)
    assert summary["median_slope_mb_per_min"] == 0.0 and summary["largest_step_mb"] == 40.0


def test_the_slope_between_steps():
    """Steps of at least STEP_MB split the series into plateaus; the slope is taken within
    them: steady growth under three steps gives its rate, three steps alone 0."""
    t = np.arange(0.0, 1800.0, 2.0)
    w = STEP_WINDOW_S
    stairs = 24.0 * np.searchsorted([300.0, 900.0, 1500.0], t, side="right")
    assert list(np.unique(plateaus(t, stairs, STEP_MB, w))) == [0, 1, 2, 3]
    assert steady_slope_per_minute(t, 200.0 + stairs, STEP_MB, w) == 0.0
    rising = 200.0 + stairs + 20.0 * t / 3600.0
    assert steady_slope_per_minute(t, rising, STEP_MB, w) * 60.0 == pytest.approx(20.0, rel=1e-9)
    assert math.isnan(steady_slope_per_minute([0.0, 2.0], [0.0, 10.0], STEP_MB, w))  # no pair
    summary = memory_summary(t, rising * MB, warmup_s=0.0)
    # each step's rise holds the steady growth of a window before it and after (20 MB/h)
    assert summary["steps"] == 3
    assert 72.0 < summary["steps_mb"] < 72.0 + 3 * 20.0 * (2 * w + 2.0) / 3600.0
    assert summary["steady_slope_mb_per_min"] * 60.0 == pytest.approx(20.0, rel=1e-9)


def test_a_step_taken_over_seconds_is_a_step_and_slow_growth_is_not():
    """A high-water mark taken over seconds in rises below STEP_MB each (seen: sim_bridge
    +5.5 MB over 18 s, 0.3-0.7 MB a sample, after a recorder was killed, in a 250 Hz soak)
    is one step, not growth; growth slower than STEP_MB per STEP_WINDOW_S is growth,
    however it comes (0.5 MB every 20 s, 90 MB/h); growth so fast that every window holds a
    step is all steps here (and judged over the run: fault_metrics.run_growth)."""
    t = np.arange(0.0, 720.0, 2.0)
    ramp = 138.0 + np.interp(t, [424.0, 442.0], [0.0, 5.5])
    summary = memory_summary(t, ramp * MB, warmup_s=60.0)
    assert summary["steps"] == 1 and summary["steps_mb"] == pytest.approx(5.5, abs=1e-9)
    assert summary["largest_step_mb"] < STEP_MB  # no single interval is a step
    assert summary["steady_slope_mb_per_min"] == 0.0
    # judged per interval, as before: the ramp read as +34 MB/h
    assert median_slope_per_minute(t[t >= 60.0], ramp[t >= 60.0]) * 60.0 > 30.0
    # growth in pieces below a step: 0.5 MB every 20 s, at most 1 MB a window
    pieces = 200.0 + 0.5 * np.floor(t / 20.0)
    assert plateaus(t, pieces, STEP_MB, STEP_WINDOW_S).max() == 0
    slope = steady_slope_per_minute(t, pieces, STEP_MB, STEP_WINDOW_S) * 60.0
    assert slope == pytest.approx(90.0, rel=0.05)
    # the limit's growth, 30 MB/h in 4 kB pages, is growth: 0.25 MB a window
    pages = 200.0 + np.floor(30.0 * t / 3600.0 / 0.004096) * 0.004096
    assert memory_summary(t, pages * MB, warmup_s=0.0)["steps"] == 0
    assert steady_slope_per_minute(t, pages, STEP_MB, STEP_WINDOW_S) * 60.0 > 29.0
    # 450 MB/h (0.25 MB a sample): every window holds a step
    fast = 200.0 + 0.25 * np.arange(t.size)
    assert plateaus(t, fast, STEP_MB, STEP_WINDOW_S).max() == t.size - 1
    assert math.isnan(steady_slope_per_minute(t, fast, STEP_MB, STEP_WINDOW_S))


def test_cpu_seconds_are_user_plus_system_after_a_command_name_with_spaces_and_parentheses():
    # fields 14 (utime) and 15 (stime) of proc(5); the name would shift a naive split
    stat = "4242 (sim (bridge) x) S 1 4242 4242 0 -1 4194560 900 0 0 0 1234 567 0 0 -51 0 9"
    assert parse_cpu_seconds(stat, 100.0) == pytest.approx(18.01)


def test_system_cpu_splits_busy_idle_and_steal():
    stat = "cpu  100 5 50 1000 20 3 2 40 0 0\ncpu0 50 2 25 500 10 1 1 20 0 0\nintr 1\n"
    cpu = parse_system_cpu(stat, 100.0)
    assert cpu == pytest.approx({"busy": 1.60, "idle": 10.20, "steal": 0.40})


def test_cores_used_is_the_mean_and_the_busiest_minute():
    # a process at a quarter of a core for 2 minutes, then a whole core for 1 minute
    t = np.arange(0.0, 181.0, 2.0)
    cpu = np.where(t <= 120, 0.25 * t, 30.0 + (t - 120))
    mean, peak = cores_used(t, cpu)
    assert mean == pytest.approx(90.0 / 180.0)
    assert peak == pytest.approx(1.0)
    assert all(math.isnan(x) for x in cores_used([0.0], [1.0]))
    # shorter than the window: the busiest minute is the mean
    assert cores_used([0.0, 10.0], [0.0, 5.0]) == pytest.approx((0.5, 0.5))


def test_format_cpu_names_each_process_and_leaves_out_one_sample():
    text = format_cpu({"sim_bridge.0": ([0.0, 60.0], [0.0, 24.0]), "dashboard.1": ([5.0], [1.0])})
    assert "sim_bridge.0" in text and " 0.40  0.40" in text
    assert "dashboard.1" not in text
