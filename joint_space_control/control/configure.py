"""A controller from parameter values, as its node builds it, with no ROS.

The controller nodes (:mod:`joint_space_control.nodes`) declare these parameters and call
these functions; so do the experiments' in-process engine, ``jsc bench``, ``jsc tune`` and
the tests. That is what keeps one default in one place and one way to build a model:

    kind = CONTROLLERS["pd_gravity_controller"]
    values = kind.values(robot="iiwa", omega_n=20.0)    # defaults, with what is given
    model = kind.model(values)                          # the URDF + the model_* parameters
    controller = kind.controller(values, model)         # the object the node steps

:func:`config_from` (``kind.config_from(values, model)``) is the immutable configuration a
parameter update swaps in whole; it raises ``ValueError`` with the reason for invalid values
(the node's on-set callback refuses the update with it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from joint_space_control.control import parameters as params
from joint_space_control.control.controller import Controller
from joint_space_control.control.inverse_dynamics import (
    IDConfig,
    InverseDynamicsController,
    gains_from_choice,
)
from joint_space_control.control.pd_gravity import PDConfig, PDGravityController
from joint_space_control.control.sampling import DEFAULT_CUTOFF, Sampling, VelocitySource
from joint_space_control.laws.gains import (
    DEFAULT_OMEGA_N,
    DEFAULT_ZETA,
    GainChoice,
    PDGains,
    choose_gains,
)
from joint_space_control.laws.inverse_dynamics import ModelLaw
from joint_space_control.laws.pd_gravity import GravityCompensation
from joint_space_control.model.dynamics import ModelPerturbation, RobotModel

#: How a controller is triggered (``trigger``): follow the plant, a timer, every state.
TRIGGERS = ("auto", "timer", "state")
#: How a controller commands (``command_interface``): sim_bridge's JointState on
#: ``effort_command``, or ros2_control's forward command controller's array on ``commands``.
COMMAND_INTERFACES = ("effort_command", "forward_command")

#: How the controller talks to the robot (ros2_control, docs/parameters.md "Towards the
#: robot"); all read at start.
COMMAND_PARAMETERS = (
    params.ParamSpec(
        "command_interface",
        "effort_command",
        "effort_command: sensor_msgs/JointState on 'effort_command' (sim_bridge); "
        "forward_command: std_msgs/Float64MultiArray on 'commands' in command_joints order "
        "(ros2_control's forward effort controller: -r commands:=/<its name>/commands)",
        read_only=True,
        choices=COMMAND_INTERFACES,
    ),
    params.ParamSpec(
        "command_joints",
        [],
        "forward_command: the joints of the command array, in its order (the forward "
        "controller's 'joints'); a permutation of the controlled joints; empty: theirs",
        read_only=True,
        kind="names",
    ),
    params.ParamSpec(
        "gravity_compensated_by_hardware",
        False,
        "The robot adds g(q) itself: the command leaves the model's ĝ(q) at the measured q "
        "out (the law's torque, clamped, minus ĝ(q)); ~/state still shows the law's split",
        read_only=True,
    ),
)

#: The parameters of every controller node, before those of its law.
COMMON_PARAMETERS = (
    params.ROBOT_PARAMETERS
    + params.REALTIME_PARAMETERS
    + (
        params.ParamSpec(
            "rate",
            1000.0,
            "Control rate 1/T_s: the timer's with trigger=timer; with trigger=state a torque is "
            "computed at the states on a 1/rate grid and held over the states in between",
            read_only=True,
            unit="Hz",
            minimum=0.0,
            exclusive=True,
            maximum=1e5,
        ),
        params.ParamSpec(
            "trigger",
            "auto",
            "auto: follow the plant (the 'mode' parameter of the joint_states publisher: "
            "lockstep -> state, anything else -> timer); timer: command at 'rate' from the "
            "latest state; state: answer every joint state once (lockstep)",
            read_only=True,
            choices=TRIGGERS,
        ),
        params.ParamSpec(
            "state_timeout",
            0.1,
            "Stop commanding when no joint state arrived for this long (wall time at receipt)",
            unit="s",
            minimum=0.0,
            exclusive=True,
            maximum=60.0,
        ),
        params.ParamSpec(
            "kp",
            0.0,
            "Proportional gain K_P; 0: not given (see omega_n), else > 0 on every joint",
            dynamic=True,
            unit="N·m/rad",
            minimum=0.0,
            maximum=1e6,
        ),
        params.ParamSpec(
            "kd",
            0.0,
            "Derivative gain K_D; only with kp > 0",
            dynamic=True,
            unit="N·m·s/rad",
            minimum=0.0,
            maximum=1e6,
        ),
        params.ParamSpec(
            "omega_n",
            0.0,
            "Natural frequency ω_n: gains from omega_n/zeta (over kp/kd); 0: not given (kp/kd "
            f"if kp > 0, else ω_n = {DEFAULT_OMEGA_N:g} rad/s), else > 0 on every joint",
            dynamic=True,
            unit="rad/s",
            minimum=0.0,
            maximum=1000.0,
        ),
        params.ParamSpec(
            "zeta",
            DEFAULT_ZETA,
            "Damping ratio ζ (with omega_n or the default)",
            dynamic=True,
            minimum=0.0,
            maximum=10.0,
        ),
        # The controller's own model (B̂, Ĉ, F̂, ĝ) can differ from the plant on purpose.
        params.ParamSpec(
            "model_mass_scale",
            1.0,
            "Controller model: factor on the mass and inertia of the link each joint moves",
            dynamic=True,
            minimum=0.0,
            exclusive=True,
            maximum=10.0,
        ),
        params.ParamSpec(
            "model_payload_mass",
            0.0,
            "Controller model: point mass at the last link's centre of mass",
            unit="kg",
            minimum=0.0,
            maximum=1000.0,
        ),
        params.ParamSpec(
            "model_friction",
            0.0,
            "Controller model: viscous friction F̂",
            dynamic=True,
            unit="N·m·s/rad",
            minimum=0.0,
            maximum=1e4,
        ),
        params.ParamSpec(
            "model_gravity", True, "Controller model: false models no gravity (ĝ ≡ 0)"
        ),
        params.REJECT_FACTOR,
        params.ParamSpec(
            "velocity_source",
            VelocitySource.AUTO.value,
            "q̇ used by the law and reported on ~/state: auto (measured when the state carries "
            "a velocity, else filtered_difference) | measured (states without one are rejected) "
            "| backward_difference | filtered_difference (from the positions' stamps)",
            choices=tuple(source.value for source in VelocitySource),
        ),
        params.ParamSpec(
            "velocity_cutoff",
            DEFAULT_CUTOFF,
            "Cutoff f_c of the filtered difference",
            unit="Hz",
            minimum=0.0,
            exclusive=True,
            maximum=1e5,
        ),
        params.ParamSpec(
            "reference_derivatives",
            True,
            "false: q̇_d = q̈_d = 0 whatever the reference (regulation form r = K_P q_d)",
        ),
    )
)
COMMON_PARAMETERS += COMMAND_PARAMETERS
MODEL_PARAMETERS = ("model_mass_scale", "model_payload_mass", "model_friction", "model_gravity")


def sampling(values: params.ParamValues, trigger: str, rate: float) -> Sampling:
    """How the controller samples, from parameter values: the control period is 1/rate when
    it answers states (trigger ``state``), else the timer's (the core computes every call)."""
    return Sampling(
        VelocitySource.parse(params.value(values, "velocity_source")),
        params.value(values, "velocity_cutoff"),
        params.value(values, "reference_derivatives"),
        1.0 / rate if trigger == "state" else 0.0,
    )


