"""jsc tune without ROS runs (workbench/tuning/): the step problem, the search space, the parameter
file as a node reads it, the scenario it writes, the study's ask/tell loop with a stand-in
runner (the theory's second-order responses), resume, failed runs and the exit codes."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import yaml
from optuna.trial import TrialState

from joint_space_control.analysis.spec import parse_spec
from joint_space_control.cli import tune as tune_cli
from joint_space_control.cli.main import main
from joint_space_control.laws.gains import FROM_KP, FROM_OMEGA_N, choose_gains
from joint_space_control.workbench.experiments.scenarios import format as scenarios
from joint_space_control.workbench.experiments.scenarios.params_file import (
    node_parameters,
    with_params_file,
)
from joint_space_control.workbench.tuning import outputs
from joint_space_control.workbench.tuning.problem import TuneProblem, step_inside_limits
from joint_space_control.workbench.tuning.session import TuneOptions
from joint_space_control.workbench.tuning.space import SearchSpace, parse_range
from joint_space_control.workbench.tuning.study import (
    INTERRUPTED,
    best_trial,
    is_feasible,
    is_finished,
    open_study,
    run_trials,
)
from test.unit.tuning_fakes import (
    FakeResult,
    FakeRunner,
    ReorderingRunner,
    controller_metrics,
)

SPEC = "overshoot<=5, settling_2pct<=0.6"
JOINTS = ("joint1", "joint2")


def problem(spec: str = SPEC, law: str | None = "inverse_dynamics") -> TuneProblem:
    return TuneProblem(
        "planar_2dof",
        "inverse_dynamics_controller",
        JOINTS,
        np.zeros(2),
        np.full(2, 0.2),
        2.0,
        parse_spec(spec),
        law,
    )


# --------------------------------------------------------------------------- the step


def test_the_step_starts_at_zero_inside_the_limits_and_stays_inside():
    lo = np.array([-3.0, -0.5, 0.3, -np.inf, 0.0])
    hi = np.array([3.0, 0.02, 2.0, np.inf, 0.04])
    q0, target = step_inside_limits(lo, hi, 0.2)
    assert q0[0] == 0.0 and target[0] == pytest.approx(0.2)
    # 0 lies within 10 % of the upper limit 0.02 (range 0.52): start 0.052 below it, step
    # down by a quarter of the range (0.13 < 0.2)
    assert q0[1] == pytest.approx(-0.032) and target[1] == pytest.approx(-0.162)
    assert q0[2] == pytest.approx(0.47) and target[2] == pytest.approx(0.67)
    assert q0[3] == 0.0 and target[3] == pytest.approx(0.2)  # continuous joint
    assert target[4] - q0[4] == pytest.approx(0.01)  # a quarter of a 0.04 range
    with np.errstate(invalid="ignore"):  # inf − inf of the continuous joint, not used
        inner_lo = np.where(np.isfinite(lo), lo + 0.1 * (hi - lo), -np.inf)
        inner_hi = np.where(np.isfinite(hi), hi - 0.1 * (hi - lo), np.inf)
    assert np.all((target >= inner_lo - 1e-12) & (target <= inner_hi + 1e-12))
    with pytest.raises(ValueError, match="step"):
        step_inside_limits(lo, hi, 0.0)


# --------------------------------------------------------------------------- the space


def test_the_omega_zeta_space_is_per_joint_and_log_uniform_in_omega():
    space = SearchSpace(JOINTS, omega_n=(2.0, 40.0), zeta=(0.5, 1.2))
    d = space.distributions()
    assert list(d) == ["omega_n.joint1", "omega_n.joint2", "zeta.joint1", "zeta.joint2"]
    assert (d["omega_n.joint2"].low, d["omega_n.joint2"].high, d["omega_n.joint2"].log) == (
        2.0,
        40.0,
        True,
    )
    assert d["zeta.joint1"].log is False
    point = {"omega_n.joint1": 9.0, "omega_n.joint2": 16.0, "zeta.joint1": 1.0, "zeta.joint2": 0.7}
    assert space.node_gains(point) == {
        "omega_n": [9.0, 16.0],
        "zeta": [1.0, 0.7],
        "kp": 0.0,
        "kd": 0.0,
    }
    kp, kd = space.kp_kd(point)
    assert kp.tolist() == [81.0, 256.0] and kd == pytest.approx([18.0, 22.4])


def test_the_kp_kd_space_covers_the_same_second_order_box_through_the_inertia():
    b = (135.0, 22.5)
    space = SearchSpace(JOINTS, "kp_kd", (2.0, 40.0), (0.5, 1.2), b)
    d = space.distributions()
    assert d["kp.joint1"].low == pytest.approx(135.0 * 4) and d["kp.joint1"].high == 135.0 * 1600
    assert d["kd.joint2"].low == pytest.approx(22.5 * 2 * 0.5 * 2)
    point = {"kp.joint1": 135.0 * 100, "kp.joint2": 22.5 * 49, "kd.joint1": 135 * 20.0}
    point["kd.joint2"] = 22.5 * 2 * 0.8 * 7
    omega, zeta = space.second_order(point)
    assert omega == pytest.approx([10.0, 7.0]) and zeta == pytest.approx([1.0, 0.8])
    gains = space.node_gains(point)
    assert gains["omega_n"] == 0.0  # else omega_n would win over kp in the node
    choice = choose_gains(2, gains["kp"], gains["kd"], gains["omega_n"], 1.0)
    assert choice.source == FROM_KP


@pytest.mark.parametrize("text", ["5", "a:b", "5:1", "0:10", "-1:2", "1:inf"])
def test_bad_ranges_are_refused(text):
    with pytest.raises(ValueError, match="LO:HI"):
        parse_range(text, "--omega-n")


# --------------------------------------------------------------------------- the files


def _best_params(tmp_path: Path) -> tuple[Path, dict]:
    p = problem()
    gains = {"omega_n": [11.25, 14.5], "zeta": [0.95, 1.05], "kp": 0.0, "kd": 0.0}
    path = tmp_path / "best_params.yaml"
    path.write_text(outputs.params_yaml(p, gains, ["tuned", "ω_n = 11.25, 14.5"]))
    return path, gains


def test_the_params_file_loads_as_the_controller_node_reads_it(tmp_path):
    """rcl parses the file for a node named inverse_dynamics_controller (as ``--ros-args
    --params-file``) and the node's gain rule gives back the tuned ω_n, ζ."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    from joint_space_control.nodes.controller_base import COMMON_PARAMETERS
    from joint_space_control.processes.domains import lease_domain
    from joint_space_control.ros.parameters import ParamValues, value

    path, gains = _best_params(tmp_path)
    lease = lease_domain()
    context = Context()
    rclpy.init(
        args=["--ros-args", "--params-file", str(path)],
        context=context,
        domain_id=lease.domain_id,
    )
    try:
        node = Node(
            "inverse_dynamics_controller",
            context=context,
            automatically_declare_parameters_from_overrides=True,
            start_parameter_services=False,
        )
        read = {name: p.value for name, p in node._parameters.items()}
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
        lease.release()
    assert read["law"] == "inverse_dynamics"
    assert list(read["omega_n"]) == gains["omega_n"] and list(read["zeta"]) == gains["zeta"]
    specs = {s.name: s for s in COMMON_PARAMETERS}
    values = ParamValues(specs.values(), {k: read.get(k, s.default) for k, s in specs.items()})
    choice = choose_gains(2, *(value(values, k, 2) for k in ("kp", "kd", "omega_n", "zeta")))
    assert choice.source == FROM_OMEGA_N
    assert choice.omega_n.tolist() == gains["omega_n"] and choice.zeta.tolist() == gains["zeta"]
    # and jsc experiment --params-file reads the same entry
    assert node_parameters(path, "inverse_dynamics_controller") == {
        "law": "inverse_dynamics",
        **gains,
    }


