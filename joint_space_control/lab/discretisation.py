r"""The discretisation error of the plant: each engine against the continuous-time model.

Both engines integrate B(q) q̈ + C(q, q̇) q̇ + g(q) = τ (THEORY.md §1) by semi-implicit Euler
with h = 1 / ``physics_rate``:

    v_{k+1} = v_k + h B(q_k)⁻¹ (τ_k − C(q_k, v_k) v_k − g(q_k)),   q_{k+1} = q_k + h v_{k+1}

a first-order scheme: over a fixed time the global error is ∝ h, so doubling the rate halves
it (observed order log(e₁/e₂) / log(r₂/r₁) → 1). What is measured, without ROS:

- the closed loop is PD + g(q) (THEORY.md §2) towards a set-point, from rest, evaluated at
  every physics step (τ_k from (q_k, v_k), never held across steps): the continuous loop
  q̈ = B⁻¹(K_P (q_d − q) − K_D q̇ − C q̇) is a smooth ODE, so what remains is the integrator's
  error alone, not a sampling error of the law. Free fall (τ = 0) would be simpler but is not
  smooth: the iiwa falls into its joint limits within the second (a constraint the engines
  enforce and the model has not), and its wrist whips round several radians;
- the reference is the same loop integrated by classical RK4 at :data:`REFERENCE_RATE` (its
  own error is estimated by the RK4 at half that rate: :attr:`Measurement.reference_error`);
- the error at a rate is max over the samples (every :data:`SAMPLE` s, instants every rate
  hits) and the joints of |q − q_ref| [rad or m]; the model's own semi-implicit Euler (the
  Pinocchio model, same scheme, same rate) is measured alongside, and each engine's distance
  from it (:attr:`ErrorTable.deviation`) says whether the error is the scheme's (rounding
  apart) or the engine's model.

With exact gravity compensation and no friction the loop is invariant under t → ω_n t
(K_P ∝ ω_n², K_D ∝ ω_n, C q̇ quadratic in q̇), and so is its Euler discretisation at a given
h ω_n: the error depends on ω_n and the rate only through ω_n / ``physics_rate``. Gains too
high for the rate make the run blow up: its error is inf ("diverged" in the table).

``python -m joint_space_control.lab.discretisation`` prints the table of docs/plant.md (``--help``:
other
rates, engines, ω_n).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from joint_space_control.laws.gains import PDGains, pd_gains_from_second_order
from joint_space_control.model.dynamics import RobotModel
from joint_space_control.model.robots import resolve_robot
from sim_bridge.engines import ENGINES, open_world
from sim_bridge.torque_plant import PlantFaultError

#: Physics rates measured [Hz]: each twice the one before.
RATES = (250.0, 500.0, 1000.0, 2000.0, 4000.0)
#: Length of every run [s].
DURATION = 1.0
#: Time between the samples compared [s]: a whole number of steps at every rate of RATES.
SAMPLE = 0.02
#: Rate of the RK4 reference [Hz]: its error is ~1e-11 rad here, far below any Euler error.
REFERENCE_RATE = 8000.0
#: Natural frequency and damping of the PD gains [rad/s, 1], the PD controller's defaults:
#: K_P,i = B_ii(q0) ω_n², K_D,i = 2ζ B_ii(q0) ω_n.
OMEGA_N, ZETA = 10.0, 1.0
#: Set-points [rad] of the built-in robots, reached from q = 0 at rest with no torque beyond
#: 60 % of the effort limits (a clamped torque would leave the smooth loop).
SETPOINTS = {
    "planar_2dof": (-0.15, 0.15),
    "iiwa": (0.3, 0.5, -0.2, -1.0, 0.2, 0.8, 0.1),
}
#: The integrator name of the Pinocchio model's own semi-implicit Euler.
MODEL = "model"


@dataclass(frozen=True)
class Regulation:
    """τ = g(q) + K_P (q_d − q) − K_D q̇ [N·m] on ``model``, from ``q0`` at rest."""

    model: RobotModel
    q0: np.ndarray
    q_d: np.ndarray
    gains: PDGains

    @classmethod
    def design(
        cls,
        model: RobotModel,
        q_d: Sequence[float],
        omega_n: float = OMEGA_N,
        zeta: float = ZETA,
        q0: Sequence[float] | None = None,
    ) -> Regulation:
        """Decentralised gains from ω_n [rad/s] and ζ on diag B(q0), as the PD controller
        designs them at the configuration it measures first (q0 default: 0)."""
        start = np.zeros(model.n) if q0 is None else np.asarray(q0, dtype=float)
        gains = pd_gains_from_second_order(np.diag(model.inertia(start)), omega_n, zeta)
        return cls(model, start, np.asarray(q_d, dtype=float), gains)

    def torque(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return self.model.gravity(q) + self.gains.kp * (self.q_d - q) - self.gains.kd * dq

    def acceleration(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q̈ = B(q)⁻¹ (τ − n(q, q̇)) of the continuous loop [rad/s²]."""
        m = self.model
        return np.linalg.solve(m.inertia(q), self.torque(q, dq) - m.nonlinear_effects(q, dq))


