"""jsc bench's alternating rounds: the median row and the ratio paired within each round."""

from __future__ import annotations

import math

from joint_space_control.lab.bench.run import median_row, ratios


def test_median_row_keeps_every_round():
    rows = [{"robot": "iiwa", "v": v, "round": k} for k, v in enumerate([3.0, 1.0, 2.0, 9.0])]
    row = median_row(rows, "v")
    assert row["v"] == 2.0 and "round" not in row  # the lower middle of 1, 2, 3, 9
    assert row["v_rounds"] == [3.0, 1.0, 2.0, 9.0]


def test_loop_over_pingpong_is_the_median_of_ratios_of_the_same_round():
    # the machine slows down by 2× in round 1: paired ratios stay 1.1, unpaired ones would not
    pp = [
        {"robot": "iiwa", "round_trips_per_s": v, "round": k}
        for k, v in enumerate([1000, 500, 1000])
    ]
    loops = [
        {"robot": "iiwa", "law": "inverse_dynamics", "steps_per_s": v, "round": k}
        for k, v in enumerate([1100, 550, 1100])
    ]
    # as users run it (use_sim_time, a recorder): paired with the same rounds' ping-pong
    as_used = [
        {"robot": "iiwa", "law": "inverse_dynamics", "steps_per_s": v, "round": k}
        for k, v in enumerate([800, 450, 900])
    ]
    result = {
        "lockstep": [median_row(loops, "steps_per_s")],
        "pingpong": [median_row(pp, "round_trips_per_s")],
        "rounds": {"pingpong": pp, "lockstep": loops, "lockstep_as_used": as_used},
    }
    (ratio,) = ratios(result)
    assert math.isclose(ratio["loop_over_pingpong"], 1.1)
    assert [round(x, 12) for x in ratio["loop_over_pingpong_rounds"]] == [1.1, 1.1, 1.1]
    assert [round(x, 12) for x in ratio["as_used_over_pingpong_rounds"]] == [0.8, 0.9, 0.9]
    assert math.isclose(ratio["as_used_over_pingpong"], 0.9)
    assert math.isnan(ratio["loop_over_in_process"])  # no in-process section


def test_no_pingpong_gives_nan():
    loops = [{"robot": "iiwa", "law": "pd_gravity", "steps_per_s": 900.0, "round": 0}]
    result = {"lockstep": [median_row(loops, "steps_per_s")], "rounds": {"lockstep": loops}}
    assert math.isnan(ratios(result)[0]["loop_over_pingpong"])
