"""What a measurement was made on: the machine and the software versions.

``jsc bench`` and ``jsc soak`` both report timings of a shared, possibly virtual machine;
the numbers mean little without the CPU, its load, the CPU time the hypervisor stole and
the versions that ran. Neither tool owns this description, so it lives below both.
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
import sys
import timeit
from pathlib import Path
from typing import Any

#: Distributions reported, by the name shown (first installed distribution wins).
PACKAGES = {
    "rclpy": ("ros-jazzy-rclpy", "ros-rclpy", "rclpy"),
    "rmw_fastrtps_cpp": ("ros-rmw-fastrtps-cpp",),
    "fastdds": ("ros-fastrtps",),
    "pinocchio": ("pin",),
    "pybullet": ("pybullet",),
    "numpy": ("numpy",),
}


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo), else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:  # pragma: no cover - not Linux
        pass
    return platform.processor() or platform.machine()


def python_speed_us(repeat: int = 5, number: int = 1000) -> float:
    """A yardstick of this machine for the Python the loop's nodes run: the best of
    ``repeat`` timings of ``sum(range(1000))`` [µs] (``python -m timeit "sum(range(1000))"``).

    The same CPU model can run it several times slower on a loaded or throttled host, and a
    realtime loop's figures mean little without it: about 10 µs on the machines where the
    1 kHz fault soak passed its hour, 28–43 µs on a VM where the 1 kHz loop could not keep
    up beside the rest of the run (docs/safety.md)."""
    timer = timeit.Timer("sum(range(1000))")
    return min(timer.repeat(repeat=repeat, number=number)) / number * 1e6


def machine() -> dict[str, Any]:
    """CPU, cores (all and usable by this process), platform, load averages and
    :func:`python_speed_us` now."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return {
        "cpu": cpu_model(),
        "python_speed_us": round(python_speed_us(), 1),
        "cores": os.cpu_count(),
        "cores_usable": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "platform": platform.platform(),
        "load_average_1_5_15": [round(x, 2) for x in load],
    }


def describe(found: dict[str, Any]) -> str:
    """One line of :func:`machine`'s answer: CPU, cores, the Python yardstick (when measured),
    load averages."""
    speed = found.get("python_speed_us")
    yardstick = f", sum(range(1000)) in {speed:g} µs" if speed is not None else ""
    return (
        f"{found['cpu']}, {found['cores']} cores{yardstick}, load {found['load_average_1_5_15']}"
    )


def versions() -> dict[str, str]:
    """Python, the ROS and numerical packages of :data:`PACKAGES`, the RMW in use."""
    out = {"python": sys.version.split()[0]}
    for shown, candidates in PACKAGES.items():
        for name in candidates:
            try:
                out[shown] = importlib.metadata.version(name)
                break
            except importlib.metadata.PackageNotFoundError:
                continue
        else:
            out[shown] = "not installed"
    out["rmw_implementation"] = os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp (default)")
    return out


class CpuMeter:
    """How this machine's CPUs spent their time (/proc/stat, all processes) since the meter
    was made, as fractions of all CPU time; None where not available."""

    def __init__(self) -> None:
        self._start = _cpu_times()

    def _delta(self) -> list[int] | None:
        end = _cpu_times()
        if self._start is None or end is None:
            return None
        delta = [b - a for a, b in zip(self._start, end, strict=False)]
        return delta if sum(delta) > 0 else None

    def steal(self) -> float | None:
        """The time the hypervisor took ("steal") while a part of the benchmark ran."""
        delta = self._delta()
        return None if delta is None else delta[7] / sum(delta)

    def busy(self) -> float | None:
        """The time the CPUs were neither idle nor waiting for I/O."""
        delta = self._delta()
        return None if delta is None else (sum(delta) - delta[3] - delta[4]) / sum(delta)


def _cpu_times() -> list[int] | None:
    try:
        fields = Path("/proc/stat").read_text().splitlines()[0].split()
    except OSError:  # pragma: no cover - not Linux
        return None
    values = [int(v) for v in fields[1:]]
    return values if len(values) >= 8 else None
