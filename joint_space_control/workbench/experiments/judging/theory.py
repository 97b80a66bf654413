"""Theory checks of experiment runs (THEORY.md §2–3, §5): measured numbers next to the
prediction, with a verdict. Pure: metrics dictionaries and the robot model in, outcomes out.

A check is named in a scenario's ``checks`` list with its tolerances, e.g.
``{check: second_order, overshoot_pp: 1.0, settling_rel: 0.05}``. ``passed`` is True or
False where the theory makes a claim, None where it does not (e.g. K_P below α).

Any check can be given a subset of the runs: ``where: {parameters.model_mass_scale: 1.0}``
keeps the runs with those settings, ``unsaturated: true`` those that never reached an
effort limit (e.g. the nominal row of a grid judged against the second-order theory); when
none is left (the short form of a grid runs its corners) the check makes no claim.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from joint_space_control.analysis.spec import judge, parse_spec
from joint_space_control.workbench.experiments.judging import boundaries, practical
from joint_space_control.workbench.experiments.judging.boundaries import gravity_bound
from joint_space_control.workbench.experiments.judging.outcome import (
    Outcome,
    RunView,
    fmt,
    joints,
    vec,
)

_fmt, _joints, _vec = fmt, joints, vec


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
        g = r.plant_model().gravity(q_e)
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


def _gravity_equilibrium(r: RunView, q_d: np.ndarray, kp: np.ndarray) -> np.ndarray:
    """q_e with K_P (q_d − q_e) = g(q_e) − ĝ(q_d): where τ = ĝ(q_d) + K_P q̃ − K_D q̇ comes to
    rest when the controller's ĝ (its model: ``model_mass_scale``, ``model_payload_mass``) is
    not the plant's g (its ``payload_mass``). For K_P,i > α the map
    q ↦ q_d − K_P⁻¹(g(q) − ĝ(q_d)) is a contraction (‖K_P⁻¹ ∂g/∂q‖₂ ≤ α / min K_P < 1), so
    the fixed point is unique and found by iterating it; q_e = q_d when ĝ = g."""
    plant = r.plant_model(payload=True)
    g_hat = r.controller_model().gravity(q_d)
    q = q_d.copy()
    for _ in range(1000):
        nxt = q_d - (plant.gravity(q) - g_hat) / kp
        if np.max(np.abs(nxt - q)) < 1e-13:
            return nxt
        q = nxt
    return q


def constant_gravity(
    runs: list[RunView], tol: float = 1e-3, per_run: bool = True
) -> list[Outcome]:
    """τ = ĝ(q_d) + K_P q̃ − K_D q̇ converges for every K_P,i > α (sufficient, not necessary),
    α = max ‖∂g/∂q‖₂ of the run's plant (with its ``payload_mass``): to q_d, or, when the
    controller's ĝ is not the plant's g, to the equilibrium of :func:`_gravity_equilibrium`;
    "converged" is max |q − q_e| < ``tol`` [rad] at the end. Below α no claim. ``per_run``
    false (a grid): one outcome for the runs above α and one for those below."""
    rows = []
    for r in runs:
        joints = _joints(r.controller)
        e = _vec(r.controller["final_error"], joints)
        kp = np.array(r.controller["config"]["kp"], dtype=float)
        alpha = gravity_bound(r.robot, float(r.plant["payload_mass"]))
        q_d = np.array([r.controller["steps"][-1]["joints"][j]["target"] for j in joints])
        q_e = _gravity_equilibrium(r, q_d, kp) if kp.min() > alpha else q_d
        miss = float(np.max(np.abs((q_d - e) - q_e)))  # q = q_d − e at the end
        rows.append((r, alpha, float(kp.min()), q_e, q_d, miss, float(np.max(np.abs(e)))))
    if per_run:
        out = []
        for r, alpha, kp_min, q_e, q_d, miss, err in rows:
            above, converged = kp_min > alpha, miss < tol
            shifted = above and not np.allclose(q_e, q_d, rtol=0.0, atol=1e-12)
            out.append(
                Outcome(
                    "constant_gravity",
                    converged if above else None,
                    f"{r.label}: min K_P = {kp_min:g} {'>' if above else '<'} α = {alpha:.1f} "
                    f"N·m/rad; final max |q_d − q| = {_fmt(err)} rad"
                    + (f", |q − q_e| = {_fmt(miss)} rad (ĝ ≠ g: q_e ≠ q_d)" if shifted else "")
                    + (" (converged)" if converged else " (did not converge)")
                    + ("" if above else "; below α the theorem makes no claim"),
                    {"alpha": alpha, "kp_min": kp_min, "max_abs_final_error": err, "miss": miss},
                )
            )
        return out
    above = [row for row in rows if row[2] > row[1]]
    below = [row for row in rows if row[2] <= row[1]]
    out = []
    if above:
        stuck = [f"{r.label} ({_fmt(miss)} rad)" for r, *_, miss, _ in above if miss >= tol]
        worst = max(row[5] for row in above)
        out.append(
            Outcome(
                "constant_gravity",
                not stuck,
                f"{len(above)} runs with every K_P,i > α (α = {_fmt(min(r[1] for r in above))}"
                f"–{_fmt(max(r[1] for r in above))} N·m/rad with the plant's payload): "
                + (
                    f"all converge, max |q − q_e| = {_fmt(worst)} rad < {tol:g}"
                    if not stuck
                    else "did not converge: " + ", ".join(stuck)
                ),
                {
                    "labels": [r[0].label for r in above],
                    "miss": [r[5] for r in above],
                    "tolerance": tol,
                },
            )
        )
    if below:
        ok = [r[0].label for r in below if r[5] < tol]
        out.append(
            Outcome(
                "constant_gravity",
                None,
                f"{len(below)} runs with some K_P,i ≤ α (no claim): {len(ok)} converge anyway"
                + (f" ({', '.join(ok)})" if ok and len(ok) <= 6 else "")
                + f", {len(below) - len(ok)} do not",
                {"labels": [r[0].label for r in below], "miss": [r[5] for r in below]},
            )
        )
    return out


def saturation_boundary(runs: list[RunView], margin: float = 0.15) -> list[Outcome]:
    """Inverse dynamics on a step: the command saturates at the step's instant once ω_n
    reaches the onset ω_s of :func:`~.boundaries.saturation_onset` (its model, q0, target).
    A run with ω_n < (1 − margin) ω_s must have no sample at the effort limit, one with
    ω_n > (1 + margin) ω_s some (> 0 %); within the margin (where later peaks of the torque
    decide) no claim. One outcome for each side."""
    below, above, between = [], [], []
    for r in runs:
        omega = r.given.get("omega_n")  # as the scenario gives it
        if np.size(omega) != 1:
            raise ValueError(f"{r.label}: saturation_boundary needs one omega_n, got {omega!r}")
        omega = float(np.ravel(omega)[0])
        onset = boundaries.saturation_onset(r)
        td = r.controller["torque_demand"]
        sat = float(np.nanmax(_vec(td["saturated_fraction"], _joints(r.controller))))
        row = (r.label, omega, onset, 100.0 * sat)
        if omega < (1 - margin) * onset:
            below.append(row)
        elif omega > (1 + margin) * onset:
            above.append(row)
        else:
            between.append(row)

    def numbers(group: list[tuple[str, float, float, float]]) -> dict[str, Any]:
        keys = ("labels", "omega_n", "onset", "saturated_percent")
        return {k: [g[i] for g in group] for i, k in enumerate(keys)} | {"margin": margin}

    out = []
    if below:
        wrong = [f"{x[0]} ({_fmt(x[3])} %)" for x in below if not x[3] == 0.0]
        out.append(
            Outcome(
                "saturation_boundary",
                not wrong,
                f"{len(below)} runs with ω_n below the onset by more than {margin:.0%}: "
                + ("none saturates" if not wrong else "saturated: " + ", ".join(wrong)),
                numbers(below),
            )
        )
    if above:
        wrong = [x[0] for x in above if not x[3] > 0.0]
        least = min(x[3] for x in above)
        out.append(
            Outcome(
                "saturation_boundary",
                not wrong,
                f"{len(above)} runs with ω_n above the onset by more than {margin:.0%}: "
                + (
                    f"all saturate (at least {_fmt(least)} % of the record)"
                    if not wrong
                    else "not saturated: " + ", ".join(wrong)
                ),
                numbers(above),
            )
        )
    if between:
        sat = [x[0] for x in between if x[3] > 0.0]
        out.append(
            Outcome(
                "saturation_boundary",
                None,
                f"{len(between)} runs within {margin:.0%} of the onset (no claim): "
                f"{len(sat)} saturate",
                numbers(between),
            )
        )
    onsets = sorted({round(x[2], 2) for x in below + above + between})
    if out:
        out[0].text += f" (onset ω_s from {_fmt(onsets[0])} to {_fmt(onsets[-1])} rad/s)"
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
        g_d = r.plant_model().gravity(q_d)
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
    "saturation_boundary": saturation_boundary,
    "spec": spec,
    **practical.CHECKS,
}


def _matches(r: RunView, key: str, value: Any) -> bool:
    """The run's setting ``key`` ("controller" or "section.name") equals ``value`` (numbers
    to 1e-9 relative)."""
    if key == "controller":
        have = r.executable
    else:
        section, _, name = key.partition(".")
        have = getattr(r, section, {}).get(name)
    if isinstance(have, int | float) and isinstance(value, int | float):
        return math.isclose(have, value, rel_tol=1e-9, abs_tol=1e-12)
    return have == value


def _unsaturated(r: RunView) -> bool:
    fractions = _vec(r.controller["torque_demand"]["saturated_fraction"], _joints(r.controller))
    return bool(np.all(fractions == 0.0))


def select(runs: list[RunView], where: dict | None = None, unsaturated: bool = False):
    """The runs a check judges: those whose settings match ``where`` ({"section.name":
    value}) and, with ``unsaturated``, that never reached an effort limit."""
    chosen = [r for r in runs if all(_matches(r, k, v) for k, v in (where or {}).items())]
    return [r for r in chosen if _unsaturated(r)] if unsaturated else chosen


def evaluate(spec: dict[str, Any], runs: list[RunView]) -> list[Outcome]:
    """The check ``spec["check"]`` with its tolerances, on the runs ``where`` and
    ``unsaturated`` (optional, any check) select; none selected: one outcome, no claim."""
    spec = dict(spec)
    name = spec.pop("check", None)
    if name not in CHECKS:
        raise ValueError(f"unknown check {name!r}; known: {', '.join(CHECKS)}")
    where, unsaturated = spec.pop("where", None), bool(spec.pop("unsaturated", False))
    if where is not None and not isinstance(where, dict):
        raise ValueError(f"'where' must be a mapping of settings, got {where!r}")
    chosen = select(runs, where, unsaturated)
    if not chosen:
        which = ", ".join(f"{k} = {v}" for k, v in (where or {}).items())
        which += (" and " if which else "") + ("no saturation" if unsaturated else "")
        return [Outcome(name, None, f"no run with {which or 'these settings'}: nothing to judge")]
    return CHECKS[name](chosen, **spec)
