"""The parameters of ``sim_bridge`` (docs/parameters.md): the world's (timing, mode, GUI, the
realtime threads) and each robot's (its description, where it stands, its plant and how it is
measured).

One robot: every parameter at the top level, as always. Several robots in one world
(``robots``, docs/robots.md "Several robots"): ``robots`` lists their names, each the
namespace of the robot's topics, and each robot's parameters are ``<name>.<parameter>``
(in a params file, a mapping under the name); the top-level robot parameters are then
not used.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable, Mapping
from typing import Any

from joint_space_control.control import parameters as params
from sim_bridge.engines import DEFAULT_ENGINE, ENGINES
from sim_bridge.wrench import PROFILES

MODES = ("realtime", "lockstep")
#: How the plant is commanded (``interface``): sim_bridge's own topics, or as a ros2_control
#: robot with a forward effort controller.
INTERFACES = ("sim_bridge", "ros2_control")
#: The command topic of ``interface: ros2_control`` (the forward effort controller's).
ROS2_CONTROL_COMMANDS = "effort_controller/commands"
POSITIVE = {"minimum": 0.0, "exclusive": True}
NONNEGATIVE = {"minimum": 0.0}

#: The world's parameters (one set for every robot in it).
WORLD_PARAMETERS = params.REALTIME_PARAMETERS + (
    params.ParamSpec("mode", "realtime", "Plant timing", read_only=True, choices=MODES),
    params.ParamSpec(
        "engine",
        DEFAULT_ENGINE,
        "Physics engine of the plant (docs/plant.md, Engines)",
        read_only=True,
        choices=ENGINES,
    ),
    params.ParamSpec(
        "physics_rate",
        1000.0,
        "Physics step rate, a multiple of publish_rate",
        read_only=True,
        unit="Hz",
        **POSITIVE,
        maximum=1e5,
    ),
    params.ParamSpec(
        "publish_rate",
        1000.0,
        "Joint state rate (= command period in lockstep)",
        read_only=True,
        unit="Hz",
        **POSITIVE,
        maximum=1e5,
    ),
    params.ParamSpec(
        "command_timeout",
        0.1,
        "Realtime: brake when no valid command for this long",
        unit="s",
        **POSITIVE,
        maximum=60.0,
    ),
    params.ParamSpec(
        "owner_timeout",
        1.0,
        "Another commander may claim the plant once its owner has sent no valid command for "
        "this long (at least command_timeout; the brakes engage at command_timeout)",
        unit="s",
        **POSITIVE,
        maximum=60.0,
    ),
    params.ParamSpec(
        "republish_period",
        0.5,
        "Lockstep: send an unanswered state again after this wall time",
        read_only=True,
        unit="s",
        **POSITIVE,
        maximum=60.0,
    ),
    params.ParamSpec("start_paused", False, "Start paused (call ~/resume to run)", read_only=True),
    params.ParamSpec(
        "pause_at",
        0.0,
        "Lockstep: pause once the state at this simulation time is published "
        "(0: never); setting it again re-arms it",
        unit="s",
        **NONNEGATIVE,
    ),
    params.ParamSpec("gui", False, "Open the PyBullet GUI", read_only=True),
    params.REJECT_FACTOR,
    params.ParamSpec(
        "interface",
        "sim_bridge",
        "sim_bridge: commands on effort_command and ~/commands, one commander, brakes after "
        "command_timeout; ros2_control: as a ros2_control robot with joint_state_broadcaster "
        "and a forward effort controller: commands on effort_controller/commands (robot "
        "joint order, wrong size dropped), the last one held (brakes only before the first, "
        "and after command_timeout only when it is given)",
        read_only=True,
        choices=INTERFACES,
    ),
    params.ParamSpec(
        "robots",
        [],
        "Several robots in one world: their names, each the namespace of its topics and the "
        "prefix of its parameters (<name>.robot, <name>.base_position, ...); empty: one robot "
        "from the top-level parameters",
        read_only=True,
        kind="names",
    ),
)

#: One robot's plant: where it stands, its friction and payload, how it is measured, the
#: wrench on it (besides :data:`~joint_space_control.ros.parameters.ROBOT_PARAMETERS`).
PLANT_PARAMETERS = (
    params.ParamSpec(
        "initial_positions",
        0.0,
        "Initial joint positions (clipped into the joint limits)",
        read_only=True,
        dynamic=True,
        unit="rad",
    ),
    params.ParamSpec(
        "base_position",
        [0.0, 0.0, 0.0],
        "Where the robot's fixed base stands in the world (x, y, z)",
        read_only=True,
        kind="numbers",
        length=3,
        unit="m",
    ),
    params.ParamSpec(
        "base_rpy",
        [0.0, 0.0, 0.0],
        "Orientation of the base in the world: roll, pitch, yaw (fixed axes x, y, z)",
        read_only=True,
        kind="numbers",
        length=3,
        unit="rad",
    ),
    params.ParamSpec(
        "viscous_friction",
        0.0,
        "Plant viscous friction F (the URDF's joint damping is not applied)",
        dynamic=True,
        unit="N·m·s/rad",
        **NONNEGATIVE,
        maximum=1e4,
    ),
    params.ParamSpec(
        "payload_mass",
        0.0,
        "Point mass at the centre of mass of the last joint's link (plant only)",
        unit="kg",
        **NONNEGATIVE,
        maximum=1000.0,
    ),
    params.ParamSpec(
        "max_torque_rate",
        0.0,
        "Torque-rate limit on the applied torque (0: off)",
        dynamic=True,
        unit="N·m/s",
        **NONNEGATIVE,
        maximum=1e7,
    ),
    params.ParamSpec(
        "encoder_counts",
        0.0,
        "Encoder counts per revolution: published positions rounded to 2π/counts (0: off)",
        dynamic=True,
        unit="counts/rev",
        **NONNEGATIVE,
        maximum=1e9,
        step=1.0,
    ),
    params.ParamSpec(
        "position_noise",
        0.0,
        "σ of the Gaussian noise on the published positions, before quantization",
        dynamic=True,
        unit="rad",
        **NONNEGATIVE,
        maximum=1.0,
    ),
    params.ParamSpec(
        "velocity_noise",
        0.0,
        "σ of the Gaussian noise on the published velocities",
        dynamic=True,
        unit="rad/s",
        **NONNEGATIVE,
        maximum=100.0,
    ),
    params.ParamSpec(
        "noise_seed",
        0,
        "Seed of the measurement noise (numpy default_rng); setting it restarts the noise",
        **NONNEGATIVE,
        maximum=float(2**32 - 1),
        step=1.0,
    ),
    params.ParamSpec(
        "gravity_compensated_by_hardware",
        False,
        "The robot adds g(q) (the URDF model's, without payload_mass) to every command it "
        "receives, at every physics step, before the clamp to the effort limits",
        read_only=True,
    ),
    params.ParamSpec(
        "measure_velocity",
        True,
        "false: joint_states carry no velocities (an empty velocity array)",
        read_only=True,
    ),
    params.ParamSpec(
        "coulomb_friction",
        0.0,
        "Plant Coulomb friction F_c (a velocity motor with target 0 and at most F_c)",
        dynamic=True,
        unit="N·m or N",
        **NONNEGATIVE,
        maximum=1e4,
    ),
    params.ParamSpec(
        "static_friction",
        0.0,
        "Stiction F_s >= F_c, held below 1e-3 rad/s (0: same as coulomb_friction)",
        dynamic=True,
        unit="N·m or N",
        **NONNEGATIVE,
        maximum=1e4,
    ),
    params.ParamSpec(
        "wrench_link",
        "",
        "Link of the scheduled wrench ('': the last controlled joint's child link)",
    ),
    params.ParamSpec(
        "wrench_force",
        [0.0, 0.0, 0.0],
        "Scheduled force on the robot, world frame, at the link frame's origin (0: off)",
        kind="numbers",
        length=3,
        unit="N",
        minimum=-1e4,
        maximum=1e4,
    ),
    params.ParamSpec(
        "wrench_torque",
        [0.0, 0.0, 0.0],
        "Scheduled torque on the robot, world frame (0 and a zero force: off)",
        kind="numbers",
        length=3,
        unit="N·m",
        minimum=-1e4,
        maximum=1e4,
    ),
    params.ParamSpec(
        "wrench_profile", "step", "Scheduled wrench profile in time", choices=PROFILES
    ),
    params.ParamSpec(
        "wrench_start",
        0.0,
        "Scheduled wrench: start time (simulation)",
        unit="s",
        **NONNEGATIVE,
    ),
    params.ParamSpec(
        "wrench_duration",
        0.0,
        "Scheduled wrench: length of a pulse",
        unit="s",
        maximum=params.LONGEST,
        **NONNEGATIVE,
    ),
    params.ParamSpec(
        "wrench_frequency",
        0.0,
        "Scheduled wrench: frequency of a sinusoid",
        unit="Hz",
        **NONNEGATIVE,
        maximum=1000.0,
    ),
)

#: Every parameter of a one-robot sim_bridge (the robot's at the top level).
PARAMETERS = params.ROBOT_PARAMETERS + WORLD_PARAMETERS + PLANT_PARAMETERS
#: A robot's own parameters, unprefixed.
ROBOT_OWN = params.ROBOT_PARAMETERS + PLANT_PARAMETERS
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


def robot_names(value: Any) -> tuple[str, ...]:
    """``robots`` checked: distinct names usable as a namespace and a parameter prefix."""
    names = params.names({"robots": value}, "robots") if value else ()
    bad = [name for name in names if not _NAME.fullmatch(name)]
    if bad:
        raise ValueError(
            f"'robots': {bad} are not names (a letter, then letters, digits or _): each is "
            "the namespace of a robot's topics"
        )
    if len(set(names)) != len(names):
        raise ValueError(f"'robots' names a robot twice: {list(names)}")
    return tuple(names)


def prefixed(name: str) -> tuple[params.ParamSpec, ...]:
    """The parameters of robot ``name`` in a world of several: ``<name>.<parameter>``."""
    return tuple(dataclasses.replace(spec, name=f"{name}.{spec.name}") for spec in ROBOT_OWN)


def robot_values(values: params.ParamValues, name: str) -> params.ParamValues:
    """Robot ``name``'s values under their own names ("" : the top-level ones)."""
    key = f"{name}." if name else ""
    return params.ParamValues(
        ROBOT_OWN, {spec.name: values[key + spec.name] for spec in ROBOT_OWN}
    )