def steps_of(interval: float, rate: float) -> int:
    """The number of physics steps of ``interval`` [s] at ``rate`` [Hz], which must be whole."""
    steps = round(interval * rate)
    if steps < 1 or not math.isclose(steps, interval * rate, rel_tol=1e-9):
        raise ValueError(f"{interval} s is not a whole number of steps at {rate} Hz")
    return steps


def _sampled(
    step: Callable[[], np.ndarray], q0: np.ndarray, rate: float, duration: float, sample: float
) -> np.ndarray:
    """(q at t = 0, sample, 2·sample, …, duration), one row each, ``step`` advancing one step
    of 1/rate and returning q; PlantFaultError once q is not finite."""
    every, total = steps_of(sample, rate), steps_of(duration, rate)
    rows = [np.array(q0, dtype=float)]
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, total + 1):
            q = step()
            if not np.all(np.isfinite(q)):
                raise PlantFaultError(f"diverged at t = {k / rate:g} s at {rate:g} Hz")
            if k % every == 0:
                rows.append(np.array(q, dtype=float))
    return np.array(rows)


def reference_trajectory(
    loop: Regulation,
    duration: float = DURATION,
    sample: float = SAMPLE,
    rate: float = REFERENCE_RATE,
) -> np.ndarray:
    """The continuous loop by classical RK4 at ``rate``, sampled every ``sample`` [s]."""
    h, n = 1.0 / rate, loop.model.n
    x = np.r_[loop.q0, np.zeros(n)]

    def f(x: np.ndarray) -> np.ndarray:
        return np.r_[x[n:], loop.acceleration(x[:n], x[n:])]

    def step() -> np.ndarray:
        nonlocal x
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return x[:n]

    return _sampled(step, loop.q0, rate, duration, sample)


def euler_trajectory(
    loop: Regulation, rate: float, duration: float = DURATION, sample: float = SAMPLE
) -> np.ndarray:
    """The model's semi-implicit Euler at ``rate`` (the scheme both engines claim)."""
    h = 1.0 / rate
    q, v = loop.q0.copy(), np.zeros(loop.model.n)

    def step() -> np.ndarray:
        nonlocal q, v
        v = v + h * loop.acceleration(q, v)
        q = q + h * v
        return q

    return _sampled(step, loop.q0, rate, duration, sample)


def engine_trajectory(
    engine: str,
    loop: Regulation,
    rate: float,
    duration: float = DURATION,
    sample: float = SAMPLE,
) -> np.ndarray:
    """The loop on ``engine``'s plant at ``rate``: the torque from the plant's state at every
    physics step, clamped to the model's effort limits (a clamped run leaves the model's
    Euler: :attr:`ErrorTable.deviation` shows it)."""
    m = loop.model
    world = open_world(engine, rate)
    try:
        plant = world.load(
            m.spec,
            m.joint_names,
            initial_positions=loop.q0,
            locked_positions=m.locked_positions,
            effort_limits=m.effort_limits,
        )

        def step() -> np.ndarray:
            s = plant.state()
            plant.step(loop.torque(s.q, s.dq))
            return plant.state().q

        return _sampled(step, loop.q0, rate, duration, sample)
    finally:
        world.close()


def observed_orders(rates: Sequence[float], errors: Sequence[float]) -> np.ndarray:
    """p_i = log(e_i / e_{i+1}) / log(r_{i+1} / r_i): 1 for a first-order scheme."""
    r, e = np.asarray(rates, dtype=float), np.asarray(errors, dtype=float)
    return np.log(e[:-1] / e[1:]) / np.log(r[1:] / r[:-1])


@dataclass(frozen=True)
class ErrorTable:
    """One integrator (:data:`MODEL` or an engine) on one robot, rate by rate."""

    robot: str
    integrator: str
    rates: tuple[float, ...]
    #: max over samples and joints of |q − q_ref| [rad], per rate
    errors: np.ndarray
    #: max over samples and joints of |q − q_model| [rad], q_model the model's Euler at the
    #: same rate (0 for the model itself)
    deviation: np.ndarray

    @property
    def orders(self) -> np.ndarray:
        return observed_orders(self.rates, self.errors)