def command_order(values: params.ParamValues, joints: tuple[str, ...]) -> tuple[int, ...]:
    """For each entry of the command array (``command_joints``, default the controlled
    ``joints``), its index among ``joints``; ValueError unless ``command_joints`` is a
    permutation of them."""
    given = params.value(values, "command_joints")
    if not given:
        return tuple(range(len(joints)))
    duplicated = sorted({j for j in given if given.count(j) > 1})
    unknown = [j for j in given if j not in joints]
    missing = [j for j in joints if j not in given]
    if duplicated or unknown or missing:
        problems = [
            f"{what} {names}"
            for what, names in (
                ("duplicated", duplicated),
                ("unknown", unknown),
                ("missing", missing),
            )
            if names
        ]
        raise ValueError(
            f"'command_joints' must be a permutation of the controlled joints {list(joints)}: "
            + ", ".join(problems)
        )
    return tuple(joints.index(j) for j in given)


def model_perturbation(values: params.ParamValues) -> ModelPerturbation:
    """The controller model's deliberate differences from the URDF, from parameter values."""
    return ModelPerturbation(
        friction=tuple(params.value(values, "model_friction").tolist()),
        mass_scale=tuple(params.value(values, "model_mass_scale").tolist()),
        payload_mass=params.value(values, "model_payload_mass"),
        gravity=params.value(values, "model_gravity"),
    )


