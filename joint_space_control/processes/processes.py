"""Start nodes as separate processes, the way a launch file would, and always stop them.

Each node runs as ``python -m <module> --ros-args -r __node:=<name> --params-file <yaml>``
(and ``-r __ns:=/<namespace>`` for a robot's node in a world of several) in an isolated ROS
domain (``ROS_DOMAIN_ID``) with localhost-only discovery.

A node never outlives the process that started it: ``JSC_PARENT_PID`` in its environment
names that process, and the node stops as on SIGTERM once it is gone
(:func:`~joint_space_control.ros.node_main.watch_parent`), also when it was killed and could
not stop its nodes (a Dask worker that died mid-run). A node also holds the run's domain
lease (its lock file stays open in the node), so the domain is handed out again only once
every node of the run has exited.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from joint_space_control.ros.node_main import PARENT_PID_ENV

#: Executable name → module with ``main`` (the console scripts of the package).
EXECUTABLES = {
    "sim_bridge": "sim_bridge.node",
    "pd_gravity_controller": "joint_space_control.nodes.pd_gravity_controller",
    "inverse_dynamics_controller": "joint_space_control.nodes.inverse_dynamics_controller",
    "recorder": "joint_space_control.nodes.recorder",
    "trajectory_generator": "joint_space_control.nodes.trajectory_generator",
    "dashboard": "joint_space_control.nodes.dashboard",
}


def isolated_env(domain_id: int, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment for one run: its own domain, discovery on this machine only."""
    if not 0 <= domain_id <= 101:
        raise ValueError("ROS_DOMAIN_ID must be in 0..101")
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


class NodeProcess:
    """One node process with its parameters file and log file."""

    def __init__(
        self,
        executable: str,
        name: str,
        params: Mapping[str, Any],
        workdir: Path,
        env: Mapping[str, str],
        extra_args: list[str] | None = None,
        prefix: Sequence[str] = (),
        namespace: str = "",
        hold_fds: Sequence[int] = (),
        tag: str = "",
    ) -> None:
        """``prefix``: a command that runs the node (``setpriv …``, ``taskset …``);
        ``namespace``: the node's (its files then go in ``workdir/<namespace>/``);
        ``hold_fds``: descriptors the node keeps open while it runs (a domain lease);
        ``tag``: added to the names of its files (a node restarted under the same name keeps
        the log of each run)."""
        if executable not in EXECUTABLES:
            raise ValueError(f"unknown executable '{executable}'")
        if namespace:
            workdir = workdir / namespace
            extra_args = ["-r", f"__ns:=/{namespace}", *(extra_args or [])]
        workdir.mkdir(parents=True, exist_ok=True)
        self.name = f"{namespace}/{name}" if namespace else name
        self.executable = executable
        self.params_file = workdir / f"{name}{tag}.params.yaml"
        self.params_file.write_text(yaml.safe_dump({"/**": {"ros__parameters": dict(params)}}))
        self.log_path = workdir / f"{name}{tag}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 - closed in stop()
        cmd = [
            *prefix,
            sys.executable,
            "-m",
            EXECUTABLES[executable],
            "--ros-args",
            "-r",
            f"__node:={name}",
            "--params-file",
            str(self.params_file),
            *(extra_args or []),
        ]
        self.proc = subprocess.Popen(
            cmd,
            env={**env, PARENT_PID_ENV: str(os.getpid())},
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            pass_fds=tuple(hold_fds),
        )

    def alive(self) -> bool:
        return self.proc.poll() is None

    def signal(self, sig: int) -> None:
        if self.alive():
            self.proc.send_signal(sig)

    def stop(self, timeout: float = 5.0) -> int:
        """SIGINT, then SIGTERM, then SIGKILL: the process is gone when this returns."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not self.alive():
                break
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                continue
        self.proc.wait()
        self._log.close()
        return self.proc.returncode

    def log(self) -> str:
        self._log.flush()
        return self.log_path.read_text(errors="replace")


def stop_together(nodes: Sequence[NodeProcess], timeout: float = 5.0) -> None:
    """:meth:`NodeProcess.stop` of every one of ``nodes`` at once: each signal goes to all
    that still run, then they get ``timeout`` seconds between it and the next."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        running = [n for n in nodes if n.alive()]
        if not running:
            break
        for node in running:
            node.signal(sig)
        deadline = time.monotonic() + timeout
        for node in running:
            try:
                node.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                continue
    for node in nodes:
        node.stop()  # reaped, its log closed (nothing left to signal)


class ProcessGroup:
    """Context manager owning node processes; every one is stopped on exit, also on error."""

    def __init__(self, workdir: Path, domain_id: int, hold_fds: Sequence[int] = ()) -> None:
        """``hold_fds``: descriptors every node keeps open (the lock of the domain's lease:
        the domain stays leased until the last node has exited)."""
        self.workdir = Path(workdir)
        self.env = isolated_env(domain_id)
        self.hold_fds = tuple(hold_fds)
        self.nodes: dict[str, NodeProcess] = {}

    def start(
        self,
        executable: str,
        params: Mapping[str, Any],
        name: str | None = None,
        extra_args: list[str] | None = None,
        prefix: Sequence[str] = (),
        namespace: str = "",
        tag: str = "",
    ) -> NodeProcess:
        """Start a node; it is ``nodes[name]``, or ``nodes["<namespace>/<name>"]``
        (``tag``: see :class:`NodeProcess`)."""
        node = NodeProcess(
            executable,
            name or executable,
            params,
            self.workdir,
            self.env,
            extra_args,
            prefix,
            namespace,
            self.hold_fds,
            tag,
        )
        self.nodes[node.name] = node
        return node

    def check_alive(self) -> None:
        dead = [n for n in self.nodes.values() if not n.alive()]
        if dead:
            raise RuntimeError(
                "; ".join(
                    f"node '{n.name}' exited with {n.proc.returncode}:\n{n.log()[-2000:]}"
                    for n in dead
                )
            )

    def stop_all(self, timeout: float = 5.0) -> None:
        """Stop every node: the recorders last, so that they take what the others sent
        until they stopped; the others together (SIGINT to each, then SIGTERM and SIGKILL
        to those still running after ``timeout``): a run's stop costs one node's stop, not
        the sum of them."""
        nodes = list(reversed(self.nodes.values()))
        stop_together([n for n in nodes if n.executable != "recorder"], timeout)
        stop_together([n for n in nodes if n.executable == "recorder"], timeout)

    def __enter__(self) -> ProcessGroup:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
