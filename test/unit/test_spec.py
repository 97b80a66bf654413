"""Step-response specifications (analysis/spec.py): parsing, one-line errors, worst joint,
normalised violations, and the ``spec`` check of jsc experiment built on them."""

from __future__ import annotations

import math

import pytest

from joint_space_control.analysis.spec import (
    METRICS,
    VIOLATION_CAP,
    SpecError,
    judge,
    parse_spec,
)
from joint_space_control.workbench.experiments.judging.outcome import RunView
from joint_space_control.workbench.experiments.judging.theory import evaluate
from test.unit.tuning_fakes import controller_metrics


def test_parse_spec_reads_every_clause_in_order():
    spec = parse_spec(" overshoot<=5, settling_2pct <= 0.8,peak_torque_ratio<=0.8, rise_time>=.05")
    assert [(c.metric, c.op, c.bound) for c in spec.clauses] == [
        ("overshoot", "<=", 5.0),
        ("settling_2pct", "<=", 0.8),
        ("peak_torque_ratio", "<=", 0.8),
        ("rise_time", ">=", 0.05),
    ]
    assert str(spec) == "overshoot<=5, settling_2pct<=0.8, peak_torque_ratio<=0.8, rise_time>=0.05"
    assert parse_spec(str(spec)) == spec  # the text written into scenario.yaml reads back


def test_every_required_metric_is_known():
    for name in (
        "overshoot",
        "settling_2pct",
        "settling_5pct",
        "rise_time",
        "steady_state_error",
        "peak_torque_ratio",
        "saturated_fraction",
    ):
        assert parse_spec(f"{name}<=1").clauses[0].metric == name
    assert set(METRICS) >= {"overshoot", "settling_2pct", "peak_torque_ratio"}


@pytest.mark.parametrize(
    "text, words",
    [
        ("overshot<=5", "unknown metric 'overshot'"),
        ("overshoot<5", "malformed clause 'overshoot<5'"),
        ("overshoot<=five", "finite number"),
        ("overshoot<=inf", "finite number"),
        ("overshoot<=5,", "malformed clause ''"),
        ("", "empty specification"),
        ("overshoot=5", "malformed"),
    ],
)
def test_bad_specs_say_why_in_one_line_and_list_the_metrics(text, words):
    with pytest.raises(SpecError) as err:
        parse_spec(text)
    message = str(err.value)
    assert words in message
    assert "\n" not in message
    if "unknown" in words or "malformed" in words:
        assert "settling_2pct [s]" in message and "peak_torque_ratio" in message


def test_worst_joint_and_margins_on_the_theorys_step_responses():
    # joint1: ζ = 0.5 (16.3 % overshoot), joint2: ζ = 1 (none); ω_n = 10 both
    c = controller_metrics([10.0, 10.0], [0.5, 1.0])
    j = judge(parse_spec("overshoot<=20, settling_2pct<=1.0"), c)
    assert j.met
    assert j.values[0].joint == "joint1"
    assert j.values[0].value == pytest.approx(16.303, abs=1e-3)
    # violation = (value − bound)/|bound|: ≤ 0 when met, its size the margin
    assert j.violations[0] == pytest.approx((16.303 - 20) / 20, abs=1e-4)
    assert j.worst == max(j.violations) <= 0
    assert j.excess == 0.0
    j = judge(parse_spec("overshoot<=5"), c)
    assert not j.met
    assert j.violations[0] == pytest.approx((16.303 - 5) / 5, abs=1e-3)
    assert j.by_joint[0]["joint2"] == pytest.approx(-1.0)  # 0 % overshoot: margin 1
    assert j.excess == pytest.approx(j.violations[0])  # only joint1 misses


def test_greater_equal_clauses_take_the_smallest_joint():
    c = controller_metrics([5.0, 20.0], [1.0, 1.0])
    j = judge(parse_spec("rise_time>=0.2"), c)  # ζ = 1: t_r ≈ 3.36/ω_n: 0.67 s, 0.17 s
    assert j.values[0].joint == "joint2"  # the faster joint is the worst for a lower bound
    assert not j.met and j.violations[0] > 0


def test_a_response_that_never_settles_fails_with_the_duration_as_its_violation():
    c = controller_metrics([1.0, 10.0], [1.0, 1.0], duration=2.0)  # joint1: t_s ≈ 5.8 s
    assert c["steps"][0]["joints"]["joint1"]["settling_time_2"] is None
    j = judge(parse_spec("settling_2pct<=0.5"), c)
    assert j.values[0].value == math.inf and j.values[0].joint == "joint1"
    assert not j.met
    assert j.violations[0] == pytest.approx((2.0 - 0.5) / 0.5)
    assert "never" in j.text() and "NOT met" in j.text()


def test_peak_torque_ratio_is_over_each_joints_own_limit():
    c = controller_metrics([3.0, 6.0], [1.0, 1.0])
    td = c["torque_demand"]
    expected = {j: td["peak_abs"][j] / td["effort_limits"][j] for j in ("joint1", "joint2")}
    j = judge(parse_spec("peak_torque_ratio<=0.8"), c)
    worst = max(expected, key=expected.get)
    assert j.values[0].joint == worst
    assert j.values[0].value == pytest.approx(expected[worst])
    td["effort_limits"] = {"joint1": None, "joint2": None}  # unbounded in the URDF
    j = judge(parse_spec("peak_torque_ratio<=0.8"), c)
    assert math.isnan(j.values[0].value) and not j.met
    assert j.violations[0] == VIOLATION_CAP
    assert "no effort limits known" in j.text()


def test_steady_state_error_is_absolute():
    c = controller_metrics([10.0, 10.0], [1.0, 1.0])
    c["steps"][0]["joints"]["joint2"]["steady_state_error"] = -0.003
    j = judge(parse_spec("steady_state_error<=0.001"), c)
    assert j.values[0].value == pytest.approx(0.003) and j.values[0].joint == "joint2"
    assert not j.met


def test_a_run_without_a_step_cannot_meet_a_step_clause():
    c = controller_metrics([10.0, 10.0], [1.0, 1.0])
    c["steps"] = []
    j = judge(parse_spec("overshoot<=5"), c)
    assert not j.met and "no step in the run" in j.text()


def _view(label, c):
    return RunView(label, "planar_2dof", c, [], {})


def test_the_spec_check_judges_each_run():
    good = controller_metrics([12.0, 12.0], [1.0, 1.0])  # t_s ≈ 0.49 s, no overshoot
    slow = controller_metrics([6.0, 12.0], [1.0, 1.0])  # joint1: t_s ≈ 0.97 s
    outcomes = evaluate(
        {"check": "spec", "spec": "overshoot<=5, settling_2pct<=0.6"},
        [_view("good", good), _view("slow", slow)],
    )
    assert [o.passed for o in outcomes] == [True, False]
    assert outcomes[1].text.startswith("slow: ")
    assert "settling_2pct" in outcomes[1].text and "(joint1)" in outcomes[1].text
    assert outcomes[0].numbers["spec"] == "overshoot<=5, settling_2pct<=0.6"
    with pytest.raises(SpecError):
        evaluate({"check": "spec", "spec": "overshot<=5"}, [_view("good", good)])