def test_params_file_entries_apply_as_rcl_applies_them(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "/**": {"ros__parameters": {"rate": 500.0, "zeta": 0.5}},
                "/inverse_dynamics_controller": {"ros__parameters": {"zeta": 0.9}},
                "pd_gravity_controller": {"ros__parameters": {"kp": 1.0}},
            }
        )
    )
    assert node_parameters(path, "inverse_dynamics_controller") == {"rate": 500.0, "zeta": 0.9}
    assert node_parameters(path, "pd_gravity_controller") == {
        "rate": 500.0,
        "kp": 1.0,
        "zeta": 0.5,
    }
    other = tmp_path / "q.yaml"
    other.write_text(yaml.safe_dump({"sim_bridge": {"ros__parameters": {"gui": False}}}))
    with pytest.raises(ValueError, match="no parameters for /inverse_dynamics_controller"):
        node_parameters(other, "inverse_dynamics_controller")
    (tmp_path / "bad.yaml").write_text("inverse_dynamics_controller: {kp: 1}\n")
    with pytest.raises(ValueError, match="no 'ros__parameters'"):
        node_parameters(tmp_path / "bad.yaml", "inverse_dynamics_controller")


def test_the_scenario_file_loads_and_takes_the_params_file_over_its_gains(tmp_path):
    p = problem()
    written = {"omega_n": [3.0, 3.0], "zeta": [0.5, 0.5], "kp": 0.0, "kd": 0.0}
    path = tmp_path / "scenario.yaml"
    path.write_text(outputs.scenario_yaml(p, written, ["a header"]))
    s = scenarios.load(str(path))
    assert s.controller == "inverse_dynamics_controller" and s.question == 6
    assert s.reference == {"shape": "step", "target": [0.2, 0.2]}
    assert s.plant["initial_positions"] == [0.0, 0.0]
    assert s.checks == [{"check": "spec", "spec": SPEC}]
    params_path, gains = _best_params(tmp_path)
    tuned = with_params_file(s, params_path)
    assert tuned.parameters["omega_n"] == gains["omega_n"]
    assert tuned.parameters["zeta"] == gains["zeta"]
    assert s.parameters["omega_n"] == [3.0, 3.0]  # the loaded scenario is left as it was


