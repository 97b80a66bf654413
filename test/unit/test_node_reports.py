"""What a failed fault soak prints of the nodes (issue 27): their loops from the recorded
/diagnostics (analysis/loop_digest) and their logs' warnings (analysis/node_logs)."""

import math

from joint_space_control.lab.soaks.loop_digest import format_loops, loop_windows, sample
from joint_space_control.lab.soaks.node_logs import format_said, said, said_in, tracebacks


def _status(t, name="ctl: control loop", level=0, message="ok", rate="1000.0000", p99="80"):
    return sample(t, name, level, message, {"rate_hz": rate, "compute.p99_us": p99})


def test_loop_windows_keep_the_lowest_rate_the_longest_compute_and_the_worst_level():
    t0 = 1000.0
    samples = [
        _status(t0 + 0.5),
        _status(t0 + 1.5, rate="240.0000", p99="3900"),
        _status(t0 + 2.5, level=1, message="ticks late"),
        _status(t0 + 12.0, rate="nan"),
        _status(t0 + 13.0, name="sim: control loop", level=2, message="braking"),
    ]
    windows = loop_windows(samples, t0, window=10.0)
    ctl = windows["ctl: control loop"]
    assert [w.start for w in ctl] == [0.0, 10.0]
    assert ctl[0].statuses == 3 and ctl[0].min_rate_hz == 240.0
    assert ctl[0].max_compute_p99_us == 3900.0
    assert (ctl[0].level, ctl[0].message) == (1, "ticks late")
    assert math.isnan(ctl[1].min_rate_hz) and ctl[1].level == 0
    text = format_loops(windows)
    assert "ctl: control loop: 240 -" in text
    assert "0 s  WARN: ticks late" in text and "10 s  OK: ok" in text
    assert "10 s  ERROR: braking" in text


def test_said_groups_warnings_by_their_text_without_numbers():
    log = "\n".join(
        [
            "[INFO] [1.0] [ctl]: started",
            "[WARN] [2.0] [ctl]: realised period 4 ms",
            "[WARN] [3.0] [ctl]: realised period 28 ms",
            "[ERROR] [4.0] [ctl]: non-finite torque at t=1.5 s",
            "Traceback (most recent call last):",
        ]
    )
    groups = said(log)
    assert [(g.level, g.count, g.first) for g in groups] == [
        ("WARN", 2, "realised period 4 ms"),
        ("ERROR", 1, "non-finite torque at t=1.5 s"),
    ]


def test_logs_of_a_folder_are_read_per_file(tmp_path):
    (tmp_path / "a.0.log").write_text("[WARN] [1] [a]: late\nTraceback (most recent call last)\n")
    (tmp_path / "b.0.log").write_text("[INFO] [1] [b]: fine\n")
    found = said_in(tmp_path)
    assert list(found) == ["a.0.log"]
    assert "a.0.log:" in format_said(found) and "1 WARN  late" in format_said(found)
    assert tracebacks(tmp_path) == {"a.0.log": 1}
