"""What the nodes logged (no ROS): the WARN, ERROR and FATAL lines of a node's log, grouped
by their text with the numbers left out, counted, with the first line of each group, and
the Python tracebacks. A fault soak keeps them per process incarnation and prints them when
it fails."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

#: rclpy's console format: ``[LEVEL] [stamp] [logger]: message``.
_LINE = re.compile(r"^\[(WARN|ERROR|FATAL)\] \[[^\]]*\] \[[^\]]*\]: (.*)$")
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?", re.IGNORECASE)
TRACEBACK = "Traceback (most recent call last)"


@dataclass(frozen=True)
class Said:
    """A group of lines: level, how many, and the first of them (its message)."""

    level: str
    count: int
    first: str


def said(text: str) -> list[Said]:
    """The WARN/ERROR/FATAL groups of a log's text, most frequent first."""
    groups: dict[tuple[str, str], list] = {}
    for line in text.splitlines():
        m = _LINE.match(line.strip())
        if m is None:
            continue
        level, message = m.groups()
        key = (level, _NUMBER.sub("#", message))
        if key in groups:
            groups[key][0] += 1
        else:
            groups[key] = [1, message]
    found = [Said(level, count, first) for (level, _), (count, first) in groups.items()]
    return sorted(found, key=lambda s: (-s.count, s.level, s.first))


def said_in(logs: Path) -> dict[str, list[Said]]:
    """Per log file of ``logs`` (name → groups), those that said anything."""
    out = {}
    for path in sorted(logs.rglob("*.log")):
        groups = said(path.read_text(errors="replace"))
        if groups:
            out[path.name] = groups
    return out


def tracebacks(logs: Path) -> dict[str, int]:
    """Every log of ``logs`` with a Python traceback in it, and how many."""
    found = {}
    for path in sorted(logs.rglob("*.log")):
        count = path.read_text(errors="replace").count(TRACEBACK)
        if count:
            found[path.name] = count
    return found


def format_said(found: dict[str, list[Said]], most: int = 6, width: int = 200) -> str:
    """The groups per log, ``most`` per log, each line cut at ``width`` characters."""
    lines = ["what the nodes logged (WARN and above, by count):"]
    for name, groups in found.items():
        lines.append(f"  {name}:")
        for g in groups[:most]:
            lines.append(f"    {g.count:6d} {g.level:5s} {g.first}"[:width])
        if len(groups) > most:
            lines.append(f"    ... {len(groups) - most} more kinds")
    return "\n".join(lines)
