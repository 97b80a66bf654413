"""Which commander the plant obeys: one at a time (no ROS; the rule of docs/safety.md).

A commander is named by the ``header.frame_id`` of its effort commands (the package's
controllers put their fully qualified node name there; ``""`` is an unnamed sender, e.g.
``ros2 topic pub``) or, for ``~/commands`` arrays, which have no header, by that topic. The
first valid command claims the plant; from then on commands from anyone else are refused
(never applied) until the owner lets go:

- it stops commanding for ``timeout`` (sim_bridge's ``owner_timeout``, at least its
  ``command_timeout``, in the plant's time base: simulation time in realtime, wall time in
  lockstep, where time does not advance without commands). The brakes engage at
  ``command_timeout`` already: an owner that stalls is braked, not replaced;
- it leaves the graph (the node its name names no longer publishes commands);
- someone calls ``~/release``.

The same commander starting again under the same name (a restarted controller) is the
owner still, so it takes over at once.
"""

from __future__ import annotations

#: The name of a commander that sends ``~/commands`` arrays (they carry no header).
ARRAY_COMMANDER = "~/commands"


class CommandOwnership:
    """The current owner and when it last commanded."""

    def __init__(self) -> None:
        self.owner: str | None = None
        self._last = 0.0

    def admit(self, sender: str, now: float, timeout: float) -> bool:
        """True if a valid command from ``sender`` at ``now`` [s] is to be applied: it owns
        the plant, or nobody does (any more) and it claims it."""
        if self.owner is None or (sender != self.owner and now - self._last > timeout):
            self.owner = sender
        if sender != self.owner:
            return False
        self._last = now
        return True

    def release(self) -> str | None:
        """Free the plant; the owner it had (None: nobody)."""
        owner, self.owner = self.owner, None
        return owner

    def left(self, present: set[str]) -> str | None:
        """Free the plant when its owner is not ``present`` any more (the node's name among
        the publishers of commands; ``""`` while anyone publishes effort commands,
        :data:`ARRAY_COMMANDER` while anyone publishes arrays); the owner that left, else
        None."""
        if self.owner is None or self.owner in present:
            return None
        return self.release()