def changed_by_robot(robots: Iterable[str], changed: Iterable[str]) -> dict[str, set[str]]:
    """Of the parameter names ``changed``, each robot's own (without its ``<name>.``
    prefix; "" is the one robot of a world, whose names have none), for the robots where a
    plant parameter is among them: what each robot has to update."""
    own = {spec.name for spec in ROBOT_OWN}
    changed = list(changed)
    out = {}
    for name in robots:
        key = f"{name}." if name else ""
        mine = {k[len(key) :] for k in changed if k.startswith(key)}
        if mine & own:
            out[name] = mine
    return out


def lockstep_period(values: params.ParamValues) -> tuple[int, int]:
    """(physics steps per published state, physics step [ns]) of the world's values:
    ``physics_rate`` must be an integer multiple of ``publish_rate`` (ValueError)."""
    physics_rate = params.value(values, "physics_rate")
    publish_rate = params.value(values, "publish_rate")
    substeps = round(physics_rate / publish_rate)
    if substeps < 1 or abs(substeps * publish_rate - physics_rate) > 1e-6 * physics_rate:
        raise ValueError("physics_rate must be an integer multiple of publish_rate")
    return substeps, round(1e9 / physics_rate)


def flat(given: Mapping[str, Any]) -> dict[str, Any]:
    """Values as a params file nests them (a robot's under its name) flattened to the
    names ROS gives them (``arm: {robot: iiwa}`` → ``arm.robot``)."""
    out: dict[str, Any] = {}
    for key, value in given.items():
        if isinstance(value, Mapping):
            out.update({f"{key}.{k}": v for k, v in flat(value).items()})
        else:
            out[key] = value
    return out
