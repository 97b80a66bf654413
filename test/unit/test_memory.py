"""A large message's memory goes back to the system (joint_space_control/memory.py), and a
replaced reference is freed at once, not by the cyclic collector a node rarely runs."""

from __future__ import annotations

import gc
import subprocess
import sys
import weakref

import numpy as np
import pytest

from joint_space_control.memory import give_back_free_memory, large_blocks_from_the_system
from joint_space_control.trajectories.reference import Reference, Trajectory

#: In a fresh process: one 10 MB block freed (glibc then raises its threshold to 10 MB),
#: then eight 5.6 MB arrays (a 100,000-point reference's) made and freed; prints the
#: resident memory [MB] they leave behind.
LEFT_BEHIND = """
import os
import sys
import numpy as np
from joint_space_control.lab.soaks.soak import rss_of
from joint_space_control.memory import large_blocks_from_the_system
def rss():
    return rss_of(os.getpid()) / 2**20
if sys.argv[1] == "set":
    assert large_blocks_from_the_system()
big = np.ones(10 << 17)
del big
before = rss()
arrays = [np.ones((100_000, 7)) for _ in range(8)]
pin = np.ones(250_000)  # 2 MB after them, kept: the top of the heap is in use
del arrays
print(rss() - before)
"""


def resident_left(script: str, mode: str) -> float:
    """What ``script`` prints [MB], run in a fresh process with ``mode`` as its argument."""
    out = subprocess.run(
        [sys.executable, "-c", script, mode], capture_output=True, text=True, check=True
    )
    return float(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator, /proc")
def test_large_blocks_go_back_to_the_system_once_the_threshold_is_set():
    kept_by_default = resident_left(LEFT_BEHIND, "default")
    kept_when_set = resident_left(LEFT_BEHIND, "set")
    # glibc's raised threshold keeps the 45 MB in the heap; set, they go back
    assert kept_by_default > 30.0, kept_by_default
    assert kept_when_set < 5.0, kept_when_set


#: In a fresh process: 40 MB of 64 kB blocks in the heap, every other one freed while the
#: rest stay (a heap full of holes, none at its top), then the allocator asked to give its
#: free pages back (``trim``) or not; prints the resident memory [MB] the freed half leaves.
HOLES = """
import ctypes
import os
import sys
from joint_space_control.lab.soaks.soak import rss_of
from joint_space_control.memory import give_back_free_memory, large_blocks_from_the_system
def rss():
    return rss_of(os.getpid()) / 2**20
large_blocks_from_the_system()  # as every node: 64 kB blocks come from the heap
libc = ctypes.CDLL(None)
malloc, free = libc.malloc, libc.free
malloc.restype, malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
free.argtypes = (ctypes.c_void_p,)
blocks = [malloc(64 << 10) for _ in range(640)]
for b in blocks:
    ctypes.memset(b, 1, 64 << 10)  # resident
before = rss()
for b in blocks[::2]:
    free(b)
if sys.argv[1] == "trim":
    assert give_back_free_memory()
print(rss() - (before - 20.0))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator, /proc")
def test_freed_blocks_between_kept_ones_stay_resident_until_given_back():
    """What the recorder's periodic give-back is for: free() returns only the top of the
    heap to the system, so 20 MB freed between blocks still in use stay resident (a
    process's memory creeps up as such holes appear); give_back_free_memory returns them."""
    kept_after_free = resident_left(HOLES, "free")
    kept_after_trim = resident_left(HOLES, "trim")
    assert kept_after_free > 15.0, kept_after_free
    assert kept_after_trim < 5.0, kept_after_trim


def test_give_back_free_memory_runs_on_glibc():
    assert give_back_free_memory() is sys.platform.startswith("linux")
    assert large_blocks_from_the_system() is sys.platform.startswith("linux")


def test_a_replaced_reference_is_freed_without_the_cyclic_collector():
    times = np.arange(1, 2001) * 1e-3
    positions = np.sin(times)[:, None] * np.ones(3)
    old = Reference(Trajectory.build(0.0, times, positions), Reference.hold(np.zeros(3)).sample(0))
    old.sample(0.5)  # its knot rows filled
    gone = weakref.ref(old)
    enabled = gc.isenabled()
    gc.disable()
    try:
        new = Reference.hold(np.ones(3), 1.0)
        del old
        assert gone() is None  # freed by reference counting: no cycle through itself
        assert new.sample(2.0).q.tolist() == [1.0, 1.0, 1.0]
    finally:
        if enabled:
            gc.enable()
