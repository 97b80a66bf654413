"""Which topics a recorder takes: names and shell-style patterns, resolved like ROS names."""

from __future__ import annotations

import fnmatch
import re
from collections.abc import Sequence

#: A robot's topics, relative to its namespace: the loop's signals, every controller's state
#: and configuration, and the plant's true state when its measurement is imperfect
#: (published only then).
ROBOT_TOPICS = (
    "joint_states",
    "sim_bridge/true_joint_states",
    "effort_command",
    "reference",
    "*/state",
    "*/config",
)
#: The world's: simulation time, parameter changes and diagnostics.
WORLD_TOPICS = ("/clock", "/parameter_events", "/diagnostics")
#: Recorded when ``topics`` is empty: the one robot's (in the recorder's namespace) and the
#: world's.
DEFAULT_TOPICS = ROBOT_TOPICS + WORLD_TOPICS


def world_topics(namespaces: Sequence[str]) -> list[str]:
    """The ``topics`` that record a world of several robots: each robot's in its namespace
    (relative, as the robots' own are to the recorder in the root namespace) and the
    world's."""
    return [f"{ns}/{topic}" for ns in namespaces for topic in ROBOT_TOPICS] + list(WORLD_TOPICS)


_NAME = re.compile(r"^[~/]?[A-Za-z0-9_*?/\[\]{}]+$")


class TopicSelection:
    """Topic names or patterns (``*``, ``?``, ``[…]``) to record.

    A relative entry is resolved in ``namespace`` (``joint_states`` in ``/robot1`` is
    ``/robot1/joint_states``); a pattern's ``*`` also matches ``/``, so ``*/state`` takes
    the ``state`` topic of every controller in the namespace.
    """

    def __init__(self, entries: Sequence[str], namespace: str = "/") -> None:
        entries = list(entries) or list(DEFAULT_TOPICS)
        ns = "/" + namespace.strip("/")
        self.patterns: list[str] = []
        for entry in entries:
            if not isinstance(entry, str) or not _NAME.match(entry) or "//" in entry:
                raise ValueError(f"invalid topic name or pattern {entry!r}")
            if entry.startswith("~"):
                raise ValueError(f"private topic names cannot be recorded: {entry!r}")
            absolute = entry if entry.startswith("/") else f"{ns.rstrip('/')}/{entry}"
            self.patterns.append(absolute.rstrip("/") or "/")

    def matches(self, topic: str) -> bool:
        return any(fnmatch.fnmatchcase(topic, p) for p in self.patterns)
