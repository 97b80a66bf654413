r"""A recorded run → metrics per controller and per joint (THEORY.md §3–4), JSON-ready.

Arrays in, a plain dict out: the measurements are :mod:`joint_space_control.analysis.metrics`;
this module decides what to measure on a controller's recorded state
(:class:`~joint_space_control.analysis.bag.ControllerState`) and how to lay it out.

- :func:`analyze_bag`: read a bag's controllers and measure each (the library entry point);
- :func:`last_run`: the samples to analyse (after the last simulation reset, one per stamp);
- :func:`step_segments`: where the reference steps, and which joints it moves;
- :func:`controller_metrics`: every metric of one controller.

Units in the result: positions in rad (m for a prismatic joint), torques in N·m (N), times
and durations in s, control periods in ms (key names ``*_ms``), percentages in %. Per-joint
values are dicts keyed by joint name; a value that does not exist (a response that never
settles, no limits known) is None.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from joint_space_control.analysis import frequency, metrics
from joint_space_control.analysis.bag import (
    BagContents,
    BagError,
    ControllerState,
    Progress,
    controller_configs,
    controller_state,
    read_controller_bag,
)
from joint_space_control.json_values import jsonable
from joint_space_control.laws.second_order import gains_to_second_order

CONSTANT_TOL = 1e-12
"""Relative tolerance (on max(1, |q_d|)) under which q_d is constant between two samples."""
MIN_STEP_SAMPLES = 10
"""Samples a step segment needs to be measured."""
FIRST_STEP_MIN_AMPLITUDE = 1e-6
"""|q_d − q| [rad] at the first sample above which the record starts with a step."""
SATURATION_TOL = 1e-9
"""[N·m] a sample is saturated within this of the limit, or when |τ_unclamped − τ| exceeds it."""
UNITS = {
    "position": "rad (m for a prismatic joint)",
    "torque": "N·m (N for a prismatic joint)",
    "time": "s",
    "period": "ms",
    "percent": "%",
}


@dataclass(frozen=True)
class ControllerAnalysis:
    """One controller of a bag: the samples analysed, its last configuration, its metrics."""

    state: ControllerState
    config: dict | None
    metrics: dict


@dataclass(frozen=True)
class BagAnalysis:
    """Every controller of a run; ``metrics`` is the JSON-ready document (``metrics.json``);
    ``contents``: the bag's (None: a run measured from memory, with no bag)."""

    contents: BagContents | None
    controllers: list[ControllerAnalysis]
    metrics: dict


# --------------------------------------------------------------------------- entry point


def analyze_bag(path: str | Path, progress: Progress | None = None) -> BagAnalysis:
    """Read the controller topics of the bag at ``path`` and measure every controller.

    Raises:
        BagError: see :func:`~joint_space_control.analysis.bag.read_controller_bag`.
    """
    contents = read_controller_bag(path, progress)
    warnings: list[str] = []
    records = []
    for state_topic, config_topic in contents.controllers:
        configs = []
        if config_topic is not None:
            configs = controller_configs(contents.data[config_topic], warnings)
        records.append((controller_state(contents.data[state_topic]), configs))
    recording = {
        "bag": str(contents.path),
        "storage": contents.storage,
        "start_time_ns": contents.start_ns,
        "duration_s": contents.duration,
        "message_count": contents.message_count,
        "message_counts": {t.name: t.count for t in contents.topics.values()},
        "topic_types": {t.name: t.msgtype for t in contents.topics.values()},
    }
    try:
        return analyze_run(records, recording, warnings, contents)
    except ValueError as err:
        raise BagError(f"{contents.path}: {err}") from None


def analyze_run(
    records: Sequence[tuple[ControllerState, Sequence[tuple[int, dict]]]],
    recording: dict,
    warnings: list[str] | None = None,
    contents: BagContents | None = None,
) -> BagAnalysis:
    """Measure every controller of a run from its state record and configurations (log
    time [ns], document), as read from a bag or kept in memory by the loop in process;
    ``recording`` says what was recorded (``bag``, ``storage``, ``message_counts``, ...;
    ``bag`` None: nothing was). ValueError when no controller has a sample to measure."""
    warnings = [] if warnings is None else warnings
    controllers = []
    for state, configs in records:
        analysis = controller_analysis(state, configs)
        if analysis is None:
            warnings.append(f"{state.topic}: no sample with finite values, not analysed")
        else:
            controllers.append(analysis)
    if not controllers:
        raise ValueError("no controller state with finite values to analyse")
    result = {
        **recording,
        "units": UNITS,
        "controllers": {c.metrics["node"]: c.metrics for c in controllers},
        "warnings": warnings
        + [f"{c.metrics['node']}: {w}" for c in controllers for w in c.metrics["warnings"]],
    }
    return BagAnalysis(contents, controllers, jsonable(result))


