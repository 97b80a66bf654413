"""ROS domains for concurrent runs on one machine: each run leases a domain id that no other
run on the machine holds (an exclusive lock file per id, released when the lease is closed
or the process ends), so two experiments or test workers never see each other's nodes."""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

#: Domain ids handed out (0, the usual interactive default, is never used).
FIRST, LAST = 1, 100


class DomainLease:
    def __init__(self, domain_id: int, handle) -> None:
        self.domain_id = domain_id
        self._handle = handle

    def fileno(self) -> int | None:
        """The descriptor of the lock (None once released): a child process that keeps it
        open holds the domain after the lease is released, until it exits."""
        return None if self._handle is None else self._handle.fileno()

    def release(self) -> None:
        """Give the domain back (idempotent, also from another thread)."""
        handle, self._handle = self._handle, None
        if handle is not None:
            handle.close()  # closing the file drops its lock

    def __enter__(self) -> DomainLease:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _lock_dir() -> Path:
    path = Path(tempfile.gettempdir()) / f"jsc_ros_domains_{os.getuid()}"
    path.mkdir(exist_ok=True)
    return path


def lease_domain() -> DomainLease:
    """A domain id no other lease on this machine holds (starting from a pid-dependent id)."""
    count = LAST - FIRST + 1
    start = os.getpid() % count
    directory = _lock_dir()
    for k in range(count):
        domain = FIRST + (start + k) % count
        handle = open(directory / f"{domain}.lock", "w")  # noqa: SIM115 - held by the lease
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return DomainLease(domain, handle)
    raise RuntimeError(f"every ROS domain {FIRST}..{LAST} is leased by a run on this machine")
