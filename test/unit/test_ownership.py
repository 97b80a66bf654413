"""One commander at a time (sim_bridge/ownership.py): the first valid command claims the
plant, others are refused until the owner is silent for the timeout, leaves, or is
released; the owner restarted under its name is the owner still."""

from __future__ import annotations

from sim_bridge.ownership import ARRAY_COMMANDER, CommandOwnership

TIMEOUT = 0.1


def test_the_first_commander_claims_and_others_are_refused_while_it_commands():
    o = CommandOwnership()
    assert o.admit("/ctrl", 0.0, TIMEOUT) and o.owner == "/ctrl"
    assert not o.admit("/intruder", 0.05, TIMEOUT)
    assert o.admit("/ctrl", 0.09, TIMEOUT)
    assert not o.admit("/intruder", 0.19, TIMEOUT)  # 0.1 s after the owner's last: not yet
    assert not o.admit("", 0.1, TIMEOUT) and not o.admit(ARRAY_COMMANDER, 0.1, TIMEOUT)
    assert o.owner == "/ctrl"


def test_ownership_passes_after_the_timeout_on_leaving_and_on_release():
    o = CommandOwnership()
    o.admit("/ctrl", 0.0, TIMEOUT)
    assert o.admit("/other", 0.1001, TIMEOUT) and o.owner == "/other"  # silent too long
    assert not o.admit("/ctrl", 0.15, TIMEOUT)
    assert o.left({"/ctrl", "/other", ""}) is None  # still there
    assert o.left({"/ctrl", ""}) == "/other" and o.owner is None  # left the graph
    assert o.admit("/ctrl", 0.2, TIMEOUT)
    assert o.release() == "/ctrl" and o.release() is None
    assert o.admit(ARRAY_COMMANDER, 0.21, TIMEOUT)
    assert o.left({"/ctrl", ""}) == ARRAY_COMMANDER  # nobody publishes arrays any more


def test_a_restarted_commander_with_the_same_name_is_the_owner_at_once():
    o = CommandOwnership()
    o.admit("/ctrl", 0.0, TIMEOUT)
    assert o.admit("/ctrl", 0.05, TIMEOUT)  # new process, same node name: no gap
    o.admit("", 1.0, TIMEOUT)  # an unnamed sender after the owner went silent
    assert o.owner == "" and o.left({"/ctrl", ""}) is None  # some publisher may be it
    assert o.left(set()) == ""
