"""Grids of sweep keys (issue 18): parsing, the theory boundaries drawn on their heat maps,
the heat maps themselves from synthetic results, and the checks that judge grids."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from joint_space_control.workbench.experiments.execution import values
from joint_space_control.workbench.experiments.judging import boundaries, theory
from joint_space_control.workbench.experiments.presentation import sweep_figures
from joint_space_control.workbench.experiments.scenarios.format import Axis, available, load, parse

ID = "inverse_dynamics_controller"

STEP = {
    "title": "t",
    "question": 7,
    "robot": "planar_2dof",
    "duration": 2.0,
    "plant": {"initial_positions": [-1.0, 0.5]},
    "controller": "inverse_dynamics_controller",
    "parameters": {"law": "inverse_dynamics", "omega_n": 10.0, "zeta": 1.0},
    "reference": {"shape": "step", "target": [-0.9, 0.35]},
}
MASS = {"key": "parameters.model_mass_scale", "values": [0.6, 1.0, 1.4], "unit": "×"}
OMEGA = {"key": "parameters.omega_n", "values": [5, 10, 20, 40], "unit": "rad/s", "scale": "log"}


def grid(*axes, **variants):
    return parse({**STEP, "variants": {"grid": list(axes), **variants}}, "g", Path("g.yaml"))


# --------------------------------------------------------------------------- parsing
def test_a_grid_runs_the_product_of_its_axes_in_row_major_order():
    s = grid(MASS, OMEGA)
    v = s.variants
    assert v.shape == (3, 4) and v.describe() == "12 runs (3×4 grid)"
    assert [a.name for a in v.axes] == ["model_mass_scale", "omega_n"]  # last part of the key
    assert v.name == "model_mass_scale × omega_n"
    labels = [label for label, _ in s.runs()]
    assert labels[:5] == [
        "model_mass_scale=0.6,omega_n=5",
        "model_mass_scale=0.6,omega_n=10",
        "model_mass_scale=0.6,omega_n=20",
        "model_mass_scale=0.6,omega_n=40",
        "model_mass_scale=1,omega_n=5",
    ]
    assert list(v.grid_index) == [(i, j) for i in range(3) for j in range(4)]
    run = dict(s.runs())["model_mass_scale=1.4,omega_n=20"]
    assert run.parameters == {**STEP["parameters"], "model_mass_scale": 1.4, "omega_n": 20}
    assert s.parameters["omega_n"] == 10.0  # the scenario itself is not changed
    # the short form: the corners, in grid order
    assert [label for label, _ in s.runs(short=True)] == [
        "model_mass_scale=0.6,omega_n=5",
        "model_mass_scale=0.6,omega_n=40",
        "model_mass_scale=1.4,omega_n=5",
        "model_mass_scale=1.4,omega_n=40",
    ]


def test_a_grid_of_three_axes_with_names_labels_and_shared_keys():
    payload = {
        "key": "plant.payload_mass",
        "also": ["parameters.model_payload_mass"],
        "values": [0.0, 5.0],
        "name": "payload",
        "label": "payload",
        "unit": "kg",
    }
    s = grid(MASS, OMEGA, payload, name="three", short=["model_mass_scale=1,omega_n=10,payload=5"])
    v = s.variants
    assert v.shape == (3, 4, 2) and v.name == "three" and len(s.runs()) == 24
    assert v.grid_index[1] == (0, 0, 1)  # the last axis varies fastest
    label, run = s.runs(short=True)[0]
    assert label == "model_mass_scale=1,omega_n=10,payload=5"
    assert run.plant["payload_mass"] == 5.0 and run.parameters["model_payload_mass"] == 5.0
    axis = v.axes[2]
    assert (axis.keys, axis.title) == (
        ("plant.payload_mass", "parameters.model_payload_mass"),
        "payload [kg]",
    )
    assert v.axes[1].title == "omega_n [rad/s]"  # label defaults to the name
    one = grid({**MASS, "values": [1.0]}, {**OMEGA, "values": [5, 40]})
    assert [label for label, _ in one.runs(short=True)] == [
        "model_mass_scale=1,omega_n=5",
        "model_mass_scale=1,omega_n=40",
    ]


@pytest.mark.parametrize(
    ("variants", "match"),
    [
        ({"grid": [MASS]}, "two or more axes"),
        ({"grid": [MASS, {**OMEGA, "values": []}]}, r"grid\[1\].values must be a non-empty"),
        ({"grid": [MASS, {**MASS, "values": [2.0]}]}, "swept by another axis already"),
        (
            {"grid": [MASS, {**OMEGA, "also": ["parameters.model_mass_scale"]}]},
            "swept by another axis already",
        ),
        ({"grid": [MASS, {**OMEGA, "key": "gains.omega_n"}]}, "plant.X, parameters.X"),
        ({"grid": [MASS, {"values": [1]}]}, r"grid\[1\]: missing 'key'"),
        ({"grid": [MASS, {**OMEGA, "scale": "ln"}]}, r"scale must be one of \('linear', 'log'\)"),
        ({"grid": [MASS, {**OMEGA, "values": [0, 10]}]}, "a log axis needs numbers > 0"),
        ({"grid": [MASS, {**OMEGA, "colour": 1}]}, "unknown keys"),
        ({"grid": [MASS, {**OMEGA, "name": "model_mass_scale"}]}, "used twice"),
        ({"grid": [MASS, OMEGA], "boundary": "magic"}, "'variants.boundary' must be one of"),
        ({"grid": [MASS, OMEGA], "boundary": "kp_alpha"}, "must sweep parameters.kp"),
        ({"key": "parameters.kp", "values": [1], "boundary": "kp_alpha"}, "needs a grid"),
        ({"grid": [MASS, OMEGA], "key": "parameters.kp"}, "one of key \\+ values, runs or grid"),
        ({"grid": [MASS, OMEGA], "short": ["nope"]}, "'variants.short' must list run labels"),
    ],
)
def test_invalid_grids_are_refused_with_one_line(variants, match):
    with pytest.raises(ValueError, match=match) as err:
        parse({**STEP, "variants": variants}, "bad", Path("bad.yaml"))
    assert "\n" not in str(err.value)


def test_a_boundary_must_fit_the_scenario():
    sat = {"grid": [MASS, OMEGA], "boundary": "saturation_onset"}
    ramp = {"shape": "quintic", "target": [0, 0], "duration": 1.0}
    with pytest.raises(ValueError, match="needs a step reference"):
        parse({**STEP, "reference": ramp, "variants": sat}, "bad", Path("b.yaml"))
    pd = {**STEP, "controller": "pd_gravity_controller", "variants": sat}
    with pytest.raises(ValueError, match="needs inverse_dynamics_controller"):
        parse(pd, "bad", Path("b.yaml"))
    alpha = {
        "grid": [MASS, {"key": "parameters.kp", "values": [100, 200]}],
        "boundary": "kp_alpha",
    }
    with pytest.raises(ValueError, match="needs pd_gravity_controller"):
        parse({**STEP, "variants": alpha}, "bad", Path("b.yaml"))


def test_axis_positions_place_values_evenly_log_or_linear():
    log = Axis("parameters.omega_n", "omega_n", "ω_n", "rad/s", "log", (5, 10, 20, 80))
    np.testing.assert_allclose(log.positions([5, 10, 20, 80]), [0, 1, 2, 3])
    # half way in log between 20 and 80 is 40; beyond the ends the end segments go on
    np.testing.assert_allclose(log.positions([40, 5 / np.sqrt(2), 160]), [2.5, -0.5, 3.5])
    p = np.linspace(-0.5, 3.5, 17)
    np.testing.assert_allclose(log.positions(log.values_at(p)), p, atol=1e-12)
    lin = Axis("plant.payload_mass", "payload", "payload", "kg", "linear", (0.0, 10.0, 40.0))
    np.testing.assert_allclose(lin.positions([5.0, 25.0, -5.0]), [0.5, 1.5, -0.5])
    assert np.isnan(lin.positions([np.nan])).all()
    words = Axis("parameters.law", "law", "law", "", "linear", ("a", "b"))
    assert not words.numeric
    np.testing.assert_array_equal(words.positions(["b", "c"]), [1.0, np.nan])


# --------------------------------------------------------------------------- boundaries
def test_saturation_onset_is_where_the_first_command_reaches_a_limit():
    """τ(0) = B̂(q0) ω_n² Δ + ĝ(q0) at the returned ω_n: one joint exactly at its limit
    (to 1e-9), none beyond; B̂ and ĝ scale with model_mass_scale, so the onset falls."""
    q0, target = np.array([-1.0, 0.5]), np.array([-0.9, 0.35])
    onsets = []
    for scale in (0.6, 1.0, 1.4):
        model = values.controller_model(ID, "planar_2dof", {"model_mass_scale": scale})
        omega = boundaries.saturation_onset_omega(model, q0, target - q0)
        tau = boundaries.step_torque_at_rest(model, q0, target - q0, omega)
        ratio = np.abs(tau) / model.effort_limits
        assert ratio.max() == pytest.approx(1.0, abs=1e-9)
        below = boundaries.step_torque_at_rest(model, q0, target - q0, 0.999 * omega)
        assert np.all(np.abs(below) < model.effort_limits)
        onsets.append(omega)
        # the scenario form reads the same settings
        settings = SimpleNamespace(
            robot="planar_2dof",
            controller=ID,
            plant={"initial_positions": q0.tolist()},
            parameters={"model_mass_scale": scale},
            reference={"shape": "step", "target": target.tolist()},
        )
        assert boundaries.saturation_onset(settings) == omega
    assert onsets[0] > onsets[1] > onsets[2]
    unit = values.controller_model(ID, "planar_2dof", {})
    never = boundaries.saturation_onset_omega(unit, q0, np.zeros(2))
    assert never == math.inf


def test_gravity_bound_with_a_payload_matches_the_planar_arm_in_closed_form():
    """planar_2dof with m [kg] at the centre of mass of link 2 (0.5 m beyond joint 2):
    g = 9.81 [(75 + m) c1 + (25 + m/2) c12, (25 + m/2) c12], so
    α = 9.81 λ_max([[100 + 3m/2, 25 + m/2], [25 + m/2, 25 + m/2]]); and the sampled α bounds
    ‖∂g/∂q‖ at other configurations."""
    for m in (0.0, 40.0):
        a, b = 100 + 1.5 * m, 25 + 0.5 * m
        exact = 9.81 * np.linalg.eigvalsh([[a, b], [b, b]]).max()
        alpha = boundaries.gravity_bound("planar_2dof", m, samples=2000)
        assert exact * 0.995 < alpha <= exact * (1 + 1e-9)
        model = boundaries._model("planar_2dof", payload_mass=m)
        for q in np.random.default_rng(1).uniform(-np.pi, np.pi, size=(200, 2)):
            assert np.linalg.norm(boundaries.gravity_jacobian(model, q), 2) <= exact * (1 + 1e-9)


def test_boundary_curves_follow_the_other_axis():
    s = grid(MASS, OMEGA, boundary="saturation_onset")
    curve = boundaries.curve("saturation_onset", s, s.variants.axes)
    scales = np.array(curve.coords["parameters.model_mass_scale"])
    omegas = curve.coords["parameters.omega_n"]
    # across the drawn height: half a cell beyond the first and last values
    mass = s.variants.axes[0]
    np.testing.assert_allclose(mass.positions(scales)[[0, -1]], [-0.5, 2.5])
    for scale, omega in zip(scales[::3], omegas[::3], strict=True):
        model = values.controller_model(ID, "planar_2dof", {"model_mass_scale": scale})
        q0 = np.array([-1.0, 0.5])
        tau = boundaries.step_torque_at_rest(model, q0, np.array([0.1, -0.15]), omega)
        assert np.max(np.abs(tau) / model.effort_limits) == pytest.approx(1.0, abs=1e-9)
    q3 = load("q3_constant_gravity_grid")
    payload, kp = q3.variants.axes
    curve = boundaries.curve("kp_alpha", q3, q3.variants.axes)
    at = np.array(curve.coords[payload.key])
    alphas = curve.coords[kp.key]
    assert np.isnan(alphas[at < 0]).all()  # no negative payload: not drawn
    for m in (0.0, 20.0, 40.0):
        (k,) = np.flatnonzero(np.isclose(at, m))
        assert alphas[k] == boundaries.gravity_bound("planar_2dof", m)


# --------------------------------------------------------------------------- heat maps
def metrics(rms=0.01, peak=500.0, sat=0.0, settle=0.5, final=1e-4, limit=2000.0):
    steps = (
        []
        if settle is False
        else [{"joints": {"j1": {"moving": True, "settling_time_2": settle}}}]
    )
    return {
        "joints": ["j1"],
        "tracking_error": {"whole_record": {"rms": {"j1": rms}}, "moving_reference": None},
        "torque_demand": {
            "peak_abs": {"j1": peak},
            "effort_limits": {"j1": limit},
            "saturated_fraction": {"j1": sat},
        },
        "steps": steps,
        "final_error": {"j1": -final},
    }


def result(s, make, failed=(), only=None):
    runs = []
    for k, (label, _) in enumerate(s.variants.runs):
        if only is not None and label not in only:
            continue
        bad = label in failed
        c = None if bad else make(s.variants.grid_index[k])
        runs.append(SimpleNamespace(label=label, error="boom" if bad else None, controller=c))
    return SimpleNamespace(scenario=s, runs=runs)


def test_heat_maps_leave_out_undefined_quantities_and_mark_failed_runs(tmp_path):
    s = grid(MASS, OMEGA, boundary="saturation_onset")
    res = result(
        s,
        lambda ij: metrics(rms=0.01 * (1 + ij[0]), peak=500.0 * (1 + ij[1]), settle=None),
        failed=["model_mass_scale=1,omega_n=20"],
    )
    values = sweep_figures.grid_values(res)
    assert values.failed[1, 2] and values.failed.sum() == 1 and values.ran.all()
    titles = [m.title for m, _ in values.values]
    assert titles == [
        "RMS tracking error [rad]",
        "peak |τ| / effort limit",
        "saturated fraction [%]",
        "final |q_d − q| [rad]",
    ]  # no run settles: no settling panel
    rms = values.values[0][1]
    assert rms[2, 3] == pytest.approx(0.03) and np.isnan(rms[1, 2])
    assert values.values[1][1][0, 3] == pytest.approx(1.0)  # 2000 N·m of 2000
    path = tmp_path / "sweep.png"
    assert sweep_figures.draw(res, path) == titles
    assert path.stat().st_size > 10_000
    # no limit known on a run: peak torque in N·m
    res.runs[0].controller["torque_demand"]["effort_limits"] = {"j1": None}
    assert [m.title for m, _ in sweep_figures.grid_values(res).values][1] == "peak |τ| [N·m]"


def test_heat_maps_of_the_short_form_and_of_three_axes(tmp_path):
    s = grid(MASS, OMEGA)
    corners = [label for label, _ in s.runs(short=True)]
    res = result(s, lambda ij: metrics(settle=0.2 + ij[1]), only=corners)
    values = sweep_figures.grid_values(res)
    assert values.ran.sum() == 4 and values.ran[0, 0] and values.ran[2, 3]
    assert sweep_figures.draw(res, tmp_path / "short.png")
    payload = {"key": "plant.payload_mass", "values": [0.0, 5.0], "name": "payload"}
    three = grid(MASS, OMEGA, payload, boundary="saturation_onset")
    res3 = result(three, lambda ijk: metrics(rms=0.01 + ijk[2]))
    values3 = sweep_figures.grid_values(res3)
    assert values3.shape == (3, 4, 2)
    assert values3.values[0][1][1, 1, 1] == pytest.approx(1.01)
    assert sweep_figures.draw(res3, tmp_path / "three.png")
    assert (tmp_path / "three.png").is_file()


def test_nothing_defined_draws_nothing_and_one_axis_sweeps_stay_bars(tmp_path):
    s = grid(MASS, OMEGA)
    res = result(s, lambda ij: None, failed=[label for label, _ in s.runs()])
    assert sweep_figures.draw(res, tmp_path / "none.png") == []
    assert not (tmp_path / "none.png").exists()
    bars = load("q8_settling_sweep")
    res = SimpleNamespace(
        scenario=bars,
        runs=[
            SimpleNamespace(label=label, error=None, controller=metrics(settle=False))
            for label, _ in bars.runs()
        ],
    )
    assert "2 % settling time [s]" not in sweep_figures.draw(res, tmp_path / "bars.png")
    assert (tmp_path / "bars.png").is_file()


def test_cell_text_and_ticks_stay_short():
    assert [sweep_figures.cell_text(x) for x in (0, 0.0316, 2.4e-4, 12345.0, 1.0)] == [
        "0",
        "0.0316",
        "2.4e-4",
        "1.2e4",
        "1",
    ]
    assert sweep_figures.tick([100.0, 50]) == "100/50" and sweep_figures.tick(0.6) == "0.6"
    assert [sweep_figures.tick(x) for x in (1500.0, 2200.0, 1.0, 0.125, 1e7)] == [
        "1500",
        "2200",
        "1",
        "0.125",
        "1e+07",
    ]


# --------------------------------------------------------------------------- checks
def view(label, omega, scale, sat, robot="planar_2dof"):
    c = {"joints": ["j1", "j2"], "torque_demand": {"saturated_fraction": {"j1": sat, "j2": 0.0}}}
    return theory.RunView(
        label,
        robot,
        c,
        [],
        {"law": "inverse_dynamics", "omega_n": omega, "model_mass_scale": scale},
        {"initial_positions": [-1.0, 0.5]},
        "inverse_dynamics_controller",
        reference={"shape": "step", "target": [-0.9, 0.35]},
    )


def test_saturation_boundary_judges_each_side_with_its_margin():
    onset = boundaries.saturation_onset(view("x", 1.0, 1.0, 0.0))
    runs = [
        view("low", 0.8 * onset, 1.0, 0.0),
        view("high", 1.2 * onset, 1.0, 0.01),
        view("near", 1.05 * onset, 1.0, 0.0),
    ]
    below, above, near = theory.saturation_boundary(runs, margin=0.15)
    assert (below.passed, above.passed, near.passed) == (True, True, None)
    assert below.numbers["labels"] == ["low"] and near.numbers["labels"] == ["near"]
    wrong = [view("low", 0.8 * onset, 1.0, 0.001), view("high", 1.2 * onset, 1.0, 0.0)]
    assert [o.passed for o in theory.saturation_boundary(wrong, margin=0.15)] == [False, False]
    # a lighter controller model saturates later: 1.1 × the nominal onset is below its own
    light = boundaries.saturation_onset(view("x", 1.0, 0.6, 0.0))
    assert 0.85 * light > 1.1 * onset
    (only,) = theory.saturation_boundary([view("l", 1.1 * onset, 0.6, 0.0)], margin=0.15)
    assert only.passed is True and only.numbers["onset"] == [light]


def test_where_and_unsaturated_select_the_runs_a_check_judges():
    runs = [
        view("a", 8.0, 1.0, 0.0),
        view("b", 30.0, 1.0, 0.02),
        view("c", 8.0, 0.6, 0.0),
    ]
    assert [r.label for r in theory.select(runs, {"parameters.model_mass_scale": 1.0})] == [
        "a",
        "b",
    ]
    assert [r.label for r in theory.select(runs, None, unsaturated=True)] == ["a", "c"]
    spec = {"check": "saturation_boundary", "where": {"parameters.model_mass_scale": 1.4}}
    (none,) = theory.evaluate(spec, runs)
    assert none.passed is None and "no run with parameters.model_mass_scale = 1.4" in none.text
    with pytest.raises(ValueError, match="'where' must be a mapping"):
        theory.evaluate({"check": "final_error", "where": [1]}, runs)


def pd_view(label, kp, payload, final, model_payload=None):
    c = {
        "joints": ["joint1", "joint2"],
        "final_error": {"joint1": final[0], "joint2": final[1]},
        "config": {"kp": [kp, kp]},
        "steps": [{"joints": {"joint1": {"target": 1.2}, "joint2": {"target": -0.8}}}],
    }
    params = {"kp": kp, "model_payload_mass": payload if model_payload is None else model_payload}
    return theory.RunView(
        label, "planar_2dof", c, [], params, {"payload_mass": payload}, "pd_gravity_controller"
    )


def test_constant_gravity_judges_above_alpha_of_each_plant_and_summarises_a_grid():
    alpha40 = boundaries.gravity_bound("planar_2dof", 40.0)
    assert alpha40 > 1600.0  # the payload raises α above the unloaded 1055 N·m/rad
    runs = [
        pd_view("above", 1900.0, 40.0, [1e-5, 2e-5]),
        pd_view("above_but_loaded", 1600.0, 40.0, [1e-5, 0.0]),  # 1600 < α(40 kg)
        pd_view("stuck", 2200.0, 0.0, [0.5, 0.0]),
    ]
    above, below = theory.constant_gravity(runs, tol=1e-3, per_run=False)
    assert above.passed is False and "stuck (0.5 rad)" in above.text
    assert above.numbers["labels"] == ["above", "stuck"]
    assert below.passed is None and below.numbers["labels"] == ["above_but_loaded"]
    per_run = theory.constant_gravity(runs, tol=1e-3)
    assert [o.passed for o in per_run] == [True, None, False]


def test_constant_gravity_with_an_unmodelled_payload_predicts_the_equilibrium():
    """ĝ(q_d) of a model without the plant's 20 kg: the arm comes to rest at q_e with
    K_P (q_d − q_e) = g(q_e) − ĝ(q_d), not at q_d."""
    kp, q_d = 2500.0, np.array([1.2, -0.8])
    r = pd_view("x", kp, 20.0, [0.0, 0.0], model_payload=0.0)
    q_e = theory._gravity_equilibrium(r, q_d, np.array([kp, kp]))
    plant = boundaries._model("planar_2dof", payload_mass=20.0)
    g_hat = boundaries._model("planar_2dof").gravity(q_d)
    np.testing.assert_allclose(kp * (q_d - q_e), plant.gravity(q_e) - g_hat, atol=1e-9)
    assert np.max(np.abs(q_d - q_e)) > 0.01
    at_q_e = pd_view("at", kp, 20.0, (q_d - q_e).tolist(), model_payload=0.0)
    at_q_d = pd_view("at_qd", kp, 20.0, [0.0, 0.0], model_payload=0.0)
    assert [o.passed for o in theory.constant_gravity([at_q_e, at_q_d])] == [True, False]


def test_the_grid_scenarios_are_installed_with_their_boundaries():
    for name, boundary in (
        ("q7_q8_mismatch_stiffness_planar", "saturation_onset"),
        ("q7_q8_mismatch_stiffness_iiwa", "saturation_onset"),
        ("q3_constant_gravity_grid", "kp_alpha"),
    ):
        assert name in available()
        s = load(name)
        assert s.variants.boundary == boundary and len(s.variants.axes) == 2
        assert len(s.runs(short=True)) == 4 and s.short_duration <= 1.0


def test_the_results_page_shows_a_grids_heat_maps_in_its_question(tmp_path):
    from joint_space_control.workbench.experiments.experiment import ExperimentResult
    from joint_space_control.workbench.experiments.judging.outcome import Outcome
    from joint_space_control.workbench.experiments.presentation.results import (
        results_page,
        summary_markdown,
    )

    s = grid(MASS, OMEGA, boundary="saturation_onset")
    out = tmp_path / "out" / s.name
    out.mkdir(parents=True)
    res = result(s, lambda ij: metrics(), only=[label for label, _ in s.runs(short=True)])
    for r in res.runs:
        r.out, r.events, r.namespace, r.figures = out / r.label, [], "", {}
    assert sweep_figures.draw(res, out / "sweep.png")
    outcome = Outcome("saturation_boundary", True, "4 runs below the onset: none saturates")
    experiment = ExperimentResult(s, out, res.runs, [outcome], [])
    text = summary_markdown(experiment, out)
    assert "4 runs of a 3×4 grid (model_mass_scale × omega_n)" in text
    assert "![g sweep](sweep.png)" in text
    page = results_page([experiment], tmp_path / "docs", short=True).read_text()
    section5 = page[page.index("## THEORY.md §5") :]
    assert "### 7. t" in section5 and "figures/g_sweep.png" in section5
    assert (tmp_path / "docs" / "figures" / "g_sweep.png").is_file()
    (entry,) = json.loads((tmp_path / "docs" / "results.json").read_text())["experiments"]
    assert [a["values"] for a in entry["grid"]["axes"]] == [[0.6, 1.0, 1.4], [5, 10, 20, 40]]
    assert entry["grid"]["boundary"] == "saturation_onset"
    assert [r["grid_index"] for r in entry["runs"]] == [[0, 0], [0, 3], [2, 0], [2, 3]]


def test_the_results_page_points_to_the_tuning_example_only_beside_it(tmp_path):
    from joint_space_control.workbench.experiments.presentation.results import (
        TUNING_FIGURE,
        TUNING_PAGE,
        tuning_section,
    )

    docs = tmp_path / "docs"
    assert tuning_section(docs) == []  # elsewhere (a user's --report DIR): no dangling link
    (docs / "figures").mkdir(parents=True)
    (docs / TUNING_PAGE).write_text("# Gain tuning\n")
    assert tuning_section(docs) == []  # the figure is missing: still nothing
    (docs / TUNING_FIGURE).write_bytes(b"png")
    text = "\n".join(tuning_section(docs))
    assert f"]({TUNING_PAGE}#example-a-ur5-from-example-robot-data)" in text
    assert f"]({TUNING_FIGURE})" in text


def test_the_tuning_example_the_results_page_links_exists_in_the_docs():
    from joint_space_control.workbench.experiments.presentation.results import (
        TUNING_EXAMPLE,
        TUNING_FIGURE,
        TUNING_PAGE,
    )

    docs = Path(__file__).resolve().parents[2] / "docs"
    headings = [
        line for line in (docs / TUNING_PAGE).read_text().splitlines() if line[:3] == "## "
    ]
    anchors = {"#" + h[3:].strip().lower().replace(" ", "-").replace(":", "") for h in headings}
    assert TUNING_EXAMPLE in anchors and (docs / TUNING_FIGURE).is_file()
