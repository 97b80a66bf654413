"""A lockstep closed loop of real node processes, started deterministically.

The simulator starts paused; once the controller and the simulator are connected, the
reference is published and acknowledged by every subscriber, and only then is the simulator
resumed. Same inputs therefore give the same run, however loaded the machine is.

A loop holds one robot (its topics in the root namespace), or several robots in one world
(one ``sim_bridge``, docs/robots.md "Several robots"), each with its own controller in its
namespace; the world steps once every controller has answered.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from std_msgs.msg import Float64MultiArray

from joint_space_control.processes.client import STARTUP_TIMEOUT, RosClient
from joint_space_control.processes.domains import lease_domain
from joint_space_control.processes.probe import LoopProbe, in_namespace
from joint_space_control.processes.processes import ProcessGroup
from joint_space_control.recording.selection import world_topics
from joint_space_control.ros.messages import paused_stamp
from joint_space_control.simulation.world import Arm

#: After the recorder's subscriptions are matched with the run's publishers, the time
#: given to the publishers' side of those matches [s]: seen lagging by about 30 ms (a
#: lockstep plant's first 57 states and clocks missing from the bag, load 7 on 2 cores).
MATCH_MARGIN = 0.5
#: After the last state of a run, the recorder is asked every RECORD_POLL [s] what it holds,
#: until it has the whole run and its counts have not changed for RECORD_QUIET [s] (at most
#: RECORD_SETTLE_MAX [s]).
RECORD_POLL = 0.1
RECORD_QUIET = 0.5
RECORD_SETTLE_MAX = 60.0
#: Longest wait [s] for the probe to take the states up to the one a pause named.
PAUSE_TAIL_MAX = 60.0
#: A recorder whose counts stay short of the run's and unchanged this long [s] has missed
#: messages for good (not worth waiting RECORD_SETTLE_MAX for).
RECORD_GAVE_UP = 15.0
#: The plant's true state beside an imperfect measurement, in a robot's namespace.
TRUTH_TOPIC = "sim_bridge/true_joint_states"
#: Topics published by wall-time timers (they grow while the run is paused): not awaited.
_BACKGROUND_TOPICS = frozenset({"/diagnostics", "/parameter_events", "/rosout"})


class ClosedLoop:
    """sim_bridge (lockstep) + one controller per robot (answering every state) + a probe,
    and a recorder writing the bag ``record`` when one is given.

    ``robot``: the one robot's name (with ``controller`` and ``controller_params``;
    ``sim_params`` then holds its sim_bridge parameters and the world's), or the robots of a
    world of several, each in its namespace with its controller, its parameters and its own
    sim_bridge parameters (``plant``; ``sim_params``: the world's only; their references
    are the caller's to send)."""

    def __init__(
        self,
        workdir: Path,
        domain_id: int | None,
        robot: str | Sequence[Arm],
        controller: str = "pd_gravity_controller",
        controller_params: Mapping[str, Any] | None = None,
        sim_params: Mapping[str, Any] | None = None,
        record: Path | None = None,
        recorder_params: Mapping[str, Any] | None = None,
    ) -> None:
        if isinstance(robot, str):
            self.robots = [Arm("", robot, controller, dict(controller_params or {}), {})]
            world = {"robot": robot, **(sim_params or {})}
        else:
            self.robots = list(robot)
            names = [r.name for r in self.robots]
            world = {
                "robots": names,
                **{r.name: {"robot": r.robot, **r.plant} for r in self.robots},
                **(sim_params or {}),
            }
            # each robot's topics, in its namespace
            recorder_params = {"topics": world_topics(names), **(recorder_params or {})}
        self.robot = self.robots[0].robot  # the (first) robot's
        self.controller = self.robots[0].controller
        self.bag = record
        self._lease = None
        self._closing = threading.Lock()
        if domain_id is None:  # one no other run on this machine uses
            self._lease = lease_domain()
            domain_id = self._lease.domain_id
        self.domain_id = domain_id
        # the nodes hold the lease too: a node that outlives this process (killed) keeps
        # its domain from the next run until it has stopped (processes.py)
        lease_fd = self._lease.fileno() if self._lease is not None else None
        self.group = ProcessGroup(workdir, domain_id, () if lease_fd is None else (lease_fd,))
        self.probe: LoopProbe | None = None
        try:
            if record is not None:  # first: it sees every node's parameters and config
                self.group.start("recorder", {**(recorder_params or {}), "output": str(record)})
            self.group.start("sim_bridge", {**world, "mode": "lockstep", "start_paused": True})
            for r in self.robots:
                self.group.start(
                    r.controller,
                    {"robot": r.robot, **r.parameters, "trigger": "state"},
                    namespace=r.name,
                )
            self.probe = LoopProbe(
                domain_id,
                name=f"jsc_probe_{domain_id}",
                namespaces=[r.name for r in self.robots],
            )
            for r in self.robots:
                # the controller itself subscribed (a recorder alone satisfies the counts)
                self.probe.wait_for_subscriber(
                    r.controller,
                    _absolute(r.name, "reference", "joint_states"),
                    check=self.group.check_alive,
                )
            self.probe.wait_for_graph(
                check=self.group.check_alive, reference_subscribers=1 + (record is not None)
            )
            if record is not None:
                for r in self.robots:  # how many states the recorder must have, at least
                    state_topic = _absolute(r.name, f"{r.controller}/state")[0]
                    self.probe.count(Float64MultiArray, state_topic)
                run_topics = ["/clock"]
                for r in self.robots:
                    run_topics += _absolute(
                        r.name,
                        "joint_states",
                        "effort_command",
                        "reference",
                        f"{r.controller}/state",
                    )
                self.wait_recorder_matched(run_topics)  # subscribed, and matched
        except BaseException:
            self.close()
            raise

    def wait_recorder_matched(
        self, topics: Sequence[str], timeout: float = STARTUP_TIMEOUT
    ) -> None:
        """:func:`wait_recorder_matched` with the run's probe."""
        wait_recorder_matched(self.probe, topics, self.group.check_alive, timeout)

    def start(
        self,
        joints: Sequence[str],
        positions: Sequence[Sequence[float]],
        times: Sequence[float] = (0.0,),
        velocities: Sequence[Sequence[float]] | None = None,
        accelerations: Sequence[Sequence[float]] | None = None,
    ) -> None:
        """Send the (first) robot's reference (acknowledged) and only then let the simulator
        run. With several robots: ``probe.send_reference(..., namespace=)`` to each, then
        :meth:`resume`."""
        self.probe.send_reference(
            joints, positions, times, velocities=velocities, accelerations=accelerations
        )
        self.resume()

    def run_until(self, t_sim: float, timeout: float = 300.0) -> None:
        self.probe.run_until(t_sim, timeout, check=self.group.check_alive)

    def hold_at(self, t_sim: float) -> None:
        """With the simulator's ``pause_at`` = t_sim: wait until it has paused there and the
        controllers have answered that state (the answer is repeated after ``resume()``),
        so that changes made now apply from the next step, in every run alike."""
        self.run_until(t_sim)
        self.probe.wait_for_answer(round(t_sim * 1e9), check=self.group.check_alive)

    def resume(self) -> None:
        response = self.probe.call_trigger("/sim_bridge/resume")
        if not response.success:
            raise RuntimeError(f"sim_bridge did not resume: {response.message}")

    def pause(self, settle: float = 0.3) -> int | None:
        """Pause the simulator and collect what is still in flight: afterwards the probe's
        last joint state is the last one the simulator published. Returns that state's
        stamp [ns] as the simulator's answer names it."""
        response = self.probe.call_trigger("/sim_bridge/pause")
        if not response.success:
            raise RuntimeError(f"sim_bridge did not pause: {response.message}")
        # the last state the plant sent, named in its answer: a quiet spell alone once ended
        # the wait with the probe 128 states short of it on a loaded machine
        last = paused_stamp(response.message)
        if last is not None:
            self.probe.spin_until(
                lambda: self.probe.latest_time() >= last * 1e-9,
                PAUSE_TAIL_MAX,
                f"the probe to take the states up to the pause at {last * 1e-9:.3f} s",
                self.group.check_alive,
            )
        # then until no state came for ``settle`` seconds: the probe may lag a loop that runs
        # faster than real time by more than that
        stamps = self.probe.recording.stamps
        for _ in range(100):
            seen = len(stamps)
            self.probe.spin_for(settle)
            if len(stamps) == seen:
                return last
        raise RuntimeError("joint states still coming after the simulator paused")

    def final_state(self) -> tuple[np.ndarray, np.ndarray]:
        _, q, dq, _ = self.probe.recording.arrays()
        return q[-1], dq[-1]

    def settle_recording(self, timeout: float = RECORD_SETTLE_MAX) -> None:
        """Wait until the recorder has taken the tail of the run before the nodes stop: a
        lockstep plant runs faster than the recorder writes, and what is still on its way
        when the plant's process ends is lost (seen: the last 160–1260 of 3000 states). The
        plant is paused by then. The recorder's ``~/flush`` answers what it has recorded per
        topic: the wait ends once it holds, of each robot, every joint state and ``/clock``
        message the simulator published (and every true state, when it publishes them) and
        at least the commands and the controllers' ``~/state`` messages the probe received,
        and its counts of the run's topics have then not changed for RECORD_QUIET. Under load
        the recorder takes its topics unevenly: seen, the joint states complete while 300 of
        3000 controller states were still on their way, and (before the states were counted)
        a bag closed with 11 of 34 states of a sampled-period run."""
        if self.bag is None:
            return
        expected: dict[str, int] = {}
        for r in self.robots:
            # distinct states: a state sent again (republish_period, a resume) may reach the
            # probe and not the recorder, or both (seen: 2003 at the probe, 2001 recorded)
            n = len(set(self.probe.recordings[r.name].stamps))
            expected[_absolute(r.name, "joint_states")[0]] = n
            expected[_absolute(r.name, TRUTH_TOPIC)[0]] = n  # if published at all
            expected[_absolute(r.name, "effort_command")[0]] = self.probe.commands[r.name]
        expected["/clock"] = max(expected.values())
        expected.update(self.probe.counted)  # each controller's ~/state the probe received
        deadline = time.monotonic() + timeout
        previous: dict[str, int] | None = None
        since = time.monotonic()
        while True:
            counts = self.recorded_counts()
            run = {k: v for k, v in counts.items() if k not in _BACKGROUND_TOPICS}
            complete = all(
                counts.get(topic, 0) >= n
                for topic, n in expected.items()
                if not (topic.endswith(TRUTH_TOPIC) and counts.get(topic, 0) == 0)
            )
            if run != previous:
                previous, since = run, time.monotonic()
            elif complete and time.monotonic() - since >= RECORD_QUIET:
                return
            elif not complete and time.monotonic() - since >= RECORD_GAVE_UP:
                raise RuntimeError(
                    f"the recorder missed messages of the run: recorded {counts}, at least "
                    f"{expected} expected, and nothing more for {RECORD_GAVE_UP:g} s"
                )
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"the recorder did not take the run's tail within {timeout:g} s: "
                    f"recorded {counts}, at least {expected} expected"
                )
            time.sleep(RECORD_POLL)

    def recorded_counts(self) -> dict[str, int]:
        """The messages the recorder has written, per topic (its ``~/flush`` answer)."""
        response = self.probe.call_trigger("/recorder/flush", check=self.group.check_alive)
        if not response.success:
            raise RuntimeError(f"the recorder failed: {response.message}")
        return json.loads(response.message)

    def close(self) -> None:
        """Stop everything (idempotent; Ctrl-C may close a loop from another thread)."""
        with self._closing:
            probe, self.probe = self.probe, None
            if probe is not None:
                probe.close()
            self.group.stop_all()
            if self._lease is not None:
                self._lease.release()

    def __enter__(self) -> ClosedLoop:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def wait_recorder_matched(
    client: RosClient,
    topics: Sequence[str],
    check: Callable[[], None],
    timeout: float = STARTUP_TIMEOUT,
) -> None:
    """Wait until the recorder's subscription to each of ``topics`` is matched with a
    publisher (its ``~/matched``, asked through ``client``), then :data:`MATCH_MARGIN`. A
    subscription the graph shows is not yet one the publisher sends to: under load the
    controller's ``~/state`` was matched 0.18 s into a lockstep run, and its first 357 of
    1001 states were missing from the bag. The recorder's side of a match comes first; the
    publisher's, which nothing outside its process can see, follows."""
    deadline = time.monotonic() + timeout
    while True:
        response = client.call_trigger("/recorder/matched", check=check)
        matched = json.loads(response.message)
        unmatched = [t for t in topics if matched.get(t, 0) < 1]
        if not unmatched:
            client.spin_for(MATCH_MARGIN)
            return
        if time.monotonic() > deadline:
            raise TimeoutError(
                f"the recorder's subscriptions to {unmatched} were not matched with a "
                f"publisher within {timeout:g} s"
            )
        client.spin_for(RECORD_POLL, check)


def _absolute(namespace: str, *topics: str) -> list[str]:
    """The absolute names of ``topics`` in ``namespace`` ("": the root)."""
    return [f"/{in_namespace(namespace, topic)}" for topic in topics]
