"""A controller drops joint states that fell far behind the plant (joint_space_control.
staleness; the fault soak's restarted controller answered 10 s old ones, issue 27)."""

from joint_space_control.staleness import MAX_AGE, Lag

MS = 1_000_000


def test_age_is_the_delay_beyond_the_smallest_seen_whatever_the_clock_offset():
    offset = 3_600_000 * MS  # the publisher's clock an hour behind: ages are unchanged
    lag = Lag()
    sent = [0, 1 * MS, 2 * MS, 3 * MS]
    received = [offset + 0.2 * MS, offset + 1.1 * MS, offset + 2.3 * MS, offset + 3.1 * MS]
    ages = [lag.age_ns(s, round(r)) for s, r in zip(sent, received, strict=True)]
    assert ages == [0, 0, round(0.2 * MS), 0]  # the least delay 0.1 ms from the second on
    assert not any(lag.too_old(s, round(r)) for s, r in zip(sent, received, strict=True))


def test_a_backlog_is_dropped_until_the_reader_is_current_again():
    """A reader 10 s behind takes the plant's re-sent history: everything older than
    MAX_AGE is dropped and counted, the first current state is taken."""
    lag = Lag()
    assert not lag.too_old(0, 100_000)  # the first state, 0.1 ms on its way
    now = 20_000 * MS
    backlog = [now - 10_000 * MS + k * MS for k in range(9_950)]  # up to 50 ms old
    old = [lag.too_old(sent, now) for sent in backlog]
    limit = round(MAX_AGE * 1e9)
    assert old == [now - s - 100_000 > limit for s in backlog]
    assert lag.dropped == sum(old) and 9_800 < lag.dropped < 9_950
    assert not lag.too_old(now - 1 * MS, now)
