"""Domain leases: concurrent runs on one machine never share a ROS domain."""

from __future__ import annotations

import json
import subprocess
import sys

from joint_space_control.processes.domains import FIRST, LAST, lease_domain

#: Another process leasing every domain it can get, printing their ids.
GRAB_ALL = """
import json
from joint_space_control.processes.domains import lease_domain
held = []
while True:
    try:
        held.append(lease_domain())
    except RuntimeError:
        break
print(json.dumps([lease.domain_id for lease in held]))
"""


def grab_all() -> list[int]:
    other = subprocess.run(
        [sys.executable, "-c", GRAB_ALL], capture_output=True, text=True, timeout=60
    )
    assert other.returncode == 0, other.stderr
    return json.loads(other.stdout)


def test_leases_held_at_once_are_all_different_and_in_range():
    leases = [lease_domain() for _ in range(10)]
    try:
        ids = [lease.domain_id for lease in leases]
        assert len(set(ids)) == len(ids)
        assert all(FIRST <= d <= LAST for d in ids)
    finally:
        for lease in leases:
            lease.release()


def test_a_leased_domain_is_never_handed_to_another_process_until_released():
    with lease_domain() as mine:
        taken = grab_all()
        assert taken and mine.domain_id not in taken
        held_id = mine.domain_id
    assert held_id in grab_all()  # released: free for others
