"""Bag → arrays → metrics → report on synthetic rosbag2 bags (no ROS graph, STYLE.md §5-6).

The bags carry what the recorder writes (README, "Controller state"; the ``<node>/config``
JSON); the state of an ideal inverse-dynamics loop follows the analytic second-order step
response, so the measured step figures must match the theory's within a sample.
"""

from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from rosbags.rosbag2 import StoragePlugin, Writer

from joint_space_control.analysis.bag import (
    BagError,
    controller_state,
    joint_states,
    read_bag,
    read_controller_bag,
)
from joint_space_control.analysis.figures import (
    FIGURE_NAMES,
    MAX_POINTS,
    file_prefix,
    minmax_decimate,
)
from joint_space_control.analysis.metrics import second_order_prediction
from joint_space_control.analysis.run_metrics import (
    analyze_bag,
    last_run,
    step_segments,
)
from joint_space_control.cli.analyze import ProgressBar
from joint_space_control.cli.main import main
from joint_space_control.json_values import jsonable
from test.unit.bagfactory import (
    JOINT_STATE_TYPE,
    STATE_TYPE,
    TYPESTORE,
    BagBuilder,
    config,
    second_order_state,
)

RATE = 1000.0  # [Hz] state rate of the synthetic runs
JOINTS = ("joint1", "joint2")
NODE = "/inverse_dynamics_controller"
STATE = NODE + "/state"
CONFIG = NODE + "/config"
OMEGA = (10.0, 20.0)  # [rad/s]
ZETA = (0.5, 0.8)
Y0 = (0.4, -0.7)  # [rad] non-zero start
Y1 = (0.9, -0.2)
T_STEP = (0.5, 3.5)  # [s] joint1 steps first, joint2 3 s later: one joint still per step
DURATION = 6.5  # [s]
LOG0 = 1_000_000_000  # [ns] receive time of the first state


def times(duration: float = DURATION) -> np.ndarray:
    return np.arange(round(duration * RATE) + 1) / RATE  # exact multiples of 1 ms


def logs(t: np.ndarray) -> np.ndarray:
    """Receive times [ns]: 0.2 ms after the stamp, plus a little jitter."""
    jitter = (np.arange(t.size) % 7) * 10_000
    return LOG0 + np.round(t * 1e9).astype(np.int64) + 200_000 + jitter


def id_config(**kwargs) -> dict:
    omega, zeta = np.array(OMEGA), np.array(ZETA)
    defaults = {"kp": (omega**2).tolist(), "kd": (2 * zeta * omega).tolist()}
    return config(node=NODE, joints=JOINTS, **{**defaults, **kwargs})


def write_run(path: Path, rows: dict, t: np.ndarray, storage="mcap", cfg=None, log=None) -> Path:
    """A bag with the controller state (and its config unless ``cfg`` is False)."""
    with BagBuilder(path, storage) as bag:
        if cfg is not False:
            bag.config(CONFIG, LOG0 - 1000, cfg or id_config())
        bag.states(STATE, logs(t) if log is None else log, t, rows, JOINTS)
    return path


@pytest.fixture(scope="module")
def id_bag(tmp_path_factory) -> Path:
    t = times()
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, T_STEP)
    return write_run(tmp_path_factory.mktemp("id") / "bag", rows, t)


