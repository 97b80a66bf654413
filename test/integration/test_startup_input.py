"""Bad start-up input is one line and exit code 2, never a traceback (issue 15, item 4):
a malformed or missing ``--params-file`` for every executable; a parameter the node does
not have (a typo ROS would ignore silently) is named in one WARN line."""

from __future__ import annotations

import time

import pytest

from joint_space_control.processes.processes import EXECUTABLES, ProcessGroup

from .conftest import next_domain_id

pytestmark = pytest.mark.integration


def _error_lines(log: str) -> list[str]:
    return [line for line in log.splitlines() if line.startswith("error:")]


def test_malformed_or_missing_params_file_is_one_line_and_exit_2(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("sim_bridge:\n  ros__parameters:\n    mode: [realtime\n")
    cases = {"malformed": (bad, "near line 3"), "missing": (tmp_path / "nope.yaml", "opening")}
    with ProcessGroup(tmp_path / "runs", next_domain_id()) as group:
        started = [
            (kind, group.start(exe, {}, f"{exe}_{kind}", ["--params-file", str(path)]), match)
            for exe in EXECUTABLES
            for kind, (path, match) in cases.items()
        ]
        for kind, node, match in started:
            assert node.proc.wait(timeout=60) == 2, (node.name, node.log())
            log = node.log()
            assert "Traceback" not in log, log
            (line,) = _error_lines(log)
            assert "params file" in line and match in line, (kind, line)


def test_a_parameter_the_node_does_not_have_is_named_in_one_warning(tmp_path):
    with ProcessGroup(tmp_path, next_domain_id()) as group:
        node = group.start("sim_bridge", {"physics_rat": 500.0, "viscous_friction": 0.1})
        deadline = time.monotonic() + 60
        while "realtime on pybullet, physics" not in node.log():
            group.check_alive()
            assert time.monotonic() < deadline, node.log()
            time.sleep(0.1)
        warnings = [line for line in node.log().splitlines() if "ignored parameter" in line]
        assert len(warnings) == 1 and "physics_rat" in warnings[0], node.log()
        assert "viscous_friction" not in warnings[0]