# --------------------------------------------------------------------------- the study


def _study(tmp_path: Path, trials: int, seed: int = 0, spec: str = SPEC):
    return open_study(f"sqlite:///{tmp_path / 'study.db'}", "s", seed, trials, {"spec": spec})


def test_a_study_runs_to_its_trial_count_and_finds_the_second_order_design(tmp_path):
    runner = FakeRunner(jobs=2)
    study = _study(tmp_path, 20)
    space = SearchSpace(JOINTS)
    logs: list[str] = []
    run_trials(study, space, problem(), runner.submit, tmp_path, 20, 2, logs.append)
    runner.close()
    assert sum(is_finished(t) for t in study.trials) == 20 == len(study.trials)
    best = best_trial(study)
    assert best is not None and is_feasible(best) and best.value <= 0
    # the theory's response of the best point meets the spec (ζ ≥ 0.69, fast enough)
    assert min(best.user_attrs["zeta"]) > 0.69
    assert best.user_attrs["values"][1] <= 0.6
    # one constraint per clause and joint, ≤ 0 on every one
    assert len(best.constraints) == 4 and max(best.constraints.values()) <= 0
    assert (tmp_path / "trials" / f"trial_{best.number:04d}" / "scenario.yaml").is_file()
    assert any("meets the spec" in line for line in logs)


