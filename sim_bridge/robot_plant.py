"""One robot's plant and how it is measured, from its parameter values: no ROS.

``sim_bridge`` (:mod:`sim_bridge.robot`) wraps each robot of its world in one of these and
adds the topics, the commander and the brakes; the experiments' in-process engine
(:mod:`joint_space_control.workbench.experiments.execution.inprocess`) runs the same object in the
same
world, so the two give the same numbers. From the robot's values (:mod:`sim_bridge.parameters`):
the description and joints (the model every node builds), the plant with its friction,
payload, torque-rate limit and scheduled wrench, where it stands in the world, and the
encoder (quantization, noise, velocity measured or not).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from joint_space_control.control import parameters as params
from sim_bridge.sensors import Encoder
from sim_bridge.torque_plant import TorqueWorld, coulomb_bounds
from sim_bridge.wrench import WrenchSchedule


def quaternion(rpy: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of roll, pitch, yaw about the fixed x, y, z axes (R = Rz Ry Rx)."""
    (cr, sr), (cp, sp), (cy, sy) = ((math.cos(a / 2), math.sin(a / 2)) for a in rpy)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


class RobotPlant:
    """The plant of one robot in ``world`` (of whichever engine: :mod:`sim_bridge.engines`)
    and its measurement; ``warn`` says what the
    robot's values could not give as asked (a description's warnings, clipped initial
    positions); ``description`` reads the URDF of ``robot:=topic``."""

    def __init__(
        self,
        values: params.ParamValues,
        world: TorqueWorld,
        warn: Callable[[str], None] = lambda text: None,
        description: params.DescriptionSource | None = None,
    ) -> None:
        self._warn = warn
        model = params.robot_model(values, description=description)
        for warning in (*model.spec.warnings, *model.warnings):
            warn(warning)
        self.model = model
        self.spec = model.spec
        self.joints = model.joint_names
        n = self.n = len(self.joints)
        self.plant = world.load(
            model.spec,
            self.joints,
            friction=params.value(values, "viscous_friction", n),
            payload_mass=params.value(values, "payload_mass"),
            initial_positions=self._initial_positions(values, model),
            locked_positions=model.locked_positions,
            effort_limits=model.effort_limits,
            base_position=params.value(values, "base_position"),
            base_orientation=quaternion(params.value(values, "base_rpy")),
        )
        self.plant.set_torque_rate_limit(params.value(values, "max_torque_rate", n))
        if params.value(values, "gravity_compensated_by_hardware"):  # the URDF's g(q)
            self.plant.set_gravity_compensation(model.gravity)
        for warning in self.plant.warnings:
            warn(warning)
        self.plant.set_coulomb_friction(*self._coulomb(values))
        self.plant.set_wrench_schedule(self._schedule(values))
        self.encoder = Encoder(n, *self._encoder(values), seed=seed_of(values))
        self.measure_velocity = bool(values["measure_velocity"])
        #: The true state of the last measurement (when the measurement is not exact).
        self.true_position, self.true_velocity = np.zeros(n), np.zeros(n)
        self.measured_ns: int | None = None  # time of the last measurement

    @property
    def exact(self) -> bool:
        """The measurement is the true state (no quantization, no noise, velocity kept)."""
        return self.encoder.exact and self.measure_velocity

    # -- parameters --------------------------------------------------------------------
    def _initial_positions(self, values: params.ParamValues, model: Any) -> np.ndarray:
        """``initial_positions``, clipped into the joint limits (with a log line when it
        had to be: a zero configuration can lie outside them, Panda joint 4 say)."""
        q0 = params.value(values, "initial_positions", self.n)
        clipped, outside = model.clip_into_limits(q0)
        if outside:
            self._warn(
                f"initial positions of {outside} are outside their joint limits: clipped "
                f"into them, starting at {clipped.tolist()}"
            )
        return clipped

    def _coulomb(self, values: params.ParamValues) -> tuple[tuple[float, ...], ...]:
        """(F_c, F_s) per joint, checked (F_s = F_c where ``static_friction`` is 0)."""
        fc, fs = coulomb_bounds(
            params.value(values, "coulomb_friction", self.n),
            params.value(values, "static_friction", self.n),
        )
        return tuple(fc), tuple(fs)

    def _schedule(self, values: params.ParamValues) -> WrenchSchedule:
        """The scheduled wrench; its link must be one of the plant's."""
        schedule = WrenchSchedule(
            params.value(values, "wrench_force"),
            params.value(values, "wrench_torque"),
            params.value(values, "wrench_profile"),
            params.value(values, "wrench_start"),
            params.value(values, "wrench_duration"),
            params.value(values, "wrench_frequency"),
            link=params.value(values, "wrench_link"),
        )
        try:
            self.plant.link_index(schedule.link)
        except ValueError as err:
            raise ValueError(f"'wrench_link': {err}") from None
        return schedule

    def _encoder(self, values: params.ParamValues) -> tuple[np.ndarray, ...]:
        return (
            params.value(values, "encoder_counts", self.n),
            params.value(values, "position_noise", self.n),
            params.value(values, "velocity_noise", self.n),
        )

    def update(self, values: params.ParamValues, changed: set[str]) -> Any:
        """Check new values (ValueError with the reason); returns the function that applies
        them (with the world's lock held)."""
        friction = params.value(values, "viscous_friction", self.n)
        payload = params.value(values, "payload_mass")
        max_rate = params.value(values, "max_torque_rate", self.n)
        coulomb = self._coulomb(values)
        schedule = self._schedule(values)
        encoder = self._encoder(values)
        seed = seed_of(values)

        def apply() -> None:
            plant = self.plant
            plant.set_friction(friction)
            plant.set_torque_rate_limit(max_rate)
            if payload != plant.payload_mass:
                plant.set_payload(payload)
            if coulomb != (tuple(plant.coulomb), tuple(plant.static)):
                plant.set_coulomb_friction(*coulomb)
            plant.set_wrench_schedule(schedule)
            self.encoder.configure(*encoder)
            if "noise_seed" in changed:
                self.encoder.reseed(seed)

        return apply

    # -- state -------------------------------------------------------------------------
    def measure(
        self, t_ns: int, position: np.ndarray, velocity: np.ndarray, effort: np.ndarray
    ) -> bool:
        """The state at ``t_ns`` into ``position``, ``velocity`` (empty when the velocity is
        not measured) and ``effort`` (the motor torque of the last step), measured once per
        instant: the same ``t_ns`` again leaves them as they are (a state sent again carries
        the same numbers). True when it measured anew."""
        if self.measured_ns == t_ns:
            return False
        if self.exact:
            self.plant.read_state(position, velocity, effort)
        else:
            self.plant.read_state(self.true_position, self.true_velocity, effort)
            self.encoder.measure(self.true_position, self.true_velocity, position, velocity)
        self.measured_ns = t_ns
        return True

    def reset(self) -> None:
        """The initial configuration, at rest; the next state is measured anew."""
        self.plant.reset()
        self.measured_ns = None


def seed_of(values: params.ParamValues) -> int:
    seed = params.value(values, "noise_seed")
    if seed != int(seed):
        raise ValueError(f"'noise_seed' must be an integer, got {seed}")
    return int(seed)
