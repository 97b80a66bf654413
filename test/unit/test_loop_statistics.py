"""Loop statistics on synthetic timings: exact values, window and total."""

from __future__ import annotations

import math

import numpy as np
import pytest

from joint_space_control.ros.loop_statistics import (
    LoopStatistics,
    nearest_rank,
    summary_keys,
)

US = 1000  # ns


def feed(
    stats: LoopStatistics,
    starts_us,
    computes_us,
    latencies_us=None,
    lateness_us=None,
    nominal_us=1000,
):
    for k, (s, c) in enumerate(zip(starts_us, computes_us, strict=True)):
        stats.tick(
            int(s * US),
            int((s + c) * US),
            -1 if latencies_us is None else int(latencies_us[k] * US),
            -1 if lateness_us is None else int(lateness_us[k] * US),
            -1 if nominal_us is None else int(nominal_us * US),
        )


def test_nearest_rank_is_the_textbook_definition():
    x = np.array([15.0, 20, 35, 40, 50])
    assert nearest_rank(x, 5) == 15  # rank ceil(0.25) = 1
    assert nearest_rank(x, 30) == 20  # rank ceil(1.5) = 2
    assert nearest_rank(x, 40) == 20  # rank 2
    assert nearest_rank(x, 50) == 35  # rank ceil(2.5) = 3
    assert nearest_rank(x, 100) == 50
    assert math.isnan(nearest_rank(np.array([]), 50))
    rng = np.random.default_rng(1)
    y = rng.normal(size=1001)
    for p in (1, 50, 99, 99.9):
        rank = math.ceil(p / 100 * y.size)
        assert nearest_rank(y, p) == np.sort(y)[rank - 1]


def test_one_window_exact_values():
    stats = LoopStatistics()
    # 101 ticks: periods alternate 900 and 1100 µs around the 1000 µs nominal
    starts = np.cumsum([0] + [900 if k % 2 else 1100 for k in range(100)])
    computes = np.arange(101) % 10 + 20  # 20..29 µs
    latencies = np.arange(101) * 2.0  # 0..200 µs
    feed(stats, starts, computes, latencies)
    now = int((starts[-1] + 1000) * US)
    s = stats.summary(now)
    assert set(s) == set(summary_keys())
    assert s["ticks"] == 101
    assert s["seconds"] == pytest.approx((starts[-1] + 1000) * 1e-6)
    assert s["rate_hz"] == pytest.approx(101 / s["seconds"])
    periods = np.diff(starts)
    assert s["period.mean_us"] == pytest.approx(periods.mean())
    assert s["period.p50_us"] == 900 and s["period.p99_us"] == 1100
    assert s["period.max_us"] == 1100
    assert s["jitter.p50_us"] == 100 and s["jitter.max_us"] == 100
    assert s["compute.mean_us"] == pytest.approx(computes.mean())
    assert s["compute.p50_us"] == nearest_rank(computes.astype(float), 50) == 24
    assert s["compute.p99_us"] == 29 and s["compute.max_us"] == 29
    assert s["latency.p50_us"] == 100  # rank ceil(50.5) = 51 → 2·50
    assert s["latency.p99_us"] == 198  # rank ceil(99.99) = 100 → 2·99
    assert s["latency.max_us"] == 200


def test_latency_percentiles_by_rank():
    stats = LoopStatistics()
    feed(stats, np.arange(100) * 1000.0, np.full(100, 10.0), np.arange(1, 101) * 1.0)
    s = stats.summary(100_000 * US)
    assert s["latency.p50_us"] == 50 and s["latency.p99_us"] == 99
    assert s["latency.max_us"] == 100
    assert s["total.latency.p50_us"] == 50 and s["total.latency.p99_us"] == 99
    assert s["total.latency.max_us"] == 100


def test_lateness_counts_late_and_too_late():
    stats = LoopStatistics(late_us=200, too_late_us=1000)
    lateness = [0, 50, 199, 200, 201, 999, 1000, 1001, 5000, 10]
    feed(stats, np.arange(10) * 1000.0, np.full(10, 5.0), lateness_us=lateness)
    s = stats.summary(10_000 * US)
    assert s["late"] == 5  # 201, 999, 1000, 1001, 5000 (> 200)
    assert s["too_late"] == 2  # 1001, 5000 (> 1000)
    assert s["lateness.max_us"] == 5000
    assert s["lateness.p50_us"] == 200  # sorted: 0 10 50 199 200 | 201 ...
    assert s["total.late"] == 5 and s["total.too_late"] == 2


