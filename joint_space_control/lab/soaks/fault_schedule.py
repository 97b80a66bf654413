"""The faults of ``jsc soak --faults`` and when each is injected: a seeded schedule, no ROS.

One fault every ``period`` seconds (a minute by default), drawn so that every kind comes at
least once when there are as many faults as kinds: the kinds in a seeded random order first,
then seeded draws, the whole list shuffled once more so that the draws do not all come last.
The same seed gives the same schedule, so a run that failed can be run again fault for fault.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Every kind of fault, and what it does (the order of docs/safety.md's table).
KINDS: dict[str, str] = {
    "kill_controller": "the controller SIGKILLed, restarted after 1 s",
    "kill_simulator": "sim_bridge SIGKILLed and restarted",
    "kill_recorder": "the recorder SIGKILLed and restarted into a new bag",
    "rogue_commander": "a second commander for 5 s: valid commands at 0.9 × the effort limits",
    "malformed_burst": "malformed messages on every input: NaN, wrong sizes, unknown joints, "
    "absurd values",
    "invalid_parameters": "invalid parameter updates of every kind, to the controller and "
    "the plant",
    "huge_reference": "a reference of 100,000 points",
    "second_reference": "a valid reference from a second publisher",
    "cpu_hogs": "a busy process on every core for 10 s",
    "kill_dashboard": "the dashboard SIGKILLed and restarted",
    "second_clock": "/clock from a second publisher for 2 s",
}


@dataclass(frozen=True)
class ScheduledFault:
    index: int
    at: float  # [s] from the start of the run
    kind: str


def fault_schedule(
    seconds: float, period: float = 60.0, seed: int = 0, kinds: tuple[str, ...] = tuple(KINDS)
) -> list[ScheduledFault]:
    """The faults of a run of ``seconds``: one at ``period``, 2·period, … (none in the
    last ``period``/2, so that the loop's recovery from the last one is seen), each kind at
    least once when there are at least as many faults as kinds."""
    if period <= 0 or seconds <= 0:
        raise ValueError("the run and the period between faults must be > 0 s")
    unknown = [k for k in kinds if k not in KINDS]
    if unknown or not kinds:
        raise ValueError(f"unknown fault kinds {unknown}; known: {list(KINDS)}")
    count = int((seconds - period / 2) // period)
    rng = np.random.default_rng(seed)
    every = [kinds[i] for i in rng.permutation(len(kinds))]
    if count <= len(every):
        chosen = every[:count]
    else:
        drawn = [kinds[i] for i in rng.integers(len(kinds), size=count - len(every))]
        chosen = every + drawn
        chosen = [chosen[i] for i in rng.permutation(len(chosen))]
    return [ScheduledFault(k, (k + 1) * period, kind) for k, kind in enumerate(chosen)]
