"""Runs as tasks of a RunPool: in threads, or on a Dask LocalCluster (issue 18).

- RunPool itself: a failed task is retried once, then fails; a worker killed under a task
  is a failure retried once; cancel() drops the queued tasks and stops the running ones,
  on threads and on Dask alike; a bad scheduler address is an error.
- The same lockstep sweep (a 3 × 3 grid) gives bit-identical metrics, events and recorded
  states on the threads pool and on a 2-worker LocalCluster, and its heat maps are drawn.
- ``jsc bench``'s sweep section, tiny: both cluster sizes timed, phase by phase.
- A Dask worker SIGKILLed mid-sweep: the run is retried (logged) and the sweep completes,
  and the killed worker's nodes are gone within seconds.
- Ctrl-C of ``jsc experiment`` on the LocalCluster: exit 130, no node and no worker left.

Every process a test starts carries a marker in its environment (the pool's workers and
their nodes inherit it) and is found and killed at the end, passed or failed.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from concurrent.futures import CancelledError, as_completed
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from joint_space_control.workbench.experiments.execution.distributed import RunPool, on_cancel
from joint_space_control.workbench.experiments.execution.runner import run_scenario
from joint_space_control.workbench.experiments.experiment import run_experiment
from joint_space_control.workbench.experiments.scenarios import format as scenarios

pytestmark = pytest.mark.integration

MARKER = "JSC_TEST_MARKER"

#: A 3 × 3 grid of short lockstep runs: ω_n × the controller model's mass scale under
#: inverse dynamics on the planar arm (``variants: grid:``, scenarios/format.py).
OMEGAS = (8.0, 12.0, 16.0)
MASS_SCALES = (0.8, 1.0, 1.2)
SCENARIO = """
title: distributed sweep test
question: 7
robot: planar_2dof
duration: {duration}
short_duration: {duration}
plant: {{initial_positions: [-1.0, 0.5]}}
controller: inverse_dynamics_controller
parameters: {{law: inverse_dynamics, omega_n: 10.0, zeta: 1.0}}
reference: {{shape: step, target: [-0.9, 0.35]}}
variants:
{variants}
"""


def grid_file(directory: Path, duration: float = 0.5) -> Path:
    """The 3 × 3 grid of OMEGAS × MASS_SCALES as a scenario file."""
    variants = (
        f"  grid:\n"
        f"    - {{key: parameters.omega_n, values: {list(OMEGAS)}}}\n"
        f"    - {{key: parameters.model_mass_scale, values: {list(MASS_SCALES)}}}"
    )
    path = directory / "sweep.yaml"
    path.write_text(SCENARIO.format(duration=duration, variants=variants))
    return path


def grid_labels() -> list[str]:
    """The grid's run labels, row-major (the last axis fastest)."""
    return [f"omega_n={w:g},model_mass_scale={m:g}" for w in OMEGAS for m in MASS_SCALES]


def runs_file(directory: Path, runs: list[tuple[str, float, float]], duration: float) -> Path:
    """A scenario file of the explicit ``runs`` (label, ω_n, model mass scale)."""
    lines = [
        f"    - {{label: {label}, set: {{parameters.omega_n: {w}, "
        f"parameters.model_mass_scale: {m}}}}}"
        for label, w, m in runs
    ]
    path = directory / "sweep.yaml"
    path.write_text(SCENARIO.format(duration=duration, variants="  runs:\n" + "\n".join(lines)))
    return path


# -- processes the test started ------------------------------------------------------------