def test_an_interrupted_study_resumes_to_n_without_repeating_a_trial(tmp_path):
    runner = FakeRunner(jobs=2)
    space = SearchSpace(JOINTS)
    calls = {"n": 0}

    def submit_then_interrupt(label, scenario, target):
        calls["n"] += 1
        if calls["n"] == 6:  # Ctrl-C while trials are in flight
            raise KeyboardInterrupt
        return runner.submit(label, scenario, target)

    study = _study(tmp_path, 12)
    with pytest.raises(KeyboardInterrupt):
        run_trials(study, space, problem(), submit_then_interrupt, tmp_path, 12, 2, print)
    first = {t.number: t for t in study.trials}
    finished_before = sum(is_finished(t) for t in first.values())
    interrupted = [t for t in first.values() if t.user_attrs.get(INTERRUPTED)]
    assert 3 <= finished_before <= 5 and interrupted
    assert all(t.state == TrialState.FAIL for t in interrupted)
    assert not [t for t in first.values() if t.state == TrialState.RUNNING]

    resumed = _study(tmp_path, 12)  # a new session on the same storage
    done = run_trials(resumed, space, problem(), runner.submit, tmp_path, 12, 2, print)
    runner.close()
    assert done == 12 - finished_before
    trials = resumed.trials
    assert sum(is_finished(t) for t in trials) == 12
    assert [t.number for t in trials] == list(range(len(trials)))
    for t in first.values():  # what was finished before is kept as it was
        if is_finished(t):
            assert trials[t.number].params == t.params and trials[t.number].value == t.value
    points = [tuple(sorted(t.params.items())) for t in trials if t.state == TrialState.COMPLETE]
    assert len(points) == len(set(points)) == 12  # no point run twice


def test_ctrl_c_keeps_the_finished_runs_of_its_batch_and_fails_the_others(tmp_path):
    """Trials are told per batch, but a run that finished before Ctrl-C is not lost: the
    interrupted batch (trials 4–7, asked together) tells trial 4, whose run had finished
    when trial 5's submission was interrupted, and fails 5, 6 and 7 as interrupted."""
    runner = FakeRunner(jobs=2)
    futures = []

    def submit_then_interrupt(label, scenario, target):
        if len(futures) == 5:  # trial 5 (the second of the second batch)
            futures[-1].result()  # trial 4's run has finished
            raise KeyboardInterrupt
        futures.append(runner.submit(label, scenario, target))
        return futures[-1]

    study = _study(tmp_path, 12)
    logs: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        run_trials(
            study,
            SearchSpace(JOINTS),
            problem(),
            submit_then_interrupt,
            tmp_path,
            12,
            2,
            logs.append,
            batch=4,
        )
    runner.close()
    states = [t.state for t in study.trials]
    assert states == [TrialState.COMPLETE] * 5 + [TrialState.FAIL] * 3
    assert [t.number for t in study.trials if t.user_attrs.get(INTERRUPTED)] == [5, 6, 7]
    assert study.trials[4].user_attrs["seconds"] > 0
    assert [line.split(":")[0] for line in logs if line.startswith("trial ")] == [
        f"trial {n}" for n in range(5)
    ]
    assert logs[-1] == "  5/12 finished"


def test_a_stored_study_refuses_other_settings(tmp_path):
    from joint_space_control.workbench.tuning.study import SettingsMismatchError

    _study(tmp_path, 4)
    with pytest.raises(SettingsMismatchError, match="spec"):
        _study(tmp_path, 4, spec="overshoot<=1")


def test_a_failed_run_is_a_failed_trial_and_the_study_goes_on(tmp_path):
    runner = FakeRunner(jobs=1, fail={"trial 1"})
    study = _study(tmp_path, 4)
    logs: list[str] = []
    run_trials(study, SearchSpace(JOINTS), problem(), runner.submit, tmp_path, 4, 1, logs.append)
    runner.close()
    states = [t.state for t in study.trials]
    assert states.count(TrialState.FAIL) == 1 and states[1] == TrialState.FAIL
    assert "the simulator died" in study.trials[1].user_attrs["error"]
    assert len(study.trials) == 4  # a failed run counts as finished
    assert any("run FAILED" in line for line in logs)


def _seeded_study(out: Path, submit, in_flight: int) -> tuple[list[tuple], list[str]]:
    """A study of seed 7 and 11 trials (4 random, then TPE; trial 5's run fails) run with
    ``in_flight`` runs at a time: each trial as (number, state, params, value, constraints)
    in the order stored, and the log."""
    out.mkdir()
    study = _study(out, 11, seed=7)
    logs: list[str] = []
    run_trials(study, SearchSpace(JOINTS), problem(), submit, out, 11, in_flight, logs.append)
    trials = [(t.number, t.state, t.params, t.value, t.constraints) for t in study.trials]
    return trials, logs