# --------------------------------------------------------------------------- theory


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_second_order_steps_match_the_theory(tmp_path, storage):
    t = times()
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, T_STEP)
    bag = write_run(tmp_path / "bag", rows, t, storage)
    m = analyze_bag(bag).metrics
    assert m["storage"] == storage
    c = m["controllers"][NODE]
    assert (c["law"], c["robot"]) == ("inverse_dynamics", "planar_2dof")
    assert [s["t_start"] for s in c["steps"]] == list(T_STEP)
    dt = 1.0 / RATE
    for k, step in enumerate(c["steps"]):
        mover, still = JOINTS[k], JOINTS[1 - k]
        measured = step["joints"][mover]
        theory = second_order_prediction(OMEGA[k], ZETA[k])
        assert measured["moving"] and not step["joints"][still]["moving"]
        assert measured["initial"] == Y0[k] and measured["target"] == Y1[k]
        assert measured["overshoot_percent"] == pytest.approx(
            theory["overshoot_percent"][0], rel=1e-3
        )
        for key in ("rise_time", "settling_time_2", "settling_time_5"):
            assert abs(measured[key] - theory[key][0]) <= dt, key
        assert abs(measured["steady_state_error"]) < 1e-6
        # the prediction sits next to the measured values, from the configuration's gains
        prediction = measured["prediction"]
        assert prediction["omega_n"] == pytest.approx(OMEGA[k])
        assert prediction["zeta"] == pytest.approx(ZETA[k])
        assert prediction["overshoot_percent"] == pytest.approx(theory["overshoot_percent"][0])
        # the other joint is not commanded: the loop is decoupled, it does not move (joint1
        # is still settling from its own step by e^(−ζω_n·3 s) ≈ 3e-7 when joint2 steps)
        other = step["joints"][still]
        assert other["max_deviation"] < 1e-6 and abs(other["steady_state_error"]) < 1e-6
        assert "prediction" not in other and "rise_time" not in other
    assert c["steps"][0]["joints"]["joint2"]["max_deviation"] == 0.0
    assert c["second_order"]["joint2"]["zeta"] == pytest.approx(0.8)
    # the final error is exactly the last sample's q_d − q
    expected = rows["q_d"][-1] - rows["q"][-1]
    assert [c["final_error"][j] for j in JOINTS] == expected.tolist()
    assert c["samples"]["analysed"] == t.size and c["warnings"] == []
    assert m["message_counts"] == {STATE: t.size, CONFIG: 1}


def test_constant_offset_gives_its_steady_state_error(tmp_path):
    t = times(6.0)
    offset = 0.05  # [rad] PD without gravity compensation settles short of q_d
    rows = second_order_state(t, Y0, (Y1[0] - offset, Y0[1]), OMEGA, ZETA, 0.5)
    rows["q_d"][:, 0] = np.where(t >= 0.5, Y1[0], Y0[0])
    cfg = config(node=NODE, law="pd_gravity", joints=JOINTS, kp=(100.0, 100.0), kd=(20.0, 20.0))
    c = analyze_bag(write_run(tmp_path / "bag", rows, t, cfg=cfg)).metrics["controllers"][NODE]
    (step,) = c["steps"]
    assert step["joints"]["joint1"]["steady_state_error"] == pytest.approx(offset, abs=1e-9)
    assert c["final_error"]["joint1"] == pytest.approx(offset, abs=1e-9)
    assert c["law"] == "pd_gravity"
    assert c["second_order"] is None and "prediction" not in step["joints"]["joint1"]


def test_each_step_is_predicted_from_the_configuration_in_force(tmp_path):
    t = times()
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, T_STEP)
    path = tmp_path / "bag"
    with BagBuilder(path) as bag:
        bag.config(CONFIG, LOG0 - 1000, id_config(kp=[1.0, 1.0], kd=[1.0, 1.0]))
        bag.config(CONFIG, LOG0 + 1000, id_config())  # accepted change before the 1st step
        bag.config(CONFIG, LOG0 + 2_000_000_000, id_config(kp=[100.0, 900.0]))
        bag.states(STATE, logs(t), t, rows, JOINTS)
    c = analyze_bag(path).metrics["controllers"][NODE]
    first, second = (s["joints"][j]["prediction"] for s, j in zip(c["steps"], JOINTS, strict=True))
    assert first["omega_n"] == pytest.approx(10.0)  # the change at LOG0 + 1 µs applies
    assert second["omega_n"] == pytest.approx(30.0)  # kp 900 from 2 s on
    assert c["config_count"] == 3 and c["config"]["kp"] == [100.0, 900.0]