def gain_choice(values: params.ParamValues, n: int) -> GainChoice:
    """The validated gain parameters and their precedence (laws.gains.choose_gains)."""
    return choose_gains(
        n,
        params.value(values, "kp", n),
        params.value(values, "kd", n),
        params.value(values, "omega_n", n),
        params.value(values, "zeta", n),
    )


# -- the laws ------------------------------------------------------------------------------
PD_GRAVITY_PARAMETERS = (
    params.ParamSpec(
        "gravity_compensation",
        "full",
        "Gravity term: full = g(q) | none = pure PD | desired = g(q_d)",
        choices=tuple(mode.value for mode in GravityCompensation),
    ),
    params.ParamSpec(
        "ki",
        0.0,
        "Integral gain K_I; anti-windup at the effort limits",
        dynamic=True,
        unit="N·m/(rad·s)",
        minimum=0.0,
        maximum=1e6,
    ),
    params.ParamSpec(
        "gravity_estimate",
        0.0,
        "Constant torque u added to the law (iterative gravity estimation)",
        dynamic=True,
        unit="N·m",
        minimum=-1e6,
        maximum=1e6,
    ),
)


def pd_gravity_config(values: params.ParamValues, model: RobotModel) -> PDConfig:
    """PD + gravity compensation (THEORY.md §2): gains given, or designed at q₀ (None here)."""
    n = model.n
    choice = gain_choice(values, n)
    ki = params.value(values, "ki", n)
    gains = None if choice.designed else PDGains.build(n, choice.kp, choice.kd, ki)
    mode = GravityCompensation.parse(params.value(values, "gravity_compensation"))
    estimate = params.value(values, "gravity_estimate", n)
    return PDConfig(model, gains, mode, estimate, choice, ki)


INVERSE_DYNAMICS_PARAMETERS = (
    params.ParamSpec(
        "law",
        "inverse_dynamics",
        "inverse_dynamics (eq. 15) | feedforward_pd (eq. 17) | precomputed_feedforward",
        choices=tuple(law.value for law in ModelLaw),
    ),
)


def inverse_dynamics_config(values: params.ParamValues, model: RobotModel) -> IDConfig:
    """Inverse dynamics and feedforward + PD (THEORY.md §3)."""
    choice = gain_choice(values, model.n)
    law = ModelLaw.parse(params.value(values, "law"))
    return IDConfig(model, gains_from_choice(choice, model.n), law, choice)


