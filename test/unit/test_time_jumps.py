"""Backward time jumps (issue 17): one is a restarted simulator, several within a window are
two clocks. A fake clock drives them: no test waits."""

from __future__ import annotations

from joint_space_control.time_jumps import BackwardJumps


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_a_single_backward_jump_is_a_restart_three_within_the_window_repeat():
    clock = FakeClock()
    jumps = BackwardJumps(3, 2.0, clock)
    assert not jumps.jumped()  # a restarted simulator
    clock.now += 5.0
    assert not jumps.jumped()  # another one, much later
    clock.now += 0.5
    assert not jumps.jumped()  # two within 2 s, the first one long before
    assert not jumps.repeating
    clock.now += 1.5
    assert jumps.jumped()  # three within 2 s
    assert jumps.repeating
    clock.now += 1.9
    assert jumps.jumped()  # still repeating: one within the window
    clock.now += 1.9
    assert jumps.repeating
    clock.now += 0.1
    assert not jumps.repeating  # 2 s without a jump
    assert not jumps.jumped()  # a new start: a restart again
    assert jumps.total == 6