# --------------------------------------------------------------------------- cleaning


def test_duplicate_stamps_keep_the_last_message(tmp_path):
    t = times(1.0)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.2)
    again = np.arange(t.size) % 10 == 3  # every 10th state sent again (lockstep re-send)
    again[-1] = True
    order = np.sort(np.concatenate((np.arange(t.size), np.flatnonzero(again))))
    dup = {k: v[order].copy() for k, v in rows.items()}
    resent = np.append(np.diff(order) == 0, False)  # the first of each pair
    dup["q_d"][resent] += 0.25  # the stale answer differs (timer mode): it must not be used
    log = LOG0 + np.arange(order.size, dtype=np.int64) * 500_000  # the re-sent answer is later
    path = write_run(tmp_path / "bag", dup, t[order], cfg=False, log=log)
    analysis = analyze_bag(path)
    c = analysis.metrics["controllers"][NODE]
    assert c["samples"]["duplicate_stamps"] == int(again.sum())
    assert c["samples"]["analysed"] == t.size
    np.testing.assert_array_equal(analysis.controllers[0].state.rows["q_d"], rows["q_d"])
    assert not any("interleaved" in w for w in c["warnings"])  # same q: repeated answers
    assert [c["final_error"][j] for j in JOINTS] == (rows["q_d"][-1] - rows["q"][-1]).tolist()
    assert c["period_statistics"]["stamp_period_ms"]["max"] == pytest.approx(1.0)


def test_reset_keeps_the_last_run_and_warns(tmp_path):
    t1, t2 = times(0.8), times(1.5)
    run1 = second_order_state(t1, (0.0, 0.0), (1.0, 1.0), OMEGA, ZETA, 0.1)
    run2 = second_order_state(t2, Y0, Y1, OMEGA, ZETA, T_STEP[0])
    both = {k: np.concatenate((run1[k], run2[k])) for k in run1}
    stamps = np.concatenate((t1, t2))
    path = tmp_path / "bag"
    with BagBuilder(path) as bag:
        bag.config(CONFIG, LOG0 - 1000, id_config())
        log = LOG0 + np.arange(stamps.size, dtype=np.int64) * 1_000_000
        bag.states(STATE, log, stamps, both, JOINTS)
    m = analyze_bag(path).metrics
    c = m["controllers"][NODE]
    assert c["samples"]["resets"] == 1
    assert c["samples"]["before_last_reset"] == t1.size
    assert c["samples"]["analysed"] == t2.size
    assert c["time"]["start"] == 0.0 and c["time"]["end"] == pytest.approx(1.5)
    assert [s["t_start"] for s in c["steps"]] == [T_STEP[0]]
    assert any("reset" in w for w in c["warnings"])
    assert any(w.startswith(f"{NODE}: ") and "reset" in w for w in m["warnings"])


def test_same_stamp_with_another_q_warns_of_interleaved_runs(tmp_path):
    t = times(0.5)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.1)
    other = second_order_state(t, Y1, Y0, OMEGA, ZETA, 0.1)  # another run, same stamps
    both = {k: np.stack((other[k], rows[k]), axis=1).reshape(-1, 2) for k in rows}
    log = LOG0 + np.arange(2 * t.size, dtype=np.int64)
    c = analyze_bag(write_run(tmp_path / "bag", both, np.repeat(t, 2), log=log)).metrics
    c = c["controllers"][NODE]
    assert c["samples"]["duplicate_stamps"] == t.size
    assert any(f"{t.size} stamps carry different joint positions" in w for w in c["warnings"])