def test_a_seeded_study_is_the_same_whatever_the_workers_and_the_order_runs_finish_in(
    tmp_path,
):
    """The issue's test: one seed, 1 worker, then 2 whose runs finish newest first (trial 0
    last of its batch): the same trials with the same values in the same order, the same
    log. Telling trials as they finish makes TPE's later suggestions differ."""
    one = FakeRunner(jobs=1, fail={"trial 5"})
    alone, alone_logs = _seeded_study(tmp_path / "one", one.submit, 1)
    one.close()
    two = ReorderingRunner(jobs=2, fail={"trial 5"})
    shuffled, shuffled_logs = _seeded_study(tmp_path / "two", two.submit, 2)
    two.close()
    # the order was forced: some run finished before one submitted earlier
    assert two.finished != two.submitted and sorted(two.finished) == sorted(two.submitted)
    assert one.submitted == [f"trial {n}" for n in range(11)]
    assert [t[0] for t in alone] == list(range(11))
    assert alone[5][1] == TrialState.FAIL and alone[10][1] == TrialState.COMPLETE
    for a, b in zip(alone, shuffled, strict=True):
        assert a == b  # params and values exactly equal, not approximately
    assert shuffled_logs == alone_logs
    trial_lines = [line for line in alone_logs if line.startswith("trial ")]
    assert [int(line.split(":")[0].split()[1]) for line in trial_lines] == list(range(11))


# --------------------------------------------------------------------------- the command


class ThreadPool:
    """The RunPool interface (jobs, scheduler, log; submit, cancel, close, missing, workers,
    description), in threads."""

    def __init__(self, jobs=2, scheduler=None, log=print):
        self.workers = jobs
        self.description = f"{jobs} test threads"
        self.pool = ThreadPoolExecutor(jobs)

    def submit(self, label, fn, *args):
        return self.pool.submit(fn, *args)

    def missing(self, directory):
        return [] if Path(directory).is_dir() else ["here"]

    def cancel(self):
        self.pool.shutdown(wait=False, cancel_futures=True)

    def close(self):
        self.pool.shutdown(wait=True)


def theory_run(scenario, target: Path, short: bool) -> list[FakeResult]:
    """execute_run's stand-in: the second-order response of the scenario's ω_n, ζ."""
    p = scenario.parameters
    step = np.subtract(scenario.reference["target"], scenario.plant["initial_positions"])
    metrics = controller_metrics(p["omega_n"], p["zeta"], tuple(step), scenario.duration)
    return [FakeResult(metrics, None, target)]


def options(tmp_path: Path, spec: str = SPEC, trials: int = 16, **kw) -> TuneOptions:
    return TuneOptions(
        "planar_2dof", "inverse_dynamics", spec, trials=trials, out=tmp_path / "out", **kw
    )


def test_the_command_exits_0_and_writes_its_files_when_the_spec_is_met(tmp_path):
    code = tune_cli.run(options(tmp_path), ThreadPool, theory_run, log=lambda m: None)
    assert code == 0
    out = tmp_path / "out"
    for name in ("best_params.yaml", "scenario.yaml", "report.md", "history.png", "study.db"):
        assert (out / name).is_file(), name
    params = yaml.safe_load((out / "best_params.yaml").read_text())
    design = params["inverse_dynamics_controller"]["ros__parameters"]
    report = (out / "report.md").read_text()
    assert "meets the spec" in report and "![Optimisation history" in report
    assert f"{design['omega_n'][0]:.4g}" in report
    # the written scenario is judged by the spec check: the theory says it passes
    s = scenarios.load(str(out / "scenario.yaml"))
    assert s.parameters["omega_n"] == design["omega_n"]


