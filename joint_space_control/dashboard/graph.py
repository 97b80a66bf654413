"""The robots of a ROS graph, as the dashboard finds them (pure: names in, names out).

- a **robot** is a ``…/joint_states`` topic (sensor_msgs/JointState) with a publisher, its
  plant: its key is the topic's namespace ("" in the root namespace, "/arm" for
  ``/arm/joint_states``);
- a **controller** is a node that publishes ``<node>/config`` (std_msgs/String, this
  package's configuration) and ``<node>/state`` (std_msgs/Float64MultiArray); it serves the
  robot whose joint states it subscribes to.

A plant that simulates several robots (``sim_bridge`` with ``robots``) names each robot's
parameters ``<name>.<parameter>``, ``<name>`` being the robot's namespace without its
slash (:func:`parameter_prefix`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

JOINT_STATE = "sensor_msgs/msg/JointState"
STRING = "std_msgs/msg/String"
FLOAT_ARRAY = "std_msgs/msg/Float64MultiArray"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


def robot_topics(topics: Iterable[tuple[str, Sequence[str]]]) -> dict[str, str]:
    """{robot key: joint-state topic} for every ``…/joint_states`` JointState topic."""
    found = {}
    for name, types in topics:
        head, _, last = name.rpartition("/")
        if last == "joint_states" and JOINT_STATE in types:
            found[head] = name
    return dict(sorted(found.items()))


def controller_nodes(topics: Iterable[tuple[str, Sequence[str]]]) -> list[str]:
    """The fully qualified names of the nodes that publish both ``<node>/config`` (String)
    and ``<node>/state`` (Float64MultiArray)."""
    types = {name: set(t) for name, t in topics}
    nodes = []
    for name, t in types.items():
        node, _, last = name.rpartition("/")
        if last == "config" and STRING in t and FLOAT_ARRAY in types.get(f"{node}/state", ()):
            nodes.append(node)
    return sorted(nodes)


def robot_of(
    subscriptions: Iterable[tuple[str, Sequence[str]]], robots: Mapping[str, str]
) -> str | None:
    """The key of the robot whose joint-state topic is among a node's ``subscriptions``."""
    by_topic = {topic: key for key, topic in robots.items()}
    for name, types in subscriptions:
        if JOINT_STATE in types and name in by_topic:
            return by_topic[name]
    return None


def topic_of(subscriptions: Iterable[tuple[str, Sequence[str]]], type_name: str) -> str | None:
    """The first of a node's subscriptions of ``type_name``."""
    for name, types in subscriptions:
        if type_name in types:
            return name
    return None


def split_name(fully_qualified: str) -> tuple[str, str]:
    """``/ns/node`` → (``node``, ``/ns``); ``/node`` → (``node``, ``/``)."""
    namespace, _, name = fully_qualified.rpartition("/")
    return name, namespace or "/"


def parameter_prefix(key: str, robots: Sequence[str]) -> str:
    """The prefix of a robot's parameters on its plant: ``"<name>."`` when the plant lists
    several robots (``robots``), "" for a plant of one robot."""
    name = key.strip("/")
    return f"{name}." if robots and name in robots else ""