def test_last_run_drops_non_finite_samples(tmp_path):
    t = times(0.5)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.1)
    rows["tau"][7, 1] = math.nan
    path = write_run(tmp_path / "bag", rows, t)
    state = controller_state(read_bag(path, [STATE]).data[STATE])
    warnings: list[str] = []
    clean, samples = last_run(state, warnings)
    assert samples["non_finite"] == 1 and len(clean) == t.size - 1
    assert 7 / RATE not in clean.stamp.tolist() and "non-finite" in warnings[0]


# --------------------------------------------------------------------------- torque


def saturating_rows(t: np.ndarray, limits: tuple[float, float], until: float) -> dict:
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.0)
    wanted = np.where(t[:, None] < until, 3.0 * np.array(limits), 0.5 * np.array(limits))
    rows["tau_unclamped"] = wanted
    rows["tau"] = np.clip(wanted, -np.array(limits), np.array(limits))
    return rows


def test_saturated_fraction_from_the_effort_limits(tmp_path):
    limits = (50.0, 30.0)
    t = times(2.0)
    rows = saturating_rows(t, limits, until=0.5)
    c = analyze_bag(write_run(tmp_path / "bag", rows, t)).metrics["controllers"][NODE]
    td = c["torque_demand"]
    at_limit = np.count_nonzero(t < 0.5)  # each sample holds until the next one
    expected = at_limit / (t.size - 1)
    assert td["saturation_source"] == {"joint1": "effort_limits", "joint2": "effort_limits"}
    assert td["effort_limits"] == dict(zip(JOINTS, limits, strict=True))
    assert td["saturated_fraction"]["joint1"] == pytest.approx(expected, rel=1e-12)
    assert td["clamped_fraction"]["joint2"] == pytest.approx(expected, rel=1e-12)
    assert td["peak_abs"] == dict(zip(JOINTS, limits, strict=True))


def test_without_configuration_saturation_comes_from_the_clamp(tmp_path):
    t = times(2.0)
    rows = saturating_rows(t, (50.0, 30.0), until=1.0)
    m = analyze_bag(write_run(tmp_path / "bag", rows, t, cfg=False)).metrics
    c = m["controllers"][NODE]
    td = c["torque_demand"]
    assert td["saturation_source"] == {"joint1": "tau_unclamped", "joint2": "tau_unclamped"}
    assert td["effort_limits"] == {"joint1": None, "joint2": None}
    expected = np.count_nonzero(t < 1.0) / (t.size - 1)
    assert td["saturated_fraction"]["joint2"] == pytest.approx(expected, rel=1e-12)
    assert c["law"] is None and c["second_order"] is None and c["config_topic"] is None
    assert any("no configuration" in w for w in c["warnings"])


def test_unbounded_joint_saturation_comes_from_the_clamp(tmp_path):
    """``null`` limit (no limit in the URDF): that joint falls back to τ_unclamped vs τ."""
    t = times(2.0)
    rows = saturating_rows(t, (50.0, 30.0), until=0.5)
    rows["tau_unclamped"][:, 1] = rows["tau"][:, 1]  # joint2 is never clamped
    cfg = id_config(effort_limits=[50.0, None])
    out = tmp_path / "out"
    bag = write_run(tmp_path / "bag", rows, t, cfg=cfg)
    assert main(["analyze", str(bag), "--out", str(out), "--quiet"]) == 0
    td = json.loads((out / "metrics.json").read_text())["controllers"][NODE]["torque_demand"]
    assert td["effort_limits"] == {"joint1": 50.0, "joint2": None}
    assert td["saturation_source"] == {"joint1": "effort_limits", "joint2": "tau_unclamped"}
    assert td["saturated_fraction"]["joint1"] > 0.2 and td["saturated_fraction"]["joint2"] == 0
    report = (out / "report.md").read_text()
    assert "| joint1 | 50 | " in report and "| at limit |" in report and "| clamped |" in report


# --------------------------------------------------------------------------- references


