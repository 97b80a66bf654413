"""Experiment scenarios: every installed file loads; invalid ones are refused with a reason;
variants and references are built as written; the theory checks judge synthetic metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.workbench.experiments.judging import theory
from joint_space_control.workbench.experiments.scenarios.format import (
    available,
    build_reference,
    load,
    parse,
)

MINIMAL = {
    "title": "t",
    "question": 1,
    "robot": "planar_2dof",
    "duration": 2.0,
    "controller": "pd_gravity_controller",
    "reference": {"shape": "step", "target": [0.1, 0.2]},
}


def test_every_installed_scenario_loads_and_answers_a_question():
    scenarios = available()
    assert len(scenarios) >= 12
    questions = set()
    for name in scenarios:
        s = load(name)
        questions.add(s.question)
        assert s.checks, f"{name} checks nothing"
        assert s.short_duration <= s.duration
        for label, run in s.runs(short=True):
            assert run.variants is None and label
    # THEORY.md §5: experiments 1–8; §4, the practical specifications: 9 disturbance,
    # 10 sampling period, 11 bandwidth, 12 measurement noise, 13 Coulomb friction, 14
    # accuracy and repeatability; in practice: 15 two robots in one world
    assert questions == set(range(1, 16))
    robots = {setup.robot for n in scenarios for setup in load(n).setups()}
    assert robots == {"planar_2dof", "iiwa"}


def test_variants_replace_the_named_settings():
    s = load("q7_mismatch_inverse_dynamics")
    runs = dict(s.runs())
    assert list(runs) == ["nominal", "mass_-20pct", "payload_10kg", "friction_20"]
    assert runs["mass_-20pct"].parameters["model_mass_scale"] == 0.8
    assert "model_mass_scale" not in runs["nominal"].parameters
    assert runs["payload_10kg"].plant["payload_mass"] == 10.0
    assert "payload_mass" not in s.plant  # the scenario itself is not changed
    assert [label for label, _ in s.runs(short=True)] == ["nominal", "friction_20"]
    sweep = load("q8_settling_sweep")
    assert [r.parameters["omega_n"] for _, r in sweep.runs()] == [5.0, 10.0, 20.0, 40.0, 80.0]


def test_a_variant_may_switch_the_controller_executable():
    s = parse(
        {
            **MINIMAL,
            "figures": ["overlay"],
            "variants": {
                "runs": [
                    {"label": "pd"},
                    {"label": "id", "set": {"controller": "inverse_dynamics_controller"}},
                ]
            },
        },
        "cmp",
        Path("cmp.yaml"),
    )
    runs = dict(s.runs())
    assert runs["pd"].controller == "pd_gravity_controller"
    assert runs["id"].controller == "inverse_dynamics_controller"
    assert s.controller == "pd_gravity_controller"  # the scenario itself is not changed
    assert s.figures == ("overlay",)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"colour": "red"}, "unknown keys"),
        ({"duration": -1}, "'duration' must be a number > 0"),
        ({"controller": "lqr"}, "'controller' must be one of"),
        ({"mode": "realtime"}, "lockstep"),
        ({"reference": {"shape": "spiral"}}, "reference shape"),
        ({"reference": {"shape": "step"}}, "needs 'target'"),
        ({"reference": {"shape": "step", "target": [0.1], "speed": 2}}, "unknown keys"),
        ({"changes": [{"at": 2.0}, {"at": 1.0}]}, "strictly increasing"),
        ({"changes": [{"at": 1.0, "update": "guess"}]}, "'update' must be one of"),
        ({"variants": {"key": "gains.kp", "values": [1]}}, "plant.X, parameters.X"),
        ({"variants": {"key": "parameters.kp", "values": []}}, "non-empty list"),
        ({"variants": {"runs": [{"set": {"controller": "lqr"}}]}}, "'controller' must be"),
        ({"figures": ["spiral"]}, "'figures' must be a list of"),
        ({"figures": "overlay"}, "'figures' must be a list of"),
    ],
)
def test_invalid_scenarios_are_refused_with_a_reason(change, match):
    with pytest.raises(ValueError, match=match):
        parse({**MINIMAL, **change}, "bad", Path("bad.yaml"))


WORLD = {
    "title": "t",
    "question": 15,
    "duration": 2.0,
    "plant": {"physics_rate": 1000.0},
    "robots": {
        "iiwa": {
            "robot": "iiwa",
            "controller": "pd_gravity_controller",
            "parameters": {"kp": 100.0},
            "reference": {"shape": "step", "target": [0.1] * 7},
        },
        "arm": {
            "robot": "planar_2dof",
            "plant": {"base_position": [2.2, 0.0, 0.0], "initial_positions": [0.1, 0.2]},
            "controller": "inverse_dynamics_controller",
            "reference": {"shape": "quintic", "target": [0.5, -0.3], "duration": 1.0},
        },
    },
    "checks": [{"check": "final_error"}],
}


def test_a_world_of_robots_is_one_run_of_one_setup_per_robot():
    s = parse(WORLD, "world", Path("world.yaml"))
    assert [r.name for r in s.setups()] == ["iiwa", "arm"]
    arm = s.setups()[1]
    assert (arm.robot, arm.controller) == ("planar_2dof", "inverse_dynamics_controller")
    assert arm.plant == {"base_position": [2.2, 0.0, 0.0], "initial_positions": [0.1, 0.2]}
    assert s.setups()[0].parameters == {"kp": 100.0} and arm.parameters == {}
    assert (s.robot, s.controller) == (
        "iiwa + planar_2dof",
        "pd_gravity_controller + inverse_dynamics_controller",
    )
    assert [label for label, _ in s.runs()] == ["run"] == [lbl for lbl, _ in s.runs(True)]
    # what a check sees of a robot: a one-robot scenario, the world's plant under its own
    view = s.of_robot(arm)
    assert view.name == "world/arm" and view.robots == () and view.robot == "planar_2dof"
    assert view.plant == {"physics_rate": 1000.0, **arm.plant}
    assert view.reference == arm.reference and view.setups()[0].name == ""
    # one robot: one setup in the root namespace, which is the scenario itself
    one = parse(MINIMAL, "one", Path("one.yaml"))
    (setup,) = one.setups()
    assert (setup.name, setup.robot, setup.reference) == ("", "planar_2dof", MINIMAL["reference"])
    assert one.of_robot(setup) is one


def test_the_two_robots_scenario_puts_the_arm_beside_the_iiwa():
    s = load("two_robots")
    iiwa, arm = s.setups()
    assert (iiwa.name, iiwa.robot, arm.name, arm.robot) == ("iiwa", "iiwa", "arm", "planar_2dof")
    assert iiwa.controller != arm.controller
    assert arm.plant["base_position"][0] >= 2.0  # out of the iiwa's reach
    assert {c["check"] for c in s.checks} == {"final_error", "second_order"}


def _world(**change):
    robots = {name: {**spec, **change.pop(name, {})} for name, spec in WORLD["robots"].items()}
    return {**WORLD, "robots": robots, **change}


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (_world(robot="iiwa"), r"with 'robots', \['robot'\] belong to each robot"),
        (_world(changes=[{"at": 1.0}]), "with 'robots'"),
        (_world(variants={"key": "plant.x", "values": [1]}), "with 'robots'"),
        (_world(figures=["overlay"]), "with 'robots'"),
        ({**WORLD, "robots": {}}, "at least one robot"),
        ({**WORLD, "robots": {"2nd": WORLD["robots"]["arm"]}}, "is not a name"),
        ({**WORLD, "robots": {"a-b": WORLD["robots"]["arm"]}}, "is not a name"),
        (_world(arm={"colour": "red"}), r"robots.arm: unknown keys \['colour'\]"),
        (_world(arm={"controller": "lqr"}), "robots.arm: 'controller' must be one of"),
        (_world(arm={"plant": [1, 2]}), "'robots.arm.plant' must be a mapping"),
        (
            {**WORLD, "robots": {"arm": {"robot": "planar_2dof", "reference": {}}}},
            "robots.arm: missing 'controller'",
        ),
        (_world(arm={"reference": {"shape": "step"}}), "robots.arm: reference 'step' needs"),
    ],
)
def test_invalid_worlds_are_refused_with_a_reason(data, match):
    with pytest.raises(ValueError, match=match):
        parse(data, "bad", Path("bad.yaml"))


def test_a_scenario_file_outside_the_package_loads(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(MINIMAL))
    assert load(str(path)).name == "mine"
    with pytest.raises(ValueError, match="no scenario"):
        load("no_such_scenario")


def test_references_are_built_from_the_initial_configuration():
    q0 = np.array([-1.0, 0.5])
    sin = build_reference({"shape": "sinusoid", "amplitude": 0.2, "omega": 2.0}, q0, 3.0)
    np.testing.assert_allclose(sin.positions[0], q0)  # centre defaults to q0
    assert sin.times[-1] == pytest.approx(3.0)
    quintic = build_reference({"shape": "quintic", "target": [0, 0], "duration": 2}, q0, 5.0)
    np.testing.assert_allclose(quintic.positions, [q0, [0.0, 0.0]])


# --------------------------------------------------------------------------- checks
def controller_metrics(overshoot, settling, sse=0.0, kp=(64.0,), kd=(8.0,)):
    predicted = second_order_prediction(np.sqrt(kp), np.array(kd) / (2 * np.sqrt(kp)))
    prediction = {k: float(v[0]) for k, v in predicted.items()}
    return {
        "joints": ["j1"],
        "final_error": {"j1": sse},
        "config": {"kp": list(kp), "kd": list(kd)},
        "steps": [
            {
                "joints": {
                    "j1": {
                        "moving": True,
                        "overshoot_percent": overshoot,
                        "settling_time_2": settling,
                        "steady_state_error": sse,
                        "target": 0.5,
                        "prediction": prediction,
                    }
                }
            }
        ],
    }, prediction


def view(c, label="run", events=()):
    return theory.RunView(label, "planar_2dof", c, list(events), {})


def test_second_order_check_uses_the_stated_tolerances():
    c, p = controller_metrics(0, 0)
    good, _ = controller_metrics(p["overshoot_percent"] + 0.9, p["settling_time_2"] * 1.04)
    bad_os, _ = controller_metrics(p["overshoot_percent"] + 1.1, p["settling_time_2"])
    bad_ts, _ = controller_metrics(p["overshoot_percent"], p["settling_time_2"] * 1.06)
    bad_sse, _ = controller_metrics(p["overshoot_percent"], p["settling_time_2"], sse=2e-4)
    verdicts = [theory.second_order([view(x)])[0].passed for x in (good, bad_os, bad_ts, bad_sse)]
    assert verdicts == [True, False, False, False]


def test_final_error_tracking_and_degradation_checks():
    def tracked(rms):
        return {"joints": ["j1"], "tracking_error": {"whole_record": {"rms": {"j1": rms}}}}

    runs = [view(tracked(x), f"w{x}") for x in (0.01, 0.02, 0.05)]
    assert theory.tracking_grows(runs)[0].passed is True
    assert theory.tracking_grows(runs[::-1])[0].passed is False
    assert theory.degrades(runs)[0].passed is True
    assert theory.degrades(runs[::-1])[0].passed is False
    fe = [view({"joints": ["j1"], "final_error": {"j1": e}}) for e in (5e-4, 2e-3)]
    assert [o.passed for o in theory.final_error(fe, tol=1e-3)] == [True, False]


def test_pd_offset_check_balances_gravity_against_the_spring():
    """A measured equilibrium that satisfies g(q_e) = K_P(q_d − q_e) passes; one that does
    not fails."""
    from joint_space_control.model.dynamics import RobotModel
    from joint_space_control.model.robots import resolve_robot

    model = RobotModel(resolve_robot("planar_2dof"))
    kp = np.array([2000.0, 1000.0])
    q_d = np.array([0.5, -0.3])
    q_e = q_d.copy()
    for _ in range(100):  # fixed point of q_e = q_d − K_P⁻¹ g(q_e)
        q_e = q_d - model.gravity(q_e) / kp

    def run(q):
        c = {
            "joints": ["joint1", "joint2"],
            "final_error": dict(zip(["joint1", "joint2"], (q_d - q).tolist(), strict=True)),
            "config": {"kp": kp.tolist()},
        }
        return view(c, events=[{"q": q.tolist()}])

    assert theory.pd_offset([run(q_e)])[0].passed is True
    assert theory.pd_offset([run(q_e + 0.01)])[0].passed is False


def test_gravity_bound_is_the_largest_gravity_jacobian_norm():
    """planar_2dof: g = 9.81 [75 c1 + 25 c12, 25 c12] (m = 50 kg, COM at 0.5 m, a = 1 m), so
    ∂g/∂q = −9.81 [[75 s1 + 25 s12, 25 s12], [25 s12, 25 s12]], largest in norm at
    s1 = s12 = ±1: 9.81 · λ_max([[100, 25], [25, 25]]) = 9.81 · (125 + √8125) / 2."""
    exact = 9.81 * (125 + np.sqrt(8125.0)) / 2
    alpha = theory.gravity_bound("planar_2dof", samples=2000)
    assert alpha <= exact * (1 + 1e-9)  # sampled: never above the supremum
    assert alpha > 0.995 * exact


def test_the_short_form_keeps_the_runs_variants_short_names():
    s = load("repeatability")
    assert [label for label, _ in s.runs(short=True)] == [
        "friction-1",
        "friction-2",
        "noise-1",
        "noise-2",
    ]
    with pytest.raises(ValueError, match="'variants.short' must list run labels"):
        parse(
            {**MINIMAL, "variants": {"key": "parameters.kp", "values": [1, 2], "short": ["x"]}},
            "bad",
            Path("bad.yaml"),
        )
