"""Log lines of recurring faults: at most one a second per kind, with what was held back.

A fault met at every tick (a broken joint state at 1 kHz, a law beyond its bound) must not
drown the log, nor cost the tick the text of a line nobody reads. rclpy's
``throttle_duration_sec`` drops the lines it throttles silently and formats the message
before deciding. Here the decision comes first, on a monotonic clock (wall time, so also in
simulation time), and the text is built only when it is said, from a format string and its
arguments or by a function:

    log = ThrottledLog(node.get_logger())
    log.warning("rejected joint state", "rejected joint state: {}", err)
    # → "rejected joint state: missing joints ['joint2'] (37 more since the last report)"

The first occurrence of a kind is said at once; then at most one line per ``period``, the
next one saying how many occurrences of that kind were held back since the line before.
Kinds are independent. No ROS here: the logger is anything with ``warning``, ``error`` and
``info`` methods taking a string (an rclpy logger).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from typing import Protocol

#: Appended to a line that follows held-back occurrences of its kind.
HELD_BACK = " ({} more since the last report)"


class Throttle:
    """Decides, per kind, whether an occurrence is said now (and how many were held back
    since the last one said) or counted in silence."""

    def __init__(self, period: float = 1.0, clock: Callable[[], float] = time.monotonic) -> None:
        """``period`` [s]: the shortest time between two lines of one kind, on ``clock``."""
        self.period = period
        self._clock = clock
        self._kinds: dict[Hashable, list] = {}  # kind → [time of the next line, held back]

    def due(self, kind: Hashable) -> int | None:
        """One occurrence of ``kind``: None when it is to be held back (counted), else the
        number of occurrences held back since the last line of that kind (0 the first time)."""
        now = self._clock()
        entry = self._kinds.get(kind)
        if entry is None:
            self._kinds[kind] = [now + self.period, 0]
            return 0
        if now < entry[0]:
            entry[1] += 1
            return None
        held = entry[1]
        entry[0], entry[1] = now + self.period, 0
        return held


class Logger(Protocol):
    def info(self, message: str) -> object: ...
    def warning(self, message: str) -> object: ...
    def error(self, message: str) -> object: ...


#: A line's text (a format string when arguments follow), or a function that builds it.
Text = str | Callable[[], str]


class ThrottledLog:
    """A logger behind a :class:`Throttle`: each method takes the kind, then the text and
    its format arguments (``text.format(*args)``, only when the line is said), and returns
    whether the line was said. Through an rclpy logger the lines name this module as their
    caller (``{file_name}``, ``{line_number}`` in RCUTILS_CONSOLE_OUTPUT_FORMAT)."""

    def __init__(
        self, logger: Logger, period: float = 1.0, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.logger = logger
        self.throttle = Throttle(period, clock)

    # One call of the logger per method: rclpy's logger keeps one severity per call site.
    def info(self, kind: Hashable, text: Text, *args: object) -> bool:
        line = self._line(kind, text, args)
        if line is not None:
            self.logger.info(line)
        return line is not None

    def warning(self, kind: Hashable, text: Text, *args: object) -> bool:
        line = self._line(kind, text, args)
        if line is not None:
            self.logger.warning(line)
        return line is not None

    def error(self, kind: Hashable, text: Text, *args: object) -> bool:
        line = self._line(kind, text, args)
        if line is not None:
            self.logger.error(line)
        return line is not None

    def _line(self, kind: Hashable, text: Text, args: tuple) -> str | None:
        """The line to say now, or None to hold it back."""
        held = self.throttle.due(kind)
        if held is None:
            return None
        if callable(text):
            line = text()
        else:
            line = text.format(*args) if args else text
        return line + HELD_BACK.format(held) if held else line