def test_moving_reference_is_tracked_not_stepped(tmp_path):
    t = times(3.0)
    rows = second_order_state(t, Y0, Y0, OMEGA, ZETA, 0.0)
    moving = t < 2.0  # a sinusoid for 2 s, then the reference holds where it stopped
    arg = np.where(moving, t, 2.0)[:, None]
    rows["q_d"] = np.array(Y0) + 0.3 * np.sin(2.0 * arg)
    rows["dq_d"] = np.where(moving[:, None], 0.6 * np.cos(2.0 * arg), 0.0) * np.ones(2)
    rows["q"] = rows["q_d"] - np.array([0.01, -0.02])  # constant lag
    c = analyze_bag(write_run(tmp_path / "bag", rows, t)).metrics["controllers"][NODE]
    assert c["steps"] == []  # the arrival at the hold is not a step
    moving_ref = c["tracking_error"]["moving_reference"]
    assert len(moving_ref["segments"]) == 1
    assert moving_ref["rms"]["joint1"] == pytest.approx(0.01, rel=1e-9)
    assert moving_ref["max_abs"]["joint2"] == pytest.approx(0.02, rel=1e-9)
    assert moving_ref["duration"] == pytest.approx(2.0 - 1.0 / RATE)
    assert c["tracking_error"]["whole_record"]["rms"]["joint2"] == pytest.approx(0.02, rel=1e-9)


def test_step_segments_need_a_jump_and_a_hold():
    t = times(0.1)
    q_d = np.zeros((t.size, 1))
    q_d[50:] = 1.0  # one jump at sample 50
    q_d[95:] = 2.0  # a second, held for too few samples to be measured
    segments = step_segments(t, q_d, np.zeros_like(q_d))
    assert [(s.start, s.stop) for s in segments] == [(50, 95)]
    # starting away from a constant q_d is a step at the first sample
    first = step_segments(t, q_d, q_d - 0.1)
    assert [(s.start, s.moving.tolist()) for s in first] == [(0, [True]), (50, [True])]


# --------------------------------------------------------------------------- bag reading


def test_several_controllers_are_analysed_each(tmp_path):
    t = times(1.0)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.2)
    other = "/robot1/pd_gravity_controller"
    path = tmp_path / "bag"
    with BagBuilder(path) as bag:
        bag.config(CONFIG, LOG0 - 1000, id_config())
        bag.config(other + "/config", LOG0 - 1000, config(node=other, law="pd_gravity"))
        bag.states(STATE, logs(t), t, rows, JOINTS)
        bag.states(other + "/state", logs(t) + 1, t, rows, JOINTS)
        # a Float64MultiArray that is not a controller state (ros2_control style commands)
        commands = TYPESTORE.types[STATE_TYPE](
            layout=TYPESTORE.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0),
            data=np.array([1.0, 2.0]),
        )
        bag.write("/sim_bridge/commands", STATE_TYPE, LOG0, commands)
    contents = read_controller_bag(path)
    assert contents.controllers == [(STATE, CONFIG), (other + "/state", other + "/config")]
    assert "/sim_bridge/commands" in contents.topics
    out = tmp_path / "out"
    assert main(["analyze", str(path), "--out", str(out), "--quiet"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["controllers"]) == {NODE, other}
    assert m["controllers"][other]["law"] == "pd_gravity"
    for node in (NODE, other):
        for name in FIGURE_NAMES:
            assert (out / f"{file_prefix(node)}{name}.png").is_file()
    assert file_prefix(other) == "robot1_pd_gravity_controller_"


def test_progress_is_reported_up_to_the_total(id_bag):
    calls = []
    contents = read_controller_bag(id_bag, lambda done, total: calls.append((done, total)))
    total = sum(t.count for t in contents.topics.values())
    assert len(calls) >= 2 and calls[-1] == (total, total)
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)