@dataclass(frozen=True)
class Measurement:
    """The model's semi-implicit Euler and each engine against the reference on one robot."""

    loop: Regulation
    tables: list[ErrorTable] = field(default_factory=list)
    #: max |q_ref − q_ref/2| [rad], the RK4 at REFERENCE_RATE against the RK4 at half of it:
    #: ~15 times the reference's own error (fourth order)
    reference_error: float = 0.0
    #: the largest excursion max |q − q0| of the reference [rad]
    motion: float = 0.0


def measure(
    loop: Regulation,
    engines: Sequence[str] = ENGINES,
    rates: Sequence[float] = RATES,
    duration: float = DURATION,
    sample: float = SAMPLE,
) -> Measurement:
    """The discretisation error of the model's semi-implicit Euler and of each engine; a run
    that blows up (gains too high for the rate) has the error inf."""
    rates = tuple(float(r) for r in rates)
    ref = reference_trajectory(loop, duration, sample)
    coarse = reference_trajectory(loop, duration, sample, REFERENCE_RATE / 2)

    def run(integrate: Callable[..., np.ndarray], *args: object) -> np.ndarray:
        try:
            return integrate(*args, duration, sample)
        except PlantFaultError:
            return np.full_like(ref, np.inf)

    euler = {r: run(euler_trajectory, loop, r) for r in rates}

    def table(name: str, runs: dict[float, np.ndarray]) -> ErrorTable:
        return ErrorTable(
            loop.model.spec.name,
            name,
            rates,
            np.array([np.abs(runs[r] - ref).max() for r in rates]),
            np.array([_distance(runs[r], euler[r]) for r in rates]),
        )

    tables = [table(MODEL, euler)]
    for engine in engines:
        runs = {r: run(engine_trajectory, engine, loop, r) for r in rates}
        tables.append(table(engine, runs))
    return Measurement(
        loop,
        tables,
        float(np.abs(ref - coarse).max()),
        float(np.abs(ref - loop.q0).max()),
    )


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b|, 0 between two runs that both blew up."""
    if np.all(np.isinf(a)) and np.all(np.isinf(b)):
        return 0.0
    return float(np.abs(a - b).max())


def _number(x: float, spec: str) -> str:
    return format(x, spec) if np.isfinite(x) else ("diverged" if x == np.inf else "—")


def _rate_label(rate: float) -> str:
    return f"{rate / 1000:g} kHz" if rate >= 1000 else f"{rate:g} Hz"


def markdown_table(measurements: Sequence[Measurement]) -> str:
    """One row per robot and integrator: the error per rate [rad], the observed orders and
    the largest distance from the model's Euler at the same rate."""
    rates = measurements[0].tables[0].rates
    head = ["robot", "integrator", *(_rate_label(r) for r in rates), "observed order"]
    head.append("vs model's Euler")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for m in measurements:
        for t in m.tables:
            with np.errstate(invalid="ignore", divide="ignore"):
                orders = ", ".join(_number(p, ".3f") for p in t.orders)
            deviation = "—" if t.integrator == MODEL else _number(t.deviation.max(), ".0e")
            errors = (_number(e, ".3e") for e in t.errors)
            cells = [t.robot, t.integrator, *errors, orders, deviation]
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m joint_space_control.lab.discretisation",
        description="The plant's discretisation error per engine and physics rate (PD + g(q) "
        "from q = 0 at rest to a set-point, against an RK4 reference).",
    )
    parser.add_argument("--robots", default=",".join(SETPOINTS), help="built-in robots")
    parser.add_argument("--engines", default=",".join(ENGINES))
    parser.add_argument("--rates", default=",".join(f"{r:g}" for r in RATES), help="[Hz]")
    parser.add_argument("--omega-n", type=float, default=OMEGA_N, help="[rad/s]")
    args = parser.parse_args(argv)
    engines = [e for e in args.engines.split(",") if e]
    rates = [float(r) for r in args.rates.split(",")]
    results = []
    for name in args.robots.split(","):
        if name not in SETPOINTS:
            parser.error(f"no set-point for {name!r}; known: {', '.join(SETPOINTS)}")
        model = RobotModel(resolve_robot(name))
        loop = Regulation.design(model, SETPOINTS[name], args.omega_n)
        results.append(measure(loop, engines, rates))
    print(markdown_table(results))
    for m in results:
        print(
            f"{m.loop.model.spec.name}: motion {m.motion:.3f} rad, RK4 reference at "
            f"{REFERENCE_RATE:g} Hz vs half that rate {m.reference_error:.1e} rad"
        )


if __name__ == "__main__":
    main()
