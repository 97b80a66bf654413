"""ros/graph.node_names: the nodes behind graph endpoints, none of rmw's placeholders."""

from __future__ import annotations

from types import SimpleNamespace

from joint_space_control.ros.graph import UNKNOWN_NODE_NAME, UNKNOWN_NODE_NAMESPACE, node_names


def endpoint(namespace: str, name: str) -> SimpleNamespace:
    return SimpleNamespace(node_namespace=namespace, node_name=name)


def test_names_are_fully_qualified_whatever_the_namespace():
    found = node_names([endpoint("/", "sim_bridge"), endpoint("/arm/", "controller")])
    assert found == {"/sim_bridge", "/arm/controller"}


def test_an_endpoint_whose_node_is_not_yet_named_is_left_out():
    # what rmw reports for a publisher whose participant is known before its node: a
    # restarted dashboard once took this for the plant
    unnamed = endpoint(UNKNOWN_NODE_NAMESPACE, UNKNOWN_NODE_NAME)
    assert node_names([unnamed]) == set()
    assert node_names([unnamed, endpoint("/", "sim_bridge")]) == {"/sim_bridge"}
    assert node_names([endpoint("/", UNKNOWN_NODE_NAME)]) == set()
    assert node_names([endpoint(f"/{UNKNOWN_NODE_NAMESPACE}", "x")]) == set()
