"""Names in the ROS graph."""

from __future__ import annotations

from typing import Any


def node_names(endpoints: Any) -> set[str]:
    """The fully qualified names of the nodes behind graph endpoints (topic info)."""
    return {f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in endpoints}