def marked(marker: str) -> list[int]:
    """Live processes (not zombies) whose environment has the marker: other than this one
    and its multiprocessing resource tracker (a helper of this process's own, which lives
    as long as it)."""
    needle = f"{MARKER}={marker}".encode()
    found = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = Path(f"/proc/{entry.name}/environ").read_bytes()
            cmdline = Path(f"/proc/{entry.name}/cmdline").read_bytes()
            state = Path(f"/proc/{entry.name}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        own_tracker = b"resource_tracker" in cmdline and parent_of(int(entry.name)) == os.getpid()
        if needle in environ.split(b"\0") and state != "Z" and not own_tracker:
            found.append(int(entry.name))
    return found


def nodes_under(directory: Path) -> list[int]:
    """Node processes whose command line names a file under ``directory``."""
    needle = os.fsencode(str(directory))
    found = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            cmdline = Path(f"/proc/{entry.name}/cmdline").read_bytes()
            state = Path(f"/proc/{entry.name}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if needle in cmdline and b"--ros-args" in cmdline and state != "Z":
            found.append(int(entry.name))
    return found


def _module(pid: int) -> str:
    """The node's module (``python -m <module> …``)."""
    try:
        args = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        return args[args.index(b"-m") + 1].decode()
    except (OSError, ValueError, IndexError):
        return str(pid)


def up(logs: Path) -> bool:
    """The run's controller and simulator have started (their first log lines)."""
    try:
        controller = (logs / "inverse_dynamics_controller.log").read_text()
        simulator = (logs / "sim_bridge.log").read_text()
    except OSError:
        return False
    return "kp=" in controller and "lockstep" in simulator


def parent_of(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def kill_all(pids: list[int]) -> None:
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


@pytest.fixture
def marker(monkeypatch) -> Iterator[str]:
    """A marker in this process's environment, inherited by the workers and nodes it starts;
    whatever still carries it at the end is killed (and a test that checks none is left
    does so before)."""
    value = uuid.uuid4().hex
    monkeypatch.setenv(MARKER, value)
    try:
        yield value
    finally:
        kill_all(marked(value))


# -- RunPool on its own ------------------------------------------------------------------


def square(x: int) -> int:
    return x * x


def fail_first(flag: str, value: int) -> int:
    """Fails the first time (``flag`` absent, then created), returns ``value`` after."""
    if not os.path.exists(flag):
        Path(flag).touch()
        raise RuntimeError("first attempt fails")
    return value


def always_fail(message: str) -> None:
    raise ValueError(message)


def die_first(flag: str) -> int:
    """Kills its own worker process the first time; returns the pid of the one after."""
    if not os.path.exists(flag):
        Path(flag).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return os.getpid()


def hold_until_cancelled(started: str, seconds: float) -> str:
    """Runs until the pool cancels it (the registered close is called) or ``seconds`` pass;
    touches ``started`` once running."""
    stop = threading.Event()
    with on_cancel(stop.set):
        Path(started).touch()
        stopped = stop.wait(seconds)
    return "stopped" if stopped else "ran out"


def test_threads_pool_runs_tasks_and_retries_a_failure_once(tmp_path):
    lines: list[str] = []
    with RunPool(2, "threads", lines.append) as pool:
        assert pool.workers == 2 and pool.description == "threads, 2"
        squares = [pool.submit(f"sq{k}", square, k) for k in range(5)]
        flaky = pool.submit("flaky", fail_first, str(tmp_path / "flag"), 7)
        broken = pool.submit("broken", always_fail, "no luck")
        assert [f.result(timeout=10) for f in squares] == [0, 1, 4, 9, 16]
        assert flaky.result(timeout=10) == 7
        with pytest.raises(ValueError, match="no luck"):
            broken.result(timeout=10)
    lines = sorted(re.sub(r"jsc-run_\d+", "jsc-run_N", line) for line in lines)
    assert lines == [
        "broken: failed again on jsc-run_N: ValueError: no luck",
        "broken: failed on jsc-run_N: ValueError: no luck; retrying once",
        "flaky: failed on jsc-run_N: RuntimeError: first attempt fails; retrying once",
    ]
    with pytest.raises(RuntimeError, match="closed"):
        pool.submit("late", square, 1)
    pool.close()  # idempotent


def test_threads_pool_cancel_stops_running_tasks_and_drops_queued_ones(tmp_path):
    with RunPool(2, "threads", lambda _: None) as pool:
        futures = [
            pool.submit(f"hold{k}", hold_until_cancelled, str(tmp_path / f"s{k}"), 60)
            for k in range(4)
        ]
        deadline = time.monotonic() + 10
        while not ((tmp_path / "s0").exists() and (tmp_path / "s1").exists()):
            assert time.monotonic() < deadline
            time.sleep(0.05)
        started = time.monotonic()
        pool.cancel()
        assert time.monotonic() - started < 5
        # the running two stopped through on_cancel; the queued two never ran
        assert [f.result(timeout=1) for f in futures[:2]] == ["stopped", "stopped"]
        assert all(f.cancelled() for f in futures[2:])
        assert list(as_completed(futures, timeout=1))  # every future is done
        assert not (tmp_path / "s2").exists() and not (tmp_path / "s3").exists()


def test_local_cluster_retries_a_task_whose_worker_died(tmp_path, marker):
    lines: list[str] = []
    with RunPool(2, None, lines.append) as pool:
        assert pool.workers == 2 and pool.description == "LocalCluster, 2 workers"
        assert pool.missing(tmp_path) == [] and pool.missing(tmp_path / "nowhere") != []
        flag = str(tmp_path / "died")
        survivor = pool.submit("victim", die_first, flag).result(timeout=120)
        assert os.path.exists(flag) and survivor != os.getpid()
        broken = pool.submit("broken", always_fail, "twice")
        with pytest.raises(ValueError, match="twice"):
            broken.result(timeout=60)
    died = [line for line in lines if line.startswith("victim: ")]
    assert len(died) == 1, lines
    assert died[0].startswith("victim: failed on tcp://127.0.0.1:")
    assert died[0].endswith(": its worker died (KilledWorker); retrying once")
    assert any(line.startswith("broken: failed again on tcp://") for line in lines)
    assert marked(marker) == [], "a worker outlived the closed pool"


def test_local_cluster_cancel_stops_running_tasks_on_the_workers(tmp_path, marker):
    with RunPool(2, None, lambda _: None) as pool:
        futures = [
            pool.submit(f"hold{k}", hold_until_cancelled, str(tmp_path / f"s{k}"), 60)
            for k in range(3)
        ]
        deadline = time.monotonic() + 60
        while not ((tmp_path / "s0").exists() and (tmp_path / "s1").exists()):
            assert time.monotonic() < deadline, "the tasks did not start"
            time.sleep(0.05)
        started = time.monotonic()
        pool.cancel()
        assert time.monotonic() - started < 5
        # stopped on their workers by the pool's Event, through on_cancel
        assert [f.result(timeout=1) for f in futures[:2]] == ["stopped", "stopped"]
        assert futures[2].cancelled() and not (tmp_path / "s2").exists()
        with pytest.raises(CancelledError):
            futures[2].result(timeout=0)
    assert marked(marker) == []


@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_an_unreachable_scheduler_is_a_one_line_error(tmp_path):
    with pytest.raises(ValueError, match="cannot connect to the Dask scheduler 'nonsense:x'"):
        RunPool(2, "nonsense:x")
    # nothing listens there: jsc gives up after CONNECT_TIMEOUT with one line
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    result = subprocess.run(
        [sys.executable, "-m", "joint_space_control.cli.main", "experiment"]
        + ["q6_inverse_dynamics_nominal", "--scheduler", "tcp://127.0.0.1:9"]
        + ["--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    assert result.returncode == 2
    assert result.stderr.startswith("jsc experiment: error: cannot connect to the Dask")
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "Traceback" not in result.stderr + result.stdout


# -- sweeps ------------------------------------------------------------------------------

#: What a run's metrics hold that is measured on the wall clock or names the run's files:
#: the rest must be bit-identical wherever the run executes.
WALL_CLOCK = ("bag", "start_time_ns", "duration_s", "message_count")
WALL_CLOCK_TOPICS = (
    "/diagnostics",  # published once a wall-clock second
    "/parameter_events",  # the nodes' start-up declarations: seen or not as discovery goes
)
#: A lockstep plant sends a state left unanswered for its republish_period of wall time
#: again, with its /clock, and a controller may answer it again: the raw counts of the loop's
#: topics and the controller's repeated samples follow the wall clock (seen: 502 states and
#: clocks recorded on threads, 501 on the cluster, the first run 2.9 s slower; every
#: distinct state alike). They are judged against the run's distinct states instead
#: (loop_counts_cover_the_run), and the states themselves are compared stamp by stamp.
RESENT_TOPICS = ("/clock", "/joint_states", "/effort_command")
WALL_CLOCK_CONTROLLER = (
    "period_statistics.receive_period_ms",
    "samples.messages",
    "samples.duplicate_stamps",
)


def loop_topics(metrics: dict[str, Any]) -> set[str]:
    """The topics a state sent again adds to: the plant's and each controller's ``~/state``."""
    return {*RESENT_TOPICS, *(c["state_topic"] for c in metrics["controllers"].values())}


def simulated(metrics: dict[str, Any]) -> dict[str, Any]:
    """``metrics`` without what depends on the wall clock (see WALL_CLOCK, RESENT_TOPICS)."""
    out = {k: v for k, v in metrics.items() if k not in WALL_CLOCK}
    skipped = {*WALL_CLOCK_TOPICS, *loop_topics(metrics)}
    out["message_counts"] = {
        k: v for k, v in metrics["message_counts"].items() if k not in skipped
    }
    controllers = {}
    for node, c in metrics["controllers"].items():
        c = dict(c)
        for path in WALL_CLOCK_CONTROLLER:
            section, key = path.split(".")
            c[section] = {k: v for k, v in c[section].items() if k != key}
        controllers[node] = c
    out["controllers"] = controllers
    return out


def loop_counts_cover_the_run(metrics: dict[str, Any]) -> None:
    """Each loop topic's recorded count is at least the run's distinct states, and a
    controller's repeated samples are the states it answered again."""
    (controller,) = metrics["controllers"].values()
    samples = controller["samples"]
    counts = metrics["message_counts"]
    for topic in sorted(loop_topics(metrics)):
        assert counts[topic] >= samples["analysed"] > 0, (topic, counts, samples)
    assert samples["messages"] == samples["analysed"] + samples["duplicate_stamps"], samples


def same(a: Any, b: Any) -> bool:
    """Equal, with NaN equal to NaN (undefined metrics are NaN in both runs)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return (
            isinstance(b, list | tuple)
            and len(a) == len(b)
            and all(same(x, y) for x, y in zip(a, b, strict=True))
        )
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


@pytest.mark.timeout(900)
@pytest.mark.parametrize(
    "engine",
    [
        # two LocalClusters started: about a minute of a worker, in make test-long too
        pytest.param("inprocess", marks=pytest.mark.long),
        # 18 runs of three nodes each: two minutes, so in make test-long (see docs/testing.md)
        pytest.param("ros", marks=pytest.mark.long),
    ],
)
def test_the_same_sweep_is_bit_identical_on_threads_and_on_a_local_cluster(
    tmp_path, marker, engine
):
    scenario = scenarios.load(str(grid_file(tmp_path)))
    assert [label for label, _ in scenario.runs()] == grid_labels()
    quiet = lambda _: None  # noqa: E731
    threads = run_experiment(scenario, tmp_path / "threads", pool=None, log=quiet, engine=engine)
    with RunPool(2, None, quiet) as pool:
        dask = run_experiment(scenario, tmp_path / "dask", pool=pool, log=quiet, engine=engine)
    # the grid's heat maps, drawn here from what the workers wrote
    assert (dask.out / "sweep.png").is_file() and (threads.out / "sweep.png").is_file()
    on_threads, on_dask = threads.runs, dask.runs
    assert [r.label for r in on_threads] == [r.label for r in on_dask] == grid_labels()
    for a, b in zip(on_threads, on_dask, strict=True):
        assert a.error is None and b.error is None, (a.error, b.error)
        assert a.out.parent.parent.name == "threads" and b.out.parent.parent.name == "dask"
        step = a.controller["steps"][0]["joints"]["joint1"]
        assert math.isfinite(step["overshoot_percent"])  # the metrics hold numbers
        assert same(simulated(a.metrics), simulated(b.metrics)), a.label
        for run in (a, b):
            loop_counts_cover_the_run(run.metrics)
        assert a.events == b.events and a.events[-1]["t"] == 0.5
        assert np.array_equal(a.state.stamp, b.state.stamp)
        for name, rows in a.state.rows.items():
            assert np.array_equal(rows, b.state.rows[name], equal_nan=True), (a.label, name)
    # the runs differ from each other: the comparison is not of nine copies of one run
    rms = {str(r.controller["tracking_error"]["whole_record"]["rms"]) for r in on_dask}
    assert len(rms) == 9
    assert marked(marker) == [], "a worker or node outlived the sweep"


@pytest.mark.long  # a whole sweep on a cluster with a worker killed, ~55 s: make test-long
@pytest.mark.timeout(600)
def test_a_worker_killed_mid_sweep_is_retried_and_leaves_no_node(tmp_path, marker):
    """Four runs, two of them identical, on two workers; the worker of a running run is
    SIGKILLed: its nodes stop by themselves within seconds, the run is retried (logged),
    and the sweep completes with the retried run the same as its twin."""
    runs = [("a", 8.0, 1.0), ("b", 12.0, 0.8), ("a_again", 8.0, 1.0), ("c", 16.0, 1.2)]
    scenario = scenarios.load(str(runs_file(tmp_path, runs, duration=2.0)))
    out = tmp_path / "out"
    lines: list[str] = []
    killed: dict[str, Any] = {}

    def kill_a_worker() -> None:
        """Once a run's three nodes are up (the controller has its gains, the simulator
        waits for the reference): SIGKILL their parent (the worker), then watch them go."""
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline:
            for run_dir in sorted(out.glob("*")):
                nodes = nodes_under(run_dir)
                if len(nodes) >= 3 and up(run_dir / "logs"):
                    time.sleep(0.2)  # in the run
                    nodes = nodes_under(run_dir)
                    worker = {parent_of(pid) for pid in nodes}
                    if len(worker) != 1:
                        continue
                    (pid,) = worker
                    killed.update(run=run_dir.name, worker=pid, nodes=nodes)
                    os.kill(pid, signal.SIGKILL)
                    at = time.monotonic()
                    names = {n: _module(n) for n in nodes}
                    gone: dict[str, float] = {}
                    while len(gone) < len(nodes) and time.monotonic() - at < 20:
                        alive = nodes_under(run_dir)
                        for n in nodes:
                            if n not in alive:
                                gone.setdefault(names[n], time.monotonic() - at)
                        time.sleep(0.05)
                    killed["gone"] = gone
                    killed["nodes_gone_after"] = max(gone.values(), default=math.inf)
                    return
            time.sleep(0.05)

    killer = threading.Thread(target=kill_a_worker, daemon=True)
    with RunPool(2, None, lines.append) as pool:
        killer.start()
        results = run_scenario(scenario, out, pool=pool, log=lines.append)
        killer.join(timeout=30)
        left_after_sweep = nodes_under(tmp_path)
    assert killed, "no run was found running to kill its worker"
    assert killed["nodes_gone_after"] < 5.0, killed
    assert left_after_sweep == [], "node processes outlived the sweep"
    label = killed["run"]
    retried = [line for line in lines if "retrying once" in line]
    assert len(retried) == 1 and retried[0].startswith(f"sweep/{label}: failed on tcp://")
    assert "its worker died (KilledWorker)" in retried[0]
    by_label = {r.label: r for r in results}
    assert sorted(by_label) == ["a", "a_again", "b", "c"]
    assert all(r.error is None for r in results), [r.error for r in results]
    # the retried run is the run it would have been: its identical twin's metrics
    assert same(simulated(by_label["a"].metrics), simulated(by_label["a_again"].metrics))
    assert by_label["a"].events == by_label["a_again"].events
    assert marked(marker) == [], "a worker or node outlived the pool"


@pytest.mark.timeout(300)
@pytest.mark.long  # make test-long (docs/testing.md: make test's budget)
def test_ctrl_c_of_jsc_experiment_on_a_local_cluster_leaves_nothing(tmp_path, marker):
    """Ctrl-C as a terminal sends it: SIGINT to the whole process group (jsc, the Dask
    workers it spawned); exit 130, no node and no worker process left."""
    path = grid_file(tmp_path, duration=3.0)
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "joint_space_control.cli.main", "experiment", str(path)]
        + ["--out", str(out), "--jobs", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        start_new_session=True,  # its own process group, as a shell gives a command
    )
    try:
        deadline = time.monotonic() + 180
        while len(list(out.glob("sweep/*/bag/*.mcap"))) < 2:
            assert proc.poll() is None and time.monotonic() < deadline, "no runs started"
            time.sleep(0.1)
        time.sleep(1.0)  # both runs running
        assert len(nodes_under(out)) >= 3
        os.killpg(proc.pid, signal.SIGINT)
        interrupted = time.monotonic()
        output, _ = proc.communicate(timeout=60)
        took = time.monotonic() - interrupted
        # anything the sweep started and left behind; nodes may take a moment to notice
        deadline = time.monotonic() + 5
        while marked(marker) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = marked(marker)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, output[-3000:]
    assert "interrupted" in output and "Traceback" not in output, output[-3000:]
    assert took < 30, f"jsc took {took:.1f} s to stop"
    assert left == [], f"processes left: {left}"


@pytest.mark.long  # a bench, of ROS runs: make test-long
@pytest.mark.timeout(600)
def test_bench_sweep_section_times_one_sweep_on_one_and_two_workers(tmp_path, marker):
    """``jsc bench`` section ``sweep``, tiny: both cluster sizes measured, every phase of a
    run timed, the rows printed (speeds are not judged: a shared machine)."""
    from joint_space_control.lab.bench.sweep import PHASES, format_sweep, throughput

    lines: list[str] = []
    sweep = throughput(tmp_path, runs=2, duration=0.2, workers=(1, 2), log=lines.append)
    assert [row["workers"] for row in sweep["rows"]] == [1, 2]
    for row in sweep["rows"]:
        assert row["failed"] == 0 and row["runs"] == 2
        assert row["runs_per_minute"] == pytest.approx(120.0 / row["seconds"])
        assert all(row["phases_s"][p] > 0 for p in PHASES), row["phases_s"]
        # a worker's time per run holds the run's phases and the task's own cost
        assert row["other_s"] >= 0, row
        assert row["cpu_seconds"] > 0 and row["cpu_cores_used"] > 0
        assert row["cpu_bound_runs_per_minute"] > 0
    assert sweep["speedup"] == pytest.approx(
        sweep["rows"][1]["runs_per_minute"] / sweep["rows"][0]["runs_per_minute"]
    )
    table = "\n".join(format_sweep(sweep))
    assert "runs/min" in table and "2 workers / 1:" in table
    assert not [line for line in lines if "retrying" in line]
    assert marked(marker) == []