def test_the_best_trial_is_confirmed_on_the_ros_engine_before_the_parameter_file(tmp_path):
    """Trials in process (the default engine), then the best one on the ROS engine: the
    same values confirm it (said in the report); values that differ in the last bit leave
    no parameter file and exit 1."""
    logs: list[str] = []
    confirmed: list[str] = []

    def same(scenario, target):
        confirmed.append(scenario.name)
        return theory_run(scenario, target, False)

    code = tune_cli.run(options(tmp_path, trials=5), ThreadPool, theory_run, logs.append, same)
    assert code == 0 and len(confirmed) == 1 and confirmed[0].endswith("_ros")
    assert any("confirmed on the ROS engine" in line for line in logs), logs
    out = tmp_path / "out"
    assert "confirmed on the ROS engine" in (out / "report.md").read_text()
    assert (out / "best_params.yaml").is_file()

    def differs(scenario, target):
        (result,) = theory_run(scenario, target, False)
        step = result.controller["steps"][0]["joints"]
        for joint in step.values():
            joint["overshoot_percent"] = np.nextafter(joint["overshoot_percent"], np.inf)
        return [result]

    again = tmp_path / "again"
    again.mkdir()
    code = tune_cli.run(options(again, trials=5), ThreadPool, theory_run, logs.append, differs)
    assert code == 1
    assert any("differs from its in-process run" in line for line in logs), logs
    assert not (again / "out" / "best_params.yaml").exists()
    assert "differs from its in-process run" in (again / "out" / "report.md").read_text()


def test_the_command_exits_1_naming_the_closest_clause_when_no_trial_meets_the_spec(
    tmp_path, capsys
):
    spec = "overshoot<=5, settling_2pct<=0.02"  # would need ω_n ≈ 300 rad/s: outside 1..60
    code = tune_cli.run(options(tmp_path, spec, trials=6), ThreadPool, theory_run)
    assert code == 1
    out = capsys.readouterr().out
    assert "no trial met" in out and "closest: settling_2pct<=0.02" in out
    report = (tmp_path / "out" / "report.md").read_text()
    assert "does not meet the spec" in report and "closest clause: settling_2pct<=0.02" in report
    assert (tmp_path / "out" / "best_params.yaml").is_file()  # the closest gains, said so
    assert "does NOT meet" in (tmp_path / "out" / "best_params.yaml").read_text()


def test_a_second_run_of_the_command_resumes_its_study(tmp_path):
    assert tune_cli.run(options(tmp_path, trials=5), ThreadPool, theory_run, log=print) in (0, 1)
    logs: list[str] = []
    tune_cli.run(options(tmp_path, trials=8), ThreadPool, theory_run, log=logs.append)
    assert any("resuming study 'planar_2dof_inverse_dynamics': 5 of 8" in m for m in logs)
    assert sum("finished" in m and m.strip().endswith("/8 finished") for m in logs) == 3


def test_the_command_runs_its_batches_and_says_so(tmp_path):
    """``--batch`` reaches the study (the report's sampler line); a pool larger than the
    batch is told it idles."""
    logs: list[str] = []
    pool = lambda jobs, scheduler, log: ThreadPool(3, scheduler, log)  # noqa: E731
    tune_cli.run(options(tmp_path, trials=3, batch=2), pool, theory_run, log=logs.append)
    assert any(m.startswith("note: 3 workers, batches of 2 trials: 1 idle") for m in logs)
    assert "TPE, seed 0, 3 trials in batches of 2" in (tmp_path / "out" / "report.md").read_text()


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--spec", "overshot<=5"], "unknown metric 'overshot'"),
        (["--spec", "overshoot<5"], "malformed clause"),
        (["--spec", SPEC, "--law", "pid"], "--law for inverse_dynamics sets 'law'"),
        (["--spec", SPEC, "--trials", "0"], "--trials must be >= 1"),
        (["--spec", SPEC, "--batch", "0"], "--batch must be >= 1"),
        (["--spec", SPEC, "--omega-n", "10:1"], "--omega-n must be LO:HI"),
        (["--spec", SPEC, "--trials", "x"], "invalid int value"),
        (["--spec", SPEC, "--controller", "pid"], "invalid choice"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, words):
    args = ["tune", "planar_2dof", "--controller", "inverse_dynamics", "--out", str(tmp_path)]
    try:
        code = main(args + argv)
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("jsc tune: error: ") and words in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_an_unknown_robot_or_missing_file_is_bad_input(tmp_path, capsys):
    for robot, words in (("ur99", "unknown robot 'ur99'"), ("nope.urdf", "no such robot")):
        code = main(["tune", robot, "--controller", "pd_gravity", "--spec", SPEC])
        assert code == 2
        err = capsys.readouterr().err
        assert err.startswith("jsc tune: error: ") and words in err and err.count("\n") == 1