def test_joint_state_with_empty_fields_reads_back_as_nan(tmp_path):
    path = tmp_path / "bag"
    names = ["joint1", "joint2"]
    with BagBuilder(path, "sqlite3") as bag:
        bag.joint_state("/joint_states", 10, 0.001, names, [0.1, 0.2], [1.0, 2.0], [3.0, 4.0])
        bag.joint_state("/effort_command", 20, 0.001, names, effort=[5.0, 6.0])  # recorder style
        bag.joint_state("/joint_states", 30, 0.002, names[::-1], [0.4, 0.3])  # other order
    contents = read_bag(path)
    cmd = joint_states(contents.data["/effort_command"])
    assert cmd.names == ("joint1", "joint2") and cmd.stamp.tolist() == [0.001]
    assert np.isnan(cmd.position).all() and np.isnan(cmd.velocity).all()
    assert cmd.effort.tolist() == [[5.0, 6.0]] and cmd.log_time.tolist() == [20]
    js = joint_states(contents.data["/joint_states"])
    assert js.position.tolist() == [[0.1, 0.2], [0.3, 0.4]]
    assert js.velocity[0].tolist() == [1.0, 2.0] and np.isnan(js.velocity[1]).all()


# --------------------------------------------------------------------------- errors


def write_empty(path: Path) -> Path:
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.add_connection("/joint_states", JOINT_STATE_TYPE, typestore=TYPESTORE)
    return path


def joint_states_only(path: Path) -> Path:
    with BagBuilder(path) as bag:
        for k in range(3):
            bag.joint_state("/joint_states", 10 + k, 0.001 * k, JOINTS, [0.0, 0.0], [0.0, 0.0])
    return path


def not_yaml(path: Path) -> Path:
    path.mkdir()
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    return path


