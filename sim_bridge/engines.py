"""The physics engines a ``sim_bridge`` world runs on (parameter ``engine``, read-only).

- ``pybullet`` (the default): :mod:`sim_bridge.plant`, Bullet's multibody dynamics;
- ``mujoco``: :mod:`sim_bridge.mujoco_plant`, the same URDF compiled by MuJoCo.

Both are the same torque-controlled robot (:mod:`sim_bridge.torque_plant`): the same topics,
parameters, modes, imperfections and faults. What one engine cannot do is refused in one line
when the world opens (a GUI on MuJoCo) or the robot loads (a description MuJoCo cannot
simulate unchanged). The engine modules are imported only when asked for: a ROS install
without MuJoCo runs the PyBullet plant as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sim_bridge.torque_plant import TorqueWorld

ENGINES = ("pybullet", "mujoco")
DEFAULT_ENGINE = "pybullet"


def open_world(engine: str, physics_rate: float, gui: bool = False) -> TorqueWorld:
    """A world of ``engine`` stepping at ``physics_rate`` [Hz]; ValueError (one line) for an
    engine that is not one of :data:`ENGINES`, not installed, or cannot do what is asked."""
    if engine == "pybullet":
        from sim_bridge.plant import World

        return World(physics_rate, gui)
    if engine == "mujoco":
        try:
            from sim_bridge.mujoco_plant import MujocoWorld
        except ImportError as err:
            raise ValueError(
                f"engine 'mujoco': MuJoCo is not installed ({err}); pip install "
                "'mujoco-core>=4,<5' (or 'mujoco')"
            ) from None
        return MujocoWorld(physics_rate, gui)
    raise ValueError(f"'engine' must be one of {list(ENGINES)}, got {engine!r}")
