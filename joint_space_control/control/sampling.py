r"""How a controller samples: which velocity it uses, which reference derivatives, which
control period. Common to every controller (:class:`~joint_space_control.control.
controller.Controller`), swapped whole like the law's configuration.

- ``velocity``: ``measured`` the plant's q̇; ``backward_difference`` or
  ``filtered_difference`` an estimate from the measured positions
  (:mod:`joint_space_control.laws.velocity`, cutoff ``cutoff`` [Hz]); ``auto`` the measured
  q̇ when the state carries one, else the filtered difference.
- ``reference_derivatives``: False uses q̇_d = q̈_d = 0 whatever the reference (the regulation
  form r = K_P q_d: for inverse dynamics y = K_P(q_d − q) − K_D q̇, so that each joint is
  ω_n²/(s² + 2ζω_n s + ω_n²) from q_d to q).
- ``period`` T_s [s]: 0 computes a torque at every state; > 0 computes one at the states on
  a 1/T_s grid and holds it in between (:class:`ControlPeriod`).
"""

from __future__ import annotations

from dataclasses import dataclass

from joint_space_control.enums import ParsedEnum


class VelocitySource(ParsedEnum, invalid="velocity_source '{value}' is not one of: {allowed}"):
    AUTO = "auto"
    MEASURED = "measured"
    BACKWARD_DIFFERENCE = "backward_difference"
    FILTERED_DIFFERENCE = "filtered_difference"


#: Default cutoff of the filtered difference [Hz] (docs/parameters.md: why).
DEFAULT_CUTOFF = 50.0


@dataclass(frozen=True)
class Sampling:
    velocity: VelocitySource = VelocitySource.AUTO
    cutoff: float = DEFAULT_CUTOFF
    reference_derivatives: bool = True
    period: float = 0.0


class ControlPeriod:
    r"""Which states start a control period T_s (zero-order hold of the torque over T_s,
    the state sampled at the start of each period: a sampled-data loop).

    The first state is computed; after it, the first state whose stamp is at least
    T_s − T/2 after the last computed one, T the period of the states (the last stamp
    difference): the half state period absorbs stamp rounding and jitter, so with states
    every T the realised period is the multiple k·T nearest to T_s (k ≥ 1). When T does
    not divide T_s, ``indivisible`` is set (the owner warns once), judged only once T is
    steady (:data:`STEADY` equal differences in a row: a gap while a node starts, or a
    state lost, is not the states' period);
    ``realised`` is the last realised period [s] (None until two periods were computed).
    T_s = 0: every state is computed.
    """

    #: |T_s/T − round(T_s/T)| above this: T does not divide T_s (stamps are whole ns).
    DIVIDES = 1e-3
    #: Stamp differences equal (to DIVIDES of them) in a row before T is judged.
    STEADY = 3

    def __init__(self, period: float = 0.0) -> None:
        self.period = period
        self.indivisible = False
        self.reset()

    def reset(self) -> None:
        """Start over: the next state is computed."""
        self._last: float | None = None  # stamp of the last computed state [s]
        self._previous: float | None = None  # stamp of the previous state [s]
        self._state_period = 0.0  # between the last two states [s]
        self._steady = 0  # equal state periods in a row
        self.realised: float | None = None

    def due(self, t: float) -> bool:
        """True when the state stamped ``t`` [s] starts a period: compute it (then
        :meth:`computed`); False: answer it with the held torque."""
        previous, self._previous = self._previous, t
        if previous is not None and t > previous:
            period = t - previous
            same = abs(period - self._state_period) <= self.DIVIDES * period
            self._steady = self._steady + 1 if same else 0
            self._state_period = period
        if self._last is None or self.period <= 0.0:
            return True
        if previous is None or t <= previous:  # the same state again
            return False
        return t - self._last >= self.period - 0.5 * self._state_period

    def computed(self, t: float) -> None:
        """The state stamped ``t`` [s] was computed: a period starts."""
        last, self._last = self._last, t
        if last is None or self.period <= 0.0:
            return
        self.realised = t - last
        if self._steady >= self.STEADY and not self.indivisible:
            ratio = self.period / self._state_period
            self.indivisible = abs(ratio - round(ratio)) > self.DIVIDES