def test_ranges_of_the_help_are_the_defaults():
    o = TuneOptions("planar_2dof", "pd_gravity", SPEC)
    assert o.omega_n[0] < 10 < o.omega_n[1] and o.zeta[0] < 1 < o.zeta[1]
    assert math.isclose(o.step, 0.2) and o.duration == 2.0


# --------------------------------------------------------------------------- the design


def test_zeta_for_overshoot_inverts_the_second_order_overshoot():
    from joint_space_control.analysis.metrics import second_order_prediction
    from joint_space_control.workbench.tuning.design import zeta_for_overshoot

    for percent in (0.5, 5.0, 16.3, 40.0):
        zeta = zeta_for_overshoot(percent)
        overshoot = second_order_prediction(10.0, zeta)["overshoot_percent"][0]
        assert overshoot == pytest.approx(percent, rel=1e-9)
    assert zeta_for_overshoot(0.0) == 1.0


def test_the_theory_design_meets_the_spec_on_the_second_order_loop():
    from joint_space_control.analysis.spec import judge
    from joint_space_control.workbench.tuning.design import theory_design

    spec = parse_spec("overshoot<=5, settling_2pct<=0.6, rise_time<=0.5")
    space = SearchSpace(JOINTS)
    point = theory_design(spec, space, [135.0, 22.5], [0.0, 0.0], [2000.0, 1000.0], [0.2, 0.2])
    omega, zeta = space.second_order(point)
    assert np.all(zeta >= 0.8) and np.all(omega > 3.76 / 0.6)  # ω_n t_s(ζ = 0.8) ≈ 3.76
    assert judge(spec, controller_metrics(omega, zeta)).met


def test_the_theory_design_keeps_the_step_command_under_the_torque_bound():
    from joint_space_control.workbench.tuning.design import TORQUE_MARGIN, theory_design

    spec = parse_spec("overshoot<=5, peak_torque_ratio<=0.5")
    b, g, lim, dq = np.array([145.0, 22.5]), np.array([300.0, 100.0]), [2000.0, 1000.0], 0.2
    omega, _ = SearchSpace(JOINTS).second_order(
        theory_design(spec, SearchSpace(JOINTS), b, g, lim, [dq, dq])
    )
    command = g + b * omega**2 * dq
    assert np.all(command <= TORQUE_MARGIN * 0.5 * np.array(lim) + 1e-9)
    # a settling bound the torque bound forbids: a compromise between the two, inside the box
    spec = parse_spec("settling_2pct<=0.1, peak_torque_ratio<=0.5")
    omega, _ = SearchSpace(JOINTS).second_order(
        theory_design(spec, SearchSpace(JOINTS), b, g, lim, [dq, dq])
    )
    assert np.all(b * omega**2 * dq + g > 0.45 * np.array(lim)) and np.all(omega <= 50.0)


def test_a_new_study_starts_from_the_design_and_a_resumed_one_does_not(tmp_path):
    logs: list[str] = []
    tune_cli.run(options(tmp_path, trials=3), ThreadPool, theory_run, log=logs.append)
    assert any(m.startswith("trial 0 is the theory's design") for m in logs)
    report = (tmp_path / "out" / "report.md").read_text()
    assert "| 0 | met (theory's design) |" in report
    logs.clear()
    tune_cli.run(options(tmp_path, trials=4), ThreadPool, theory_run, log=logs.append)
    assert not any("theory's design" in m for m in logs)
    logs.clear()
    no_design = options(tmp_path, trials=2, design=False, study="other")
    tune_cli.run(no_design, ThreadPool, theory_run, log=logs.append)
    assert not any("theory's design" in m for m in logs)
