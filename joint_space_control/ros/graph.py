"""Names in the ROS graph."""

from __future__ import annotations

from typing import Any

#: rmw's placeholders for an endpoint whose node's name has not been discovered yet (its
#: participant is known, its node information not): no node has that name.
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"
UNKNOWN_NODE_NAMESPACE = "_NODE_NAMESPACE_UNKNOWN_"


def node_names(endpoints: Any) -> set[str]:
    """The fully qualified names of the nodes behind graph endpoints (topic info). An
    endpoint whose node is not yet named is left out; the next discovery round names it (a
    restarted dashboard once took ``_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_`` for the
    plant and showed no robot for 13 minutes)."""
    return {
        f"{i.node_namespace.rstrip('/')}/{i.node_name}"
        for i in endpoints
        if i.node_name != UNKNOWN_NODE_NAME
        and i.node_namespace.strip("/") != UNKNOWN_NODE_NAMESPACE
    }
