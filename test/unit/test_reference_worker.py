"""ReferenceBuilder (issue 15, item 3): a large reference is built in a child process and
arrives as the same trajectory, with its arrays taken over without a copy; a rejected one
gives its reason; a dead child is replaced; close() stops it."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from rclpy.serialization import serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from joint_space_control.ros.reference_worker import (
    IN_THREAD_BYTES,
    ReferenceBuilder,
    build_reference,
)

JOINTS = ("a", "b")
LIMITS = (np.array([-2.0, -2.0]), np.array([2.0, 2.0]))


def sine(points: int, joints=JOINTS, amplitude: float = 0.5) -> bytes:
    msg = JointTrajectory(joint_names=list(joints))
    for k in range(1, points + 1):
        t = k * 1e-3
        sec, nsec = divmod(k * 1_000_000, 1_000_000_000)
        msg.points.append(
            JointTrajectoryPoint(
                positions=[amplitude * np.sin(t), -amplitude * np.cos(t)],
                time_from_start=Duration(sec=sec, nanosec=nsec),
            )
        )
    return bytes(serialize_message(msg))


@pytest.fixture
def builder():
    b = ReferenceBuilder()
    yield b
    b.close()


def arrays(tr) -> dict[str, np.ndarray]:
    out = {k: getattr(tr, k) for k in ("times", "positions", "velocities", "accelerations")}
    out |= {f"basis.{k}": getattr(tr.basis, k) for k in ("v", "a", "v_q", "a_q", "v_dq", "a_dq")}
    return out


def test_a_large_reference_is_built_in_a_child_as_it_would_be_here(builder):
    raw = sine(10_000)
    assert len(raw) > IN_THREAD_BYTES
    built = builder.build(raw, JOINTS, 2.5, LIMITS)
    assert builder.process_id is not None and builder.process_id != os.getpid()
    here = build_reference(raw, JOINTS, 2.5, LIMITS)
    assert built.start == here.start == 2.5
    for name, value in arrays(here).items():
        np.testing.assert_array_equal(arrays(built)[name], value, err_msg=name)
    # taken over from the pipe's buffers, not copied; read-only like a built trajectory's
    owner = built.positions
    while isinstance(owner, np.ndarray):
        owner = owner.base
    assert isinstance(owner, bytes) and not built.positions.flags.writeable


def test_a_small_reference_is_built_in_the_calling_thread(builder):
    built = builder.build(sine(100), JOINTS, 0.0, LIMITS)
    assert len(built.times) == 100 and builder.process_id is None


def test_a_rejected_reference_gives_its_reason_from_the_child(builder):
    outside = builder.build(sine(10_000, amplitude=3.0), JOINTS, 0.0, LIMITS)
    assert isinstance(outside, str) and "outside its limits" in outside
    unknown = builder.build(sine(10_000, joints=("a", "c")), JOINTS, 0.0, LIMITS)
    assert isinstance(unknown, str) and "missing joints ['b']" in unknown
    assert builder.process_id is not None  # the same child still serves


def test_a_dead_child_fails_one_reference_and_is_replaced(builder):
    raw = sine(10_000)
    builder.build(raw, JOINTS, 0.0, LIMITS)
    first = builder.process_id
    os.kill(first, signal.SIGKILL)
    failed = builder.build(raw, JOINTS, 0.0, LIMITS)
    assert isinstance(failed, str) and "reference worker process failed" in failed
    again = builder.build(raw, JOINTS, 0.0, LIMITS)
    assert len(again.times) == 10_000 and builder.process_id not in (None, first)


def test_close_stops_the_child(builder):
    builder.build(sine(10_000), JOINTS, 0.0, LIMITS)
    pid = builder.process_id
    builder.close()
    assert builder.process_id is None
    with pytest.raises(ProcessLookupError):  # exited and reaped
        os.kill(pid, 0)
    assert builder.build(sine(10_000), JOINTS, 0.0, LIMITS) == "the controller is shutting down"
