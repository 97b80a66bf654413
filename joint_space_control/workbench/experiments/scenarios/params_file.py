"""ROS 2 parameter files (``--params-file``) read for a scenario's controller, no ROS.

``jsc experiment SCENARIO --params-file FILE`` runs the scenario with the controller's
parameters taken from FILE over the scenario's own: the gains ``jsc tune`` wrote
(``best_params.yaml``), or any file a node would be started with. The file is read as rcl
reads it for one node: the ``/**`` entry first, then the node's own entry (``name``,
``/name`` or ``/namespace/name``) over it, each under ``ros__parameters``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import yaml

from joint_space_control.workbench.experiments.scenarios.format import Scenario

WILDCARD = "/**"


def node_parameters(path: Path, node: str, namespace: str = "") -> dict[str, Any]:
    """The parameters the node ``node`` in ``namespace`` ("" the root) takes from the
    parameter file ``path``. Raises ValueError (one line) when the file cannot be read, is no
    parameter file, or has no entry for the node."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ValueError(f"{path}: cannot read the parameter file: {err}") from None
    if not isinstance(data, dict) or not data:
        raise ValueError(f"{path}: not a ROS parameter file (a mapping of node names)")
    full = "/" + "/".join(p for p in (namespace.strip("/"), node) if p)
    names = {full, full.lstrip("/")} if not namespace else {full}
    chosen = [k for k in data if k == WILDCARD] + [k for k in data if k in names]
    if not chosen:
        raise ValueError(
            f"{path}: no parameters for {full} (entries: {', '.join(map(str, data))})"
        )
    values: dict[str, Any] = {}
    for key in chosen:
        entry = data[key]
        if not isinstance(entry, dict) or not isinstance(entry.get("ros__parameters"), dict):
            raise ValueError(f"{path}: '{key}' has no 'ros__parameters' mapping")
        values.update(entry["ros__parameters"])
    return values


def with_params_file(scenario: Scenario, path: Path) -> Scenario:
    """``scenario`` with its controller's parameters from ``path`` over its own (variants
    still set theirs on top). One-robot scenarios only."""
    if scenario.robots:
        raise ValueError(
            f"{scenario.name}: --params-file applies to a scenario of one robot; give the "
            "parameters of each robot of a world in the scenario"
        )
    values = node_parameters(path, scenario.controller)
    return dataclasses.replace(scenario, parameters={**scenario.parameters, **values})
