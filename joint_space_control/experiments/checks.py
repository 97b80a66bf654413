"""Theory checks of experiment runs (THEORY.md §2–3, §5): measured numbers next to the
prediction, with a verdict. Pure: metrics dictionaries and the robot model in, outcomes out.

A check is named in a scenario's ``checks`` list with its tolerances, e.g.
``{check: second_order, overshoot_pp: 1.0, settling_rel: 0.05}``. ``passed`` is True or
False where the theory makes a claim, None where it does not (e.g. K_P below α).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from joint_space_control.analysis.spec import judge, parse_spec
from joint_space_control.experiments import practice, views
from joint_space_control.experiments.views import Outcome, RunView

_fmt, _joints, _model, _vec = views.fmt, views.joints, views.model, views.vec


def final_error(runs: list[RunView], tol: float = 1e-3) -> list[Outcome]:
    out = []
    for r in runs:
        e = np.abs(_vec(r.controller["final_error"], _joints(r.controller)))
        out.append(
            Outcome(
                "final_error",
                bool(np.all(e < tol)),
                f"{r.label}: max |q_d − q| at the end = {_fmt(e.max())} rad (tolerance {tol:g})",
                {"max_abs_final_error": float(e.max()), "tolerance": tol},
            )
        )
    return out


def pd_offset(runs: list[RunView], rtol: float = 0.02) -> list[Outcome]:
    """Pure PD: q_e solves g(q_e) = K_P (q_d − q_e)."""
    out = []
    for r in runs:
        joints = _joints(r.controller)
        e = _vec(r.controller["final_error"], joints)
        q_e = np.array(r.events[-1]["q"])
        kp = np.array(r.controller["config"]["kp"], dtype=float)
        g = _model(r.robot).gravity(q_e)
        spring = kp * e
        residual = np.abs(spring - g)
        ok = bool(np.max(np.abs(e)) > 1e-3 and np.all(residual <= rtol * np.abs(g) + 0.5))
        out.append(
            Outcome(
                "pd_offset",
                ok,
                f"{r.label}: offset q_d − q_e = {np.array2string(e, precision=4)} rad; "
                f"K_P(q_d − q_e) = {np.array2string(spring, precision=1)} N·m vs g(q_e) = "
                f"{np.array2string(g, precision=1)} N·m",
                {"offset": e.tolist(), "kp_offset": spring.tolist(), "g_qe": g.tolist()},
            )
        )
    return out


def gravity_bound(robot: str, samples: int = 4000, seed: int = 0) -> float:
    """α ≈ max over q of ‖∂g/∂q‖₂ (spectral norm), by Pinocchio's analytic derivative of
    the generalized gravity at ``samples`` random configurations within the joint limits
    (a lower estimate of the supremum; dense enough for these arms)."""
    model = _model(robot)
    lo, hi = model.position_limits
    lo, hi = np.maximum(lo, -np.pi), np.minimum(hi, np.pi)
    rng = np.random.default_rng(seed)
    best = 0.0
    for q in rng.uniform(lo, hi, size=(samples, model.n)):
        best = max(best, float(np.linalg.norm(views.gravity_jacobian(model, q), 2)))
    return best


def constant_gravity(runs: list[RunView], tol: float = 1e-3) -> list[Outcome]:
    """τ = g(q_d) + K_P q̃ − K_D q̇ converges for every K_P,i > α (sufficient, not necessary)."""
    out = []
    alpha = gravity_bound(runs[0].robot) if runs else math.nan
    for r in runs:
        e = np.abs(_vec(r.controller["final_error"], _joints(r.controller)))
        kp_min = float(np.min(r.controller["config"]["kp"]))
        above = kp_min > alpha
        converged = bool(np.all(e < tol))
        out.append(
            Outcome(
                "constant_gravity",
                converged if above else None,
                f"{r.label}: min K_P = {kp_min:g} {'>' if above else '<'} α = {alpha:.1f} N·m/rad;"
                f" final max |q_d − q| = {_fmt(e.max())} rad "
                + ("(converged)" if converged else "(did not converge to q_d)")
                + ("" if above else "; below α the theorem makes no claim"),
                {"alpha": alpha, "kp_min": kp_min, "max_abs_final_error": float(e.max())},
            )
        )
    return out


def _tracking_rms(c: dict) -> float:
    section = c["tracking_error"].get("moving_reference") or c["tracking_error"]["whole_record"]
    return float(np.nanmax(_vec(section["rms"], _joints(c))))


def tracking_grows(runs: list[RunView]) -> list[Outcome]:
    """Time-varying q_d: the tracking error grows with the swept quantity (ω, Δ)."""
    rms = [_tracking_rms(r.controller) for r in runs]
    ok = bool(all(b > a for a, b in zip(rms, rms[1:], strict=False)))
    pairs = ", ".join(f"{r.label}: {_fmt(x)} rad" for r, x in zip(runs, rms, strict=True))
    return [Outcome("tracking_grows", ok, f"RMS tracking error {pairs}", {"rms": rms})]


def _first_step(c: dict) -> dict | None:
    return c["steps"][0] if c["steps"] else None


def second_order(
    runs: list[RunView],
    overshoot_pp: float = 1.0,
    settling_rel: float = 0.05,
    sse: float = 1e-4,
    period: float = 1e-3,
) -> list[Outcome]:
    """Nominal inverse dynamics: each joint a second-order system (ω_n, ζ from the gains)."""
    out = []
    for r in runs:
        step = _first_step(r.controller)
        if step is None:
            out.append(Outcome("second_order", False, f"{r.label}: no step found"))
            continue
        for name, j in step["joints"].items():
            if not j["moving"] or "prediction" not in j:
                continue
            p = j["prediction"]
            d_os = abs(j["overshoot_percent"] - p["overshoot_percent"])
            ts, ts_p = j["settling_time_2"], p["settling_time_2"]
            d_ts = abs(ts - ts_p) if ts is not None else math.inf
            ok = (
                d_os < overshoot_pp
                and d_ts <= max(settling_rel * ts_p, period)
                and abs(j["steady_state_error"]) < sse
            )
            out.append(
                Outcome(
                    "second_order",
                    bool(ok),
                    f"{r.label} {name} (ω_n = {p['omega_n']:.3g}, ζ = {p['zeta']:.3g}): "
                    f"overshoot {_fmt(j['overshoot_percent'])} % vs "
                    f"{_fmt(p['overshoot_percent'])} %, 2 % settling {_fmt(ts)} s vs "
                    f"{_fmt(ts_p)} s, steady-state error {_fmt(j['steady_state_error'])} rad",
                    {
                        "joint": name,
                        "overshoot": j["overshoot_percent"],
                        "overshoot_theory": p["overshoot_percent"],
                        "settling_2": ts,
                        "settling_2_theory": ts_p,
                        "steady_state_error": j["steady_state_error"],
                    },
                )
            )
    return out


def decoupled(runs: list[RunView], tol: float = 1e-3) -> list[Outcome]:
    out = []
    for r in runs:
        step = _first_step(r.controller)
        devs = {
            n: j["max_deviation"]
            for n, j in (step or {"joints": {}})["joints"].items()
            if not j["moving"]
        }
        worst = max(devs.values()) if devs else math.nan
        out.append(
            Outcome(
                "decoupled",
                bool(devs) and worst < tol,
                f"{r.label}: joints that were not commanded moved at most {_fmt(worst)} rad "
                f"(tolerance {tol:g})",
                {"max_deviation": devs},
            )
        )
    return out


def iterative_gravity(runs: list[RunView], rtol: float = 0.05) -> list[Outcome]:
    """u_i = K_P (q_d − q_e,i) + u_{i−1} → g(q_d), q_e,i → q_d."""
    out = []
    for r in runs:
        joints = _joints(r.controller)
        targets = [s["joints"] for s in r.controller["steps"]]
        q_d = np.array([targets[-1][j]["target"] for j in joints])
        g_d = _model(r.robot).gravity(q_d)
        us = [
            np.array(e["controller"]["gravity_estimate"])
            for e in r.events
            if "controller" in e and "gravity_estimate" in e["controller"]
        ]
        errors = [float(np.max(np.abs(q_d - np.array(e["q"])))) for e in r.events]
        if not us:
            out.append(Outcome("iterative_gravity", False, f"{r.label}: no iteration ran"))
            continue
        gap = float(np.max(np.abs(us[-1] - g_d) / np.maximum(np.abs(g_d), 1.0)))
        shrinking = all(b < a for a, b in zip(errors, errors[1:], strict=False))
        out.append(
            Outcome(
                "iterative_gravity",
                bool(gap < rtol and shrinking),
                f"{r.label}: after {len(us)} iterations u = {np.array2string(us[-1], precision=1)}"
                f" N·m vs g(q_d) = {np.array2string(g_d, precision=1)} N·m; max |q_d − q_e,i| "
                "per equilibrium: " + ", ".join(_fmt(x) for x in errors) + " rad",
                {"u": [u.tolist() for u in us], "g_qd": g_d.tolist(), "errors": errors},
            )
        )
    return out


def degrades(runs: list[RunView]) -> list[Outcome]:
    """Mismatch: every perturbed run tracks worse than the first (nominal) one."""
    rms = [_tracking_rms(r.controller) for r in runs]
    ok = bool(len(rms) > 1 and all(x > rms[0] for x in rms[1:]))
    pairs = ", ".join(f"{r.label}: {_fmt(x)} rad" for r, x in zip(runs, rms, strict=True))
    return [Outcome("degrades", ok, f"RMS tracking error {pairs}", {"rms": rms})]


def peak_torque_grows(runs: list[RunView]) -> list[Outcome]:
    """Large ω_n: peak torque grows; beyond the limits the command saturates."""
    peaks, sat = [], []
    for r in runs:
        td = r.controller["torque_demand"]
        joints = _joints(r.controller)
        peaks.append(float(np.nanmax(_vec(td["peak_abs"], joints))))
        sat.append(float(np.nanmax(_vec(td["saturated_fraction"], joints))))
    ok = bool(all(b >= a for a, b in zip(peaks, peaks[1:], strict=False)) and sat[-1] > 0)
    rows = ", ".join(
        f"{r.label}: {_fmt(p)} N·m ({_fmt(100 * s)} % saturated)"
        for r, p, s in zip(runs, peaks, sat, strict=True)
    )
    return [Outcome("peak_torque_grows", ok, f"peak |τ| {rows}", {"peak": peaks, "sat": sat})]


def spec(runs: list[RunView], spec: str) -> list[Outcome]:
    """A step-response specification (``"overshoot<=5, settling_2pct<=0.6"``,
    analysis/spec.py: the one ``jsc tune`` tunes to), each clause over the worst joint."""
    parsed = parse_spec(spec)
    out = []
    for r in runs:
        j = judge(parsed, r.controller)
        out.append(
            Outcome(
                "spec",
                j.met,
                f"{r.label}: {j.text()}",
                {
                    "spec": str(parsed),
                    "values": [m.value for m in j.values],
                    "joints": [m.joint for m in j.values],
                    "violations": list(j.violations),
                },
            )
        )
    return out


CHECKS: dict[str, Callable[..., list[Outcome]]] = {
    "final_error": final_error,
    "pd_offset": pd_offset,
    "constant_gravity": constant_gravity,
    "tracking_grows": tracking_grows,
    "second_order": second_order,
    "decoupled": decoupled,
    "iterative_gravity": iterative_gravity,
    "degrades": degrades,
    "peak_torque_grows": peak_torque_grows,
    "spec": spec,
    **practice.CHECKS,
}


def evaluate(spec: dict[str, Any], runs: list[RunView]) -> list[Outcome]:
    spec = dict(spec)
    name = spec.pop("check", None)
    if name not in CHECKS:
        raise ValueError(f"unknown check {name!r}; known: {', '.join(CHECKS)}")
    return CHECKS[name](runs, **spec)
