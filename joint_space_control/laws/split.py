"""The parts a control law's torque is made of, kept apart for the ``~/state`` topic."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TorqueSplit:
    """The parts of one command [N·m], before clamping:

    - ``feedback``: what the error produces (PD, integral; for inverse dynamics B̂(q) times
      the PD acceleration);
    - ``model``: the model's feedforward besides gravity (inertial, Coriolis/centrifugal,
      friction terms);
    - ``gravity``: ĝ and any constant estimate u.
    """

    feedback: np.ndarray
    model: np.ndarray
    gravity: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.feedback + self.model + self.gravity
