"""The fault soak's schedule (lab/soaks/fault_schedule.py): one fault a period, every kind
at least once when there are as many faults as kinds, the same seed the same schedule."""

from __future__ import annotations

import collections

import pytest

from joint_space_control.lab.soaks.fault_schedule import KINDS, fault_schedule


def test_an_hour_has_a_fault_a_minute_and_every_kind():
    schedule = fault_schedule(3600.0, 60.0, seed=0)
    assert [f.at for f in schedule] == [60.0 * (k + 1) for k in range(59)]  # none in the last
    counts = collections.Counter(f.kind for f in schedule)
    assert set(counts) == set(KINDS) and min(counts.values()) >= 1
    assert sum(counts.values()) == 59


def test_the_short_form_has_every_kind_once():
    schedule = fault_schedule(180.0, 15.0, seed=3)
    assert sorted(f.kind for f in schedule) == sorted(KINDS)


def test_the_same_seed_gives_the_same_schedule_and_another_seed_another():
    assert fault_schedule(3600.0, seed=7) == fault_schedule(3600.0, seed=7)
    assert fault_schedule(3600.0, seed=7) != fault_schedule(3600.0, seed=8)


def test_fewer_faults_than_kinds_are_distinct_and_bad_requests_are_refused():
    short = fault_schedule(100.0, 30.0, seed=1)
    assert len(short) == 2 and len({f.kind for f in short}) == 2
    with pytest.raises(ValueError, match="unknown fault kinds"):
        fault_schedule(600.0, kinds=("kill_everything",))
    with pytest.raises(ValueError, match="> 0"):
        fault_schedule(600.0, period=0.0)