def controller_analysis(
    state: ControllerState, configs: Sequence[tuple[int, dict]]
) -> ControllerAnalysis | None:
    """Clean a controller's recorded state (:func:`last_run`) and measure it (None if no
    sample is left to measure)."""
    warnings: list[str] = []
    clean, samples = last_run(state, warnings)
    if len(clean) == 0:
        return None
    config = config_at(configs, int(clean.log_time[-1]))
    result = controller_metrics(clean, configs, warnings)
    result["samples"] = samples
    return ControllerAnalysis(clean, config, result)


# --------------------------------------------------------------------------- cleaning


def last_run(
    state: ControllerState, warnings: list[str] | None = None
) -> tuple[ControllerState, dict]:
    """The samples to analyse, and how many were dropped and why.

    - samples with a non-finite stamp, q_d, q or τ are dropped;
    - when the stamps go backwards (the simulation was reset) only the samples after the
      last reset are kept, and a warning says so;
    - of samples sharing a stamp (a lockstep state sent again is answered again) the last
      one is kept; a warning says when they differ in q (two runs, not a repeated answer).
    """
    warnings = [] if warnings is None else warnings
    finite = np.isfinite(state.stamp)
    for name in ("q_d", "q", "tau"):
        finite &= np.all(np.isfinite(state.rows[name]), axis=1)
    dropped_non_finite = int(np.count_nonzero(~finite))
    if dropped_non_finite:
        warnings.append(f"dropped {dropped_non_finite} samples with non-finite values")
        state = state.take(finite)
    backwards = np.flatnonzero(np.diff(state.stamp) < 0.0)
    before_reset = int(backwards[-1]) + 1 if backwards.size else 0
    if backwards.size:
        warnings.append(
            f"the state stamps go back {backwards.size} time(s) (simulation reset): only the "
            f"{len(state) - before_reset} samples after the last reset are analysed "
            f"(stamps from {state.stamp[before_reset]:.6g} s), {before_reset} before it are not"
        )
        state = state.take(slice(before_reset, None))
    last_of_stamp = np.append(np.diff(state.stamp) > 0.0, True)
    duplicates = int(np.count_nonzero(~last_of_stamp))
    if duplicates:
        # an answer repeated for the same joint state carries the same q; a different q at
        # the same stamp means two simulation runs whose messages interleave in log time
        # (a recorder on simulation time across a reset): they cannot be told apart here
        repeated = np.flatnonzero(~last_of_stamp)
        q = state.rows["q"]
        conflicts = int(np.count_nonzero(np.any(q[repeated] != q[repeated + 1], axis=1)))
        if conflicts:
            warnings.append(
                f"{conflicts} stamps carry different joint positions q: probably several "
                "simulation runs interleaved in log time (recorder on simulation time across "
                "a reset); the analysis mixes them, record each run in its own bag"
            )
        state = state.take(last_of_stamp)
    if state.skipped:
        warnings.append(f"{state.skipped} state messages with a different layout were ignored")
    samples = {
        "messages": int(len(state) + duplicates + before_reset + dropped_non_finite),
        "analysed": len(state),
        "duplicate_stamps": duplicates,
        "resets": int(backwards.size),
        "before_last_reset": before_reset,
        "non_finite": dropped_non_finite,
        "other_layout": state.skipped,
    }
    return state, samples


# --------------------------------------------------------------------------- configuration


def config_at(configs: Sequence[tuple[int, dict]], log_time: int) -> dict | None:
    """The configuration in force at ``log_time`` [ns]: the last one received at or before
    it, else the first one (a latched configuration may arrive just after the first state)."""
    if not configs:
        return None
    before = [c for t, c in configs if t <= log_time]
    return before[-1] if before else configs[0][1]


