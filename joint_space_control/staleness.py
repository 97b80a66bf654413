"""How far behind the publisher a subscriber takes its messages (no ROS).

A reliable writer that keeps a history re-sends what a reader missed, in order: a controller
that falls behind the plant (it started while the plant ran, or stalled, on a loaded
machine) is then handed every state it missed, oldest first, and answering each as it comes
keeps it as far behind as the writer's history is long. The fault soak's restarted
controller answered states 10 s old for minutes that way (the plant's 10000-sample history
at 1 kHz). A state that old describes an arm that is no longer there: it is dropped unanswered,
which costs microseconds, so the reader catches up within a fraction of a second. Since
then the controller's states are best effort behind a realtime plant
(``REALTIME_STATE_QOS``): the writer re-sends it nothing, and what is judged here is only
what waited in the process itself (a stalled or starved controller).

The age of a message is its delay — receive time minus its source timestamp, both wall
clocks — less the smallest delay seen so far: the smallest is the transport's own delay plus
the offset between the two machines' clocks, so the age means the same across machines
whose clocks differ. The controller judges it only behind a plant known to run in realtime:
a lockstep plant waits for the answer to the one state it sent, however late it is taken.
"""

from __future__ import annotations

#: A joint state older than this [s] (beyond the smallest delay seen) is not answered: the
#: default command_timeout, after which the plant has braked anyway.
MAX_AGE = 0.1


class Lag:
    """Ages of the messages of one subscription (see the module docstring)."""

    def __init__(self, max_age: float = MAX_AGE) -> None:
        self.max_age_ns = round(max_age * 1e9)
        self._least = None  # smallest delay seen [ns]
        self.dropped = 0  # messages judged too old

    def age_ns(self, sent_ns: int, received_ns: int) -> int:
        """The age [ns] of a message sent at ``sent_ns`` and received at ``received_ns``."""
        delay = received_ns - sent_ns
        if self._least is None or delay < self._least:
            self._least = delay
        return delay - self._least

    def too_old(self, sent_ns: int, received_ns: int) -> bool:
        """True (and counted) when the message is older than the bound."""
        if self.age_ns(sent_ns, received_ns) > self.max_age_ns:
            self.dropped += 1
            return True
        return False