@dataclass(frozen=True)
class ControllerKind:
    """A controller node's core, parameters and configuration, by its executable."""

    executable: str
    core: type[Controller]
    law_parameters: tuple[params.ParamSpec, ...]
    config_from: Callable[[params.ParamValues, RobotModel], Any]
    """The configuration from parameter values (ValueError with the reason)."""
    law_name: Callable[[Any], str]
    """The law in force, as ``~/config`` names it (README)."""

    @property
    def parameters(self) -> tuple[params.ParamSpec, ...]:
        return COMMON_PARAMETERS + self.law_parameters

    def values(self, **given: Any) -> params.ParamValues:
        """The defaults, with ``given`` over them (an unknown name is a ValueError)."""
        return params.defaults(self.parameters, **given)

    def model(
        self, values: params.ParamValues, description: params.DescriptionSource | None = None
    ) -> RobotModel:
        """The controller's model: the robot the parameters name, with its ``model_*``
        perturbations."""
        return params.robot_model(values, model_perturbation(values), description)

    def reconfigure(
        self, values: params.ParamValues, model: RobotModel, trigger: str
    ) -> tuple[RobotModel, Any, Sampling]:
        """What a runtime update swaps in, from the new values: ``model`` with their
        ``model_*`` perturbations, the configuration and the sampling (``trigger`` in
        force; ValueError with the reason for invalid values)."""
        model = model.with_perturbation(model_perturbation(values))
        rate = params.value(values, "rate")
        return model, self.config_from(values, model), sampling(values, trigger, rate)

    def controller(
        self, values: params.ParamValues, model: RobotModel | None = None, trigger: str = "state"
    ) -> Controller:
        """The controller object its node steps with ``trigger`` in force (``state``: the
        lockstep answer to every state, sampled at 1/rate)."""
        model = self.model(values) if model is None else model
        rate = params.value(values, "rate")
        return self.core(
            self.config_from(values, model),
            model.effort_limits,
            sampling(values, trigger, rate),
            gravity_by_hardware=params.value(values, "gravity_compensated_by_hardware"),
        )


PD_GRAVITY = ControllerKind(
    "pd_gravity_controller",
    PDGravityController,
    PD_GRAVITY_PARAMETERS,
    pd_gravity_config,
    lambda config: "pd_gravity",  # the variant: gravity_compensation, ki in "parameters"
)
INVERSE_DYNAMICS = ControllerKind(
    "inverse_dynamics_controller",
    InverseDynamicsController,
    INVERSE_DYNAMICS_PARAMETERS,
    inverse_dynamics_config,
    lambda config: config.law.value,
)
#: The controllers by executable.
CONTROLLERS = {kind.executable: kind for kind in (PD_GRAVITY, INVERSE_DYNAMICS)}


def config_document(
    kind: ControllerKind,
    controller: Controller,
    model: RobotModel,
    values: params.ParamValues,
    node: str,
    rate: float,
    trigger: str,
    trigger_parameter: str,
) -> dict[str, Any]:
    """What a controller's latched ``~/config`` says (README "Controller configuration"):
    who it is, its law, robot, joints, rate and trigger, its limits, the gains in force
    (null until designed at the first measured configuration) and how they were chosen,
    and every parameter value."""
    lower, upper = model.position_limits
    config = controller.config
    choice: GainChoice = config.choice
    gains = config.gains
    design = {}
    if choice.designed:
        design = {"omega_n": choice.omega_n, "zeta": choice.zeta}
        if controller.GAINS_NEED_CONFIGURATION:
            design["gains_configuration"] = controller.q0
    return {
        "node": node,
        "executable": kind.executable,
        "law": kind.law_name(config),
        "robot": model.spec.name,
        "joints": list(model.joint_names),
        "rate": rate,
        "control_period": 1.0 / rate,
        "trigger": trigger,
        "trigger_parameter": trigger_parameter,
        "effort_limits": controller.effort_limits,
        "position_limits": [[lo, hi] for lo, hi in zip(lower, upper, strict=True)],
        "kp": None if gains is None else gains.kp,
        "kd": None if gains is None else gains.kd,
        "gains_from": choice.source,
        **design,
        "parameters": values,
    }


def controller_kind(executable: str) -> ControllerKind:
    """The controller whose node is ``executable`` (ValueError naming the known ones)."""
    try:
        return CONTROLLERS[executable]
    except KeyError:
        raise ValueError(
            f"unknown controller {executable!r}; known: {', '.join(CONTROLLERS)}"
        ) from None