def test_totals_over_windows_equal_one_window_over_everything():
    rng = np.random.default_rng(7)
    starts = np.cumsum(rng.integers(800, 1300, size=3000)).astype(float)
    computes = rng.integers(5, 400, size=3000).astype(float)
    latencies = rng.integers(50, 3000, size=3000).astype(float)
    windows, whole = LoopStatistics(), LoopStatistics()
    feed(whole, starts, computes, latencies)
    end = int((starts[-1] + 1) * US)
    total = whole.summary(end)
    for part in np.array_split(np.arange(3000), 7):
        feed(windows, starts[part], computes[part], latencies[part])
        last = windows.summary(int((starts[part[-1]] + 1) * US))
    for key in summary_keys():
        if key.startswith("total.") and key != "total.seconds":
            assert last[key] == pytest.approx(total[key], nan_ok=True), key
            # integer-µs timings: the 1 µs bins are exact, totals equal the window values
            window_key = key.removeprefix("total.")
            if window_key not in ("ticks", "seconds", "rate_hz"):
                assert total[key] == pytest.approx(total[window_key], nan_ok=True), key
    assert last["total.ticks"] == 3000
    # the first window starts at the first tick: both cover the same span
    assert last["total.seconds"] == pytest.approx(total["seconds"])


def test_period_spans_windows():
    stats = LoopStatistics()
    feed(stats, [0.0, 1000.0], [1.0, 1.0])
    first = stats.summary(1500 * US)
    feed(stats, [2500.0], [1.0])
    second = stats.summary(3000 * US)
    assert first["period.max_us"] == 1000
    assert second["ticks"] == 1 and second["period.max_us"] == 1500  # 1000 → 2500
    assert second["seconds"] == pytest.approx(1.5e-3)
    assert second["total.period.max_us"] == 1500 and second["total.ticks"] == 3


def test_empty_window_is_nan_not_an_error():
    stats = LoopStatistics()
    s = stats.summary(123)
    assert s["ticks"] == 0 and s["total.ticks"] == 0 and s["late"] == 0
    assert math.isnan(s["period.p50_us"]) and math.isnan(s["total.compute.max_us"])
    feed(stats, [0.0], [3.0])
    s = stats.summary(10 * US)
    assert s["ticks"] == 1 and s["compute.p50_us"] == 3
    assert math.isnan(s["period.p50_us"]) and math.isnan(s["jitter.max_us"])
    assert math.isnan(s["latency.p99_us"]) and math.isnan(s["lateness.p99_us"])


def test_ring_overflow_keeps_the_newest_rows_and_counts_every_tick():
    stats = LoopStatistics(capacity=8)
    feed(stats, np.arange(20) * 1000.0, np.arange(20) * 1.0)
    s = stats.summary(20_000 * US)
    assert s["ticks"] == 8 and s["total.ticks"] == 20
    assert s["compute.p50_us"] == 15  # rows 12..19
    assert s["compute.max_us"] == 19


def test_unmeasured_nominal_gives_no_jitter():
    stats = LoopStatistics()
    feed(stats, [0.0, 1000.0, 2100.0], [1.0, 1.0, 1.0], nominal_us=None)
    s = stats.summary(3000 * US)
    assert s["period.max_us"] == 1100 and math.isnan(s["jitter.p50_us"])


def test_histogram_overflow_reports_the_exact_max():
    stats = LoopStatistics(histogram_us=100)
    feed(stats, [0.0, 1000.0], [50.0, 250.0])
    s = stats.summary(2000 * US)
    assert s["total.compute.max_us"] == 250 and s["total.compute.p99_us"] == 250
    assert s["total.compute.p50_us"] == 50


def test_recording_allocates_nothing_per_tick():
    import tracemalloc

    stats = LoopStatistics(capacity=64)
    stats.tick(1, 2, 3, 4, 5)
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    for k in range(1000):
        stats.tick(k, k + 1, -1, -1, 1000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    grown = sum(d.size_diff for d in after.compare_to(before, "filename"))
    assert grown < 1024  # no per-tick growth (the ring is preallocated)