def config_values(
    config: dict | None, key: str, joints: Sequence[str], warnings: list[str] | None = None
) -> np.ndarray | None:
    """Per-joint values ``config[key]`` in the order of ``joints`` (None if not available).

    The configuration lists values in the order of its own ``joints`` (one value applies to
    every joint; ``null`` gives NaN); joints it does not list make the result None, with a
    warning.
    """
    if config is None or config.get(key) is None:
        return None
    names = list(config.get("joints") or joints)
    try:
        values = np.array(config[key], dtype=float).reshape(-1)
        if values.size == 1:
            values = np.full(len(names), values[0])
        if values.size != len(names):
            raise ValueError(f"{values.size} values for {len(names)} joints")
        index = {name: k for k, name in enumerate(names)}
        out = values[[index[j] for j in joints]]
    except (KeyError, TypeError, ValueError) as err:
        if warnings is not None:
            warnings.append(f"configuration '{key}' unusable for joints {list(joints)}: {err}")
        return None
    return out


# --------------------------------------------------------------------------- segments


@dataclass(frozen=True)
class StepSegment:
    """Samples [start, stop) during which q_d holds the value it stepped to at ``start``;
    ``moving`` (n_joints,) marks the joints the step commands to move."""

    start: int
    stop: int
    moving: np.ndarray


def _changed(q_d: np.ndarray) -> np.ndarray:
    """(N−1, n): q_d[k+1] differs from q_d[k] beyond :data:`CONSTANT_TOL`."""
    scale = np.maximum(1.0, np.maximum(np.abs(q_d[1:]), np.abs(q_d[:-1])))
    return np.abs(np.diff(q_d, axis=0)) > CONSTANT_TOL * scale


def step_segments(
    t: np.ndarray, q_d: np.ndarray, q: np.ndarray, dq_d: np.ndarray | None = None
) -> list[StepSegment]:
    r"""The set-point steps of a record: where q_d jumps, while it then stays constant.

    A joint jumps at sample k when q_d changes by more than the reference velocity explains,
    |q_d[k] − q_d[k−1]| > 2·max(|q̇_d[k−1]|, |q̇_d[k]|)·Δt (beyond :data:`CONSTANT_TOL`), so
    the samples of a moving trajectory and its arrival at a hold are not steps. The record
    also starts with a step when q_d is constant from the first sample and differs from q
    there by more than :data:`FIRST_STEP_MIN_AMPLITUDE`. A step lasts while every joint's q_d
    stays constant and is kept if that is at least :data:`MIN_STEP_SAMPLES` samples.
    """
    n = t.size
    if n < 2:
        return []
    changed = _changed(q_d)
    starts = np.concatenate(([0], np.flatnonzero(np.any(changed, axis=1)) + 1))
    stops = np.append(starts[1:], n)
    scale = np.maximum(1.0, np.abs(q_d))
    out = []
    for start, stop in zip(starts.tolist(), stops.tolist(), strict=True):
        if stop - start < MIN_STEP_SAMPLES:
            continue
        if dq_d is not None and np.any(np.abs(dq_d[start:stop]) > CONSTANT_TOL * scale[start]):
            continue  # q_d constant but the reference claims to move: not a set-point
        if start == 0:
            moving = np.abs(q_d[0] - q[0]) > FIRST_STEP_MIN_AMPLITUDE
        else:
            jump = np.abs(q_d[start] - q_d[start - 1])
            explained = np.zeros_like(jump)
            if dq_d is not None:
                speed = np.maximum(np.abs(dq_d[start - 1]), np.abs(dq_d[start]))
                explained = 2.0 * speed * (t[start] - t[start - 1])
            moving = changed[start - 1] & (jump > explained)
        if np.any(moving):
            out.append(StepSegment(start, stop, moving))
    return out


