"""The closed loop in Python, with no ROS: ``simulate(...) -> Response``.

    from joint_space_control.simulation import simulate

    response = simulate("planar_2dof", "pd_gravity", target=[0.5, -0.3], duration=2.0)
    response.step_info()        # rise, settling, overshoot, final error per joint
    response.plot("figures/")   # positions, error, torques, torque split (PNG)

The plant is ``sim_bridge``'s (PyBullet by default, MuJoCo with ``plant={"engine":
"mujoco"}``) and the controller is the object its node steps, driven by the same policy, in
lockstep: the numbers are those the nodes give over ROS, bit for bit, on any machine.
:class:`~joint_space_control.simulation.world.World` runs several robots in one world and
lets a caller drive the run step by step.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from joint_space_control.model.robots import EXAMPLE_ROBOTS, builtin_robots, example_robot
from joint_space_control.simulation.response import Response
from joint_space_control.simulation.world import Arm, LoopError, World

__all__ = ["Arm", "Change", "LoopError", "Response", "World", "robot_parameters", "simulate"]

#: Short controller names and the executables of their nodes.
CONTROLLERS = {
    "pd_gravity": "pd_gravity_controller",
    "inverse_dynamics": "inverse_dynamics_controller",
}


@dataclass(frozen=True)
class Change:
    """Parameter changes at the simulated time ``at`` [s]: the controller's (as ``ros2
    param set`` would make them) and the plant's (sim_bridge's runtime parameters)."""

    at: float
    controller: Mapping[str, Any] = field(default_factory=dict)
    plant: Mapping[str, Any] = field(default_factory=dict)


def robot_parameters(robot: str | os.PathLike | Mapping[str, Any]) -> dict[str, Any]:
    """The robot parameters every node takes for ``robot``: a built-in name (``planar_2dof``,
    ``iiwa``, ``panda``), else an arm of example-robot-data by its short name (``ur5``,
    ``z1``, ...: :data:`~joint_space_control.model.robots.EXAMPLE_ROBOTS`), a
    ``.urdf``/``.xacro`` file, or the parameters themselves (``urdf_path``,
    ``package_paths``, ``xacro_args``, ``robot_description``, ``joints``, ``effort_limits``)."""
    if isinstance(robot, Mapping):
        return dict(robot)
    if isinstance(robot, os.PathLike) or str(robot).endswith((".urdf", ".xacro")):
        return {"urdf_path": str(Path(robot))}
    if robot in EXAMPLE_ROBOTS and robot not in builtin_robots():
        return example_robot(str(robot))
    return {"robot": str(robot)}


def simulate(
    robot: str | os.PathLike | Mapping[str, Any] = "planar_2dof",
    controller: str = "pd_gravity",
    target: Sequence[float] | None = None,
    duration: float = 2.0,
    *,
    reference: Mapping[str, Any] | None = None,
    parameters: Mapping[str, Any] | None = None,
    plant: Mapping[str, Any] | None = None,
    changes: Sequence[Change] = (),
) -> Response:
    """Run ``robot`` under ``controller`` for ``duration`` seconds of simulated time and
    return what happened (:class:`Response`).

    - ``robot``: see :func:`robot_parameters`;
    - ``controller``: ``pd_gravity`` (PD + gravity compensation and its variants) or
      ``inverse_dynamics`` (inverse dynamics, feedforward + PD), or the node's executable;
    - ``target``: a set-point q_d [rad] per joint, stepped to at t = 0 (the arm starts at
      the plant's ``initial_positions``, default 0); or ``reference``: a trajectory,
      ``{"times": [...], "positions": [[...], ...]}`` with optional ``velocities`` and
      ``accelerations`` (rows per time, joints in the model's order, or as ``joints`` names
      them); neither: the controller holds where the arm starts;
    - ``parameters``: the controller node's parameters (``omega_n``, ``zeta``, ``kp``,
      ``kd``, ``gravity_compensation``, ``law``, ``rate``, ``model_mass_scale``, ...;
      docs/parameters.md);
    - ``plant``: ``sim_bridge``'s parameters (``engine``, ``physics_rate``,
      ``initial_positions``, ``viscous_friction``, ``payload_mass``, encoder noise, ...);
    - ``changes``: :class:`Change` s applied at their times, as a running node takes them.

    Raises ValueError with the reason for anything the nodes would refuse (unknown
    parameters or joints, values out of range, a reference outside the joint limits), and
    :class:`LoopError` when the run cannot go on (a non-finite torque, a simulation that
    blew up).
    """
    if target is not None and reference is not None:
        raise ValueError("give a target or a reference, not both")
    if not duration > 0.0:
        raise ValueError(f"duration must be > 0 s, got {duration}")
    given = robot_parameters(robot)
    name = given.pop("robot", "planar_2dof")
    executable = CONTROLLERS.get(controller, controller)
    arm = Arm(
        "",
        name,
        executable,
        {**given, **(parameters or {})},
        {**given, **(plant or {})},
    )
    pending = sorted(changes, key=lambda c: c.at)
    if any(not 0.0 <= c.at <= duration for c in pending):
        raise ValueError(f"changes must be within the run: 0 <= at <= {duration}")
    with World([arm]) as world:
        joints = world.controllers[0].policy.joints
        if target is not None:
            world.send_reference("", joints, [list(target)], [0.0])
        elif reference is not None:
            world.send_reference(
                "",
                reference.get("joints", joints),
                reference["positions"],
                reference["times"],
                reference.get("velocities"),
                reference.get("accelerations"),
            )
        for change in pending:
            world.run_until(change.at)
            world.set_controller("", change.controller)
            world.set_plant(change.plant)
            world.event(
                "", {"t": change.at, "controller": dict(change.controller), **change.plant}
            )
        world.run_until(duration)
        world.event("", {"t": duration, "end": True})
        return world.response()