def storage_only(path: Path) -> Path:
    path.mkdir()
    (path / "bag_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    return path


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p, "no such file or directory"),
        (lambda p: (p.mkdir(), p)[1], "not a rosbag2 directory: no metadata.yaml"),
        (storage_only, "ros2 bag reindex"),
        (not_yaml, "unreadable rosbag2 bag"),
        (write_empty, "the bag is empty"),
        (joint_states_only, "no controller state topic"),
    ],
    ids=["missing", "no-metadata", "storage-only", "bad-metadata", "empty", "no-state"],
)
def test_bag_errors_are_clear_and_exit_2(tmp_path, capsys, make, message):
    path = make(tmp_path / "bag")
    with pytest.raises(BagError, match=message) as err:
        analyze_bag(path)
    assert str(tmp_path / "bag") in str(err.value)
    assert main(["analyze", str(path)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("jsc analyze: error: ")
    assert message in lines[0] and "Traceback" not in captured.err
    assert not (tmp_path / "bag_report").exists()


def test_missing_state_lists_the_topics_found(tmp_path):
    path = joint_states_only(tmp_path / "bag")
    with pytest.raises(BagError) as err:
        read_controller_bag(path)
    assert "/joint_states (sensor_msgs/msg/JointState, 3)" in str(err.value)
    assert "std_msgs/msg/Float64MultiArray" in str(err.value)


def test_a_storage_file_points_to_its_directory(tmp_path, id_bag):
    mcap = next(id_bag.glob("*.mcap"))
    with pytest.raises(BagError, match=re.escape(f"pass the bag directory {id_bag}")):
        read_bag(mcap)


# --------------------------------------------------------------------------- outputs


def strict_json(text: str) -> dict:
    def reject(token: str):
        raise AssertionError(f"non-standard JSON token {token}")

    return json.loads(text, parse_constant=reject)


def test_cli_writes_metrics_report_and_figures(tmp_path, id_bag, capsys):
    bag = tmp_path / "run"
    bag.symlink_to(id_bag, target_is_directory=True)
    assert main(["analyze", str(bag) + "/"]) == 0
    out = tmp_path / "run_report"  # default: a sibling <BAG>_report
    metrics = strict_json((out / "metrics.json").read_text())
    assert metrics["controllers"][NODE]["steps"][0]["joints"]["joint1"]["settling_time_2"] > 0
    report = (out / "report.md").read_text()
    for name in FIGURE_NAMES:
        png = out / f"{name}.png"
        assert f"]({name}.png)" in report
        with Image.open(png) as image:
            assert image.format == "PNG" and image.size[0] >= 800 and image.size[1] >= 400
            colours = image.convert("RGB").getcolors(maxcolors=1_000_000)
            assert colours is not None and len(colours) > 50  # drawn, not blank
    assert "inverse_dynamics" in report and "theory" in report
    stdout = capsys.readouterr().out
    assert "final error" in stdout and str(out / "report.md") in stdout


def test_report_and_json_have_no_nan(tmp_path, id_bag):
    t = times(0.3)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.2)  # too short to settle: NaNs
    bag = write_run(tmp_path / "bag", rows, t)
    out = tmp_path / "out"
    assert main(["analyze", str(bag), "--out", str(out), "--quiet"]) == 0
    metrics = strict_json((out / "metrics.json").read_text())
    step = metrics["controllers"][NODE]["steps"][0]["joints"]["joint1"]
    assert step["settling_time_2"] is None  # never settled: null, not NaN
    assert "nan" not in (out / "report.md").read_text().lower()


def test_jsonable_maps_nan_and_numpy():
    value = {"a": np.float64("nan"), "b": np.arange(2), "c": (np.inf, np.bool_(True), 1.5)}
    assert jsonable(value) == {"a": None, "b": [0, 1], "c": [None, True, 1.5]}


def test_minmax_decimation_keeps_peaks():
    y = np.sin(np.linspace(0.0, 20.0, 60_001))
    y[31_234] = 7.0
    y[45_678] = -9.0
    index = minmax_decimate(y)
    assert index.size <= MAX_POINTS and {0, 31_234, 45_678, y.size - 1} <= set(index.tolist())
    assert np.all(np.diff(index) > 0)
    assert minmax_decimate(y[:100]).tolist() == list(range(100))


def test_state_fields_are_self_describing(tmp_path):
    """Extra rows are accepted and a layout without q_d, q or tau is not a controller state."""
    t = times(0.2)
    rows = second_order_state(t, Y0, Y1, OMEGA, ZETA, 0.05)
    path = tmp_path / "bag"
    extra = ("q_d", "q", "tau", "tau_friction")
    partial = ("q", "tau")
    with BagBuilder(path) as bag:
        for k, stamp in enumerate(t):
            matrix = np.stack([rows["q_d"][k], rows["q"][k], rows["tau"][k], [0.5, 0.5]])
            bag.state("/a/state", LOG0 + k, stamp, matrix, JOINTS, extra)
            bag.state("/b/state", LOG0 + k, stamp, matrix[1:3], JOINTS, partial)
    contents = read_controller_bag(path)
    assert contents.controllers == [("/a/state", None)]
    state = controller_state(contents.data["/a/state"])
    assert state.fields == extra and state.rows["tau_friction"].tolist()[0] == [0.5, 0.5]
    np.testing.assert_array_equal(state.rows["q"], rows["q"])


def test_progress_without_a_terminal_prints_a_few_lines():
    stream = io.StringIO()
    bar = ProgressBar(stream)
    for done in range(0, 60_001, 5000):
        bar(done, 60_000)
    bar.finish()
    lines = stream.getvalue().splitlines()
    assert 3 <= len(lines) <= 5 and lines[-1] == "reading: 100 % (60000/60000 messages)"
    assert "\r" not in stream.getvalue()


def test_progress_on_a_terminal_redraws_one_line():
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    stream = Terminal()
    bar = ProgressBar(stream)
    for done in (5000, 30_000, 60_000):
        bar(done, 60_000)
    bar.finish()
    text = stream.getvalue()
    assert text.count("\r") == 3 and text.endswith("60000/60000 messages\n")
    assert text.count("\n") == 1 and "[" + "#" * 30 + "]" in text