def moving_segments(q_d: np.ndarray, dq_d: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Runs [start, stop) of at least 2 samples where the reference moves: |q̇_d| > 0 on some
    joint (or, without a q̇_d row, q_d changing from one sample to the next)."""
    if q_d.shape[0] < 2:
        return []
    if dq_d is not None:
        moving = np.any(np.abs(dq_d) > CONSTANT_TOL * np.maximum(1.0, np.abs(q_d)), axis=1)
    else:
        moving = np.append(False, np.any(_changed(q_d), axis=1))
    edges = np.diff(np.concatenate(([0], moving.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True) if b - a >= 2]


# --------------------------------------------------------------------------- metrics


def _by_joint(joints: Sequence[str], values) -> dict[str, float]:
    return {j: float(v) for j, v in zip(joints, np.asarray(values).reshape(-1), strict=True)}


def _second_order(kp: np.ndarray, kd: np.ndarray) -> dict[str, np.ndarray]:
    omega_n, zeta = gains_to_second_order(kp, kd)
    return {"kp": kp, "kd": kd, **metrics.second_order_prediction(omega_n, zeta)}


def _prediction(
    config: dict | None, joints: Sequence[str], warnings: list[str]
) -> dict[str, np.ndarray] | None:
    """Second-order figures of an inverse-dynamics configuration (THEORY.md §3), else None."""
    if config is None or config.get("law") != "inverse_dynamics":
        return None
    kp = config_values(config, "kp", joints, warnings)
    kd = config_values(config, "kd", joints, warnings)
    if kp is None or kd is None:
        warnings.append("inverse_dynamics configuration without usable kp/kd: no prediction")
        return None
    try:
        return _second_order(kp, kd)
    except ValueError as err:
        warnings.append(f"no second-order prediction: {err}")
        return None


def step_response(
    state: ControllerState,
    seg: StepSegment,
    configs: Sequence[tuple[int, dict]],
    warnings: list[str],
    predict: bool = True,
) -> dict:
    """The step response of the segment ``seg`` per joint (a moving joint's rise, settling
    and overshoot, with the second-order prediction of the configuration in force when
    ``predict``; a joint the step does not move: how far the others moved it)."""
    t = state.stamp[seg.start : seg.stop]
    q = state.rows["q"][seg.start : seg.stop]
    target = state.rows["q_d"][seg.start]
    measured = metrics.step_metrics_per_joint(t, q, target, t_step=float(t[0]))
    prediction = None
    if predict:
        config = config_at(configs, int(state.log_time[seg.start]))
        prediction = _prediction(config, state.joints, warnings)
    joints = {}
    for j, name in enumerate(state.joints):
        m = measured[j]
        entry = {
            "moving": bool(seg.moving[j]),
            "initial": m.initial,
            "target": m.final_target,
            "final_value": m.final_value,
            "steady_state_error": m.steady_state_error,
        }
        if not seg.moving[j]:  # coupling: how far the step of the others moved this joint
            entry["max_deviation"] = float(np.max(np.abs(q[:, j] - q[0, j])))
        else:
            entry.update(
                step=m.final_target - m.initial,
                rise_time=m.rise_time,
                settling_time_2=m.settling_time_2,
                settling_time_5=m.settling_time_5,
                overshoot_percent=m.overshoot_percent,
            )
            if prediction is not None:
                entry["prediction"] = {k: float(v[j]) for k, v in prediction.items()}
        joints[name] = entry
    return {
        "t_start": float(t[0]),
        "t_end": float(t[-1]),
        "duration": float(t[-1] - t[0]),
        "samples": seg.stop - seg.start,
        "ends_record": seg.stop == len(state),
        "joints": joints,
    }


def _tracking(state: ControllerState) -> dict:
    t, q, q_d = state.stamp, state.rows["q"], state.rows["q_d"]
    whole = metrics.tracking_error(t, q, q_d)
    result = {
        "whole_record": {
            "t_start": float(t[0]),
            "t_end": float(t[-1]),
            "rms": _by_joint(state.joints, whole["rms"]),
            "max_abs": _by_joint(state.joints, whole["max_abs"]),
        },
        "moving_reference": None,
    }
    runs = moving_segments(q_d, state.rows.get("dq_d"))
    if runs:
        segments, weighted, peak, total = [], 0.0, 0.0, 0.0
        for a, b in runs:
            e = metrics.tracking_error(t[a:b], q[a:b], q_d[a:b])
            span = float(t[b - 1] - t[a])
            weighted = weighted + e["rms"] ** 2 * span  # ∫e² dt of this run
            peak = np.maximum(peak, e["max_abs"])
            total += span
            segments.append(
                {
                    "t_start": float(t[a]),
                    "t_end": float(t[b - 1]),
                    "rms": _by_joint(state.joints, e["rms"]),
                    "max_abs": _by_joint(state.joints, e["max_abs"]),
                }
            )
        rms = np.sqrt(weighted / total) if total > 0.0 else np.full(len(state.joints), math.nan)
        result["moving_reference"] = {
            "duration": total,
            "rms": _by_joint(state.joints, rms),
            "max_abs": _by_joint(state.joints, peak),
            "segments": segments,
        }
    return result


def _clamped_fraction(t: np.ndarray, tau: np.ndarray, tau_unclamped: np.ndarray) -> np.ndarray:
    """Time-weighted fraction of the record where τ was clamped (|τ_unclamped − τ| > tol),
    each sample holding until the next, as :func:`metrics.torque_demand` weighs it."""
    clamped = (np.abs(tau_unclamped - tau) > SATURATION_TOL).astype(float)
    total = t[-1] - t[0]
    if total > 0.0:
        return np.diff(t) @ clamped[:-1] / total
    return np.mean(clamped, axis=0)


def _torque(state: ControllerState, config: dict | None, warnings: list[str]) -> dict:
    """Peaks and saturation; a joint is saturated at its configured effort limit, or, when
    it has none (no configuration, or ``null``: unbounded in the URDF), while the controller
    clamped its command (τ_unclamped ≠ τ). ``saturation_source`` says which, per joint."""
    t, tau, joints = state.stamp, state.rows["tau"], state.joints
    n = len(joints)
    limits = config_values(config, "effort_limits", joints, warnings)
    if limits is None:
        limits = np.full(n, math.nan)
    if np.any(limits <= 0.0):
        warnings.append(f"configuration effort_limits <= 0 ignored: {limits.tolist()}")
    known = np.isfinite(limits) & (limits > 0.0)
    demand = metrics.torque_demand(t, tau)
    clamped = None
    if "tau_unclamped" in state.rows:
        clamped = _clamped_fraction(t, tau, state.rows["tau_unclamped"])
    saturated = np.full(n, math.nan) if clamped is None else clamped.copy()
    if np.any(known):
        at_limit = metrics.torque_demand(t, tau[:, known], limits[known], SATURATION_TOL)
        saturated[known] = at_limit["saturated_fraction"]
    source = np.where(known, "effort_limits", "tau_unclamped" if clamped is not None else None)
    return {
        "peak_abs": _by_joint(joints, demand["peak_abs"]),
        "peak_rate": _by_joint(joints, demand["peak_rate"]),
        "saturated_fraction": _by_joint(joints, saturated),
        "saturation_source": dict(zip(joints, source.tolist(), strict=True)),
        "clamped_fraction": None if clamped is None else _by_joint(joints, clamped),
        "effort_limits": _by_joint(joints, np.where(known, limits, math.nan)),  # NaN → null
    }


def _static_offset(state: ControllerState) -> dict:
    """Mean e = q_d − q over the last :data:`metrics.DEFAULT_FINAL_WINDOW` of the record (at
    least its last sample): the static offset of a run that ends at rest."""
    t = state.stamp
    t_start = max(float(t[0]), float(t[-1]) - metrics.DEFAULT_FINAL_WINDOW)
    e = metrics.mean_error(t, state.rows["q"], state.rows["q_d"], t_start=t_start)
    return {
        "t_start": t_start,
        "t_end": float(t[-1]),
        "mean_error": _by_joint(state.joints, e),
    }


def _frequency_response(state: ControllerState) -> list[dict] | None:
    """Gain and phase of q relative to q_d in every run of a moving reference where a
    joint's q_d is a sinusoid (ω from :func:`metrics.sinusoid_frequency`; needs the q̈_d row).

    A run holding P ≥ 2 whole periods 2π/ω is fitted over its last max(1, ⌊P/2⌋) periods, so
    that at least the first period, and about half the run, lets the transient decay; a
    joint with P < 2 is left out. None when no run has a measured joint."""
    ddq_d = state.rows.get("ddq_d")
    if ddq_d is None:
        return None
    t, q, q_d = state.stamp, state.rows["q"], state.rows["q_d"]
    out = []
    for a, b in moving_segments(q_d, state.rows.get("dq_d")):
        omega = metrics.sinusoid_frequency(q_d[a:b], ddq_d[a:b])
        span = float(t[b - 1] - t[a])
        joints = {}
        for j, name in enumerate(state.joints):
            if not np.isfinite(omega[j]):
                continue
            period = 2.0 * math.pi / float(omega[j])
            whole = math.floor(span / period * (1.0 + 1e-12))
            if whole < 2:
                continue
            t_fit = float(t[b - 1]) - max(1, whole // 2) * period * (1.0 + 1e-10)
            point = frequency.frequency_response(
                t[a:b], q_d[a:b, j], q[a:b, j], float(omega[j]), t_start=t_fit
            )
            joints[name] = {
                "omega": point.omega,
                "gain": float(point.gain[0]),
                "gain_db": float(point.gain_db[0]),
                "phase": float(point.phase[0]),
                "periods": point.periods,
                "t_fit_start": point.t_start,
                "t_fit_end": point.t_end,
            }
        if joints:
            out.append({"t_start": float(t[a]), "t_end": float(t[b - 1]), "joints": joints})
    return out or None


def _periods(state: ControllerState) -> dict:
    if len(state) < 2:
        return {"stamp_period_ms": None, "receive_period_ms": None}

    def in_ms(stats: dict[str, float], scale: float) -> dict[str, float]:
        return {k: (v if k == "count" else v * scale) for k, v in stats.items()}

    return {
        "stamp_period_ms": in_ms(metrics.period_statistics(state.stamp), 1e3),
        "receive_period_ms": in_ms(metrics.period_statistics(np.sort(state.log_time)), 1e-6),
    }


def controller_metrics(
    state: ControllerState,
    configs: Sequence[tuple[int, dict]] = (),
    warnings: list[str] | None = None,
) -> dict:
    """Every metric of one controller's (cleaned, see :func:`last_run`) state record.

    ``configs`` are the controller's configurations (log time [ns], dict) in the order
    received; the one in force at a step's start gives that step's prediction, the last
    one the effort limits. Returns a JSON-ready dict (see the module doc for units):
    ``node``, ``state_topic``, ``robot``, ``law``, ``joints``, ``config``, ``time``,
    ``final_error``, ``static_offset``, ``steps``, ``tracking_error``, ``torque_demand``,
    ``torque_chatter_rms``, ``frequency_response``, ``period_statistics``, ``second_order``,
    ``warnings``.
    """
    warnings = [] if warnings is None else warnings
    if len(state) == 0:
        raise ValueError(f"{state.topic}: no sample to analyse")
    config = config_at(configs, int(state.log_time[-1]))
    if config is None:
        warnings.append(
            "no configuration topic (<node>/config): no effort limits (saturation from "
            "tau_unclamped vs tau) and no second-order prediction"
        )
    joints = state.joints
    t, q, q_d = state.stamp, state.rows["q"], state.rows["q_d"]
    steps = [
        step_response(state, seg, configs, warnings)
        for seg in step_segments(t, q_d, q, state.rows.get("dq_d"))
    ]
    second_order = _prediction(config, joints, warnings)
    result = {
        "node": state.node,
        "state_topic": state.topic,
        "config_topic": state.node.rstrip("/") + "/config" if configs else None,
        "robot": None if config is None else config.get("robot"),
        "law": None if config is None else config.get("law"),
        "joints": list(joints),
        "fields": list(state.fields),
        "config": config,
        "config_count": len(configs),
        "time": {"start": float(t[0]), "end": float(t[-1]), "duration": float(t[-1] - t[0])},
        "final_error": _by_joint(joints, q_d[-1] - q[-1]),
        "steps": steps,
        "tracking_error": _tracking(state),
        "torque_demand": _torque(state, config, warnings),
        "static_offset": _static_offset(state),
        "torque_chatter_rms": _by_joint(joints, metrics.torque_chatter_rms(t, state.rows["tau"])),
        "frequency_response": _frequency_response(state),
        "period_statistics": _periods(state),
        "second_order": None
        if second_order is None
        else {
            name: {k: float(v[j]) for k, v in second_order.items()}
            for j, name in enumerate(joints)
        },
        "warnings": list(dict.fromkeys(warnings)),
    }
    return jsonable(result)
