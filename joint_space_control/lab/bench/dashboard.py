"""The dashboard beside the loop: the same loop measured without and with the
dashboard node running and its page open in a browser, alternating in pairs.

Each pair runs, in this order: lockstep (sim_bridge + the PD + g controller on
``planar_2dof``, ``use_sim_time:=true`` as users run it; steps/s as the ``lockstep``
section measures it, :func:`~joint_space_control.lab.bench.ros.lockstep`) without and then with
the dashboard; then realtime at 1 kHz (the ``realtime`` section's robot and law, quiet, at
the nodes' default thread_priority 50; on-time fraction as that section measures it,
:func:`~joint_space_control.lab.bench.ros.realtime`) without and then with. The dashboard is
started on a free port in the run's ROS domain once the loop is connected, the page opened
(:mod:`~joint_space_control.lab.bench.browser`) and connected with the robot's plots built, and
only then is the plant resumed: the measurement is the loop with the page open and plotting.

During each measurement the CPU time of every process is read from ``/proc/<pid>/stat``
(``utime + stime`` and that of reaped children, over each process's descendants): the
plant, the controller, the dashboard, Chromium (all its processes) and playwright (its
driver and the Python process holding the page), so that a missed goal says where the cost
is. Without chromium or playwright the section says so and measures the dashboard alone.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

from joint_space_control.lab.bench import browser, ros
from joint_space_control.lab.bench.load import cpu_hog
from joint_space_control.processes.processes import ProcessGroup

LOCKSTEP_ROBOT, LOCKSTEP_LAW = "planar_2dof", "pd_gravity"
#: The nodes' default thread_priority (the realtime section's goal rows use it too).
REALTIME_PRIORITY = 50
#: Parameters of the controllers (and the dashboard): as users run them beside sim_bridge.
SIM_TIME = {"use_sim_time": True}
#: What the dashboard must not cost the loop.
STEPS_RATIO_GOAL = 0.95
ON_TIME_DROP_GOAL = 0.1  # percentage points
_TICK = os.sysconf("SC_CLK_TCK")


def free_port(host: str = "127.0.0.1") -> int:
    """A port nothing listens on now (bound to port 0, the kernel's pick, and released)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


def _processes() -> dict[int, tuple[int, str, float]]:
    """Every process: pid → (ppid, comm, CPU seconds of it and its reaped children)."""
    out = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue  # gone meanwhile
        comm = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        # fields[0] is the state (field 3); utime, stime, cutime, cstime are fields 14..17
        cpu = sum(int(x) for x in fields[11:15]) / _TICK
        out[int(entry)] = (int(fields[1]), comm, cpu)
    return out


def _roles(roots: Mapping[str, int], page: int | None) -> dict[str, dict[int, float]]:
    """CPU seconds per role and pid: each root's tree; the page's split into ``chromium``
    and ``playwright`` (its Python process and the driver, node)."""
    procs = _processes()
    children: dict[int, list[int]] = {}
    for pid, (ppid, _comm, _cpu) in procs.items():
        children.setdefault(ppid, []).append(pid)

    def tree(root: int) -> list[int]:
        pids, todo = [], [root]
        while todo:
            pid = todo.pop()
            if pid in procs:
                pids.append(pid)
                todo.extend(children.get(pid, ()))
        return pids

    out: dict[str, dict[int, float]] = {}
    for role, root in roots.items():
        out[role] = {pid: procs[pid][2] for pid in tree(root)}
    if page is not None:
        for pid in tree(page):
            comm = procs[pid][1]
            role = "playwright" if comm.startswith(("python", "node")) else "chromium"
            out.setdefault(role, {})[pid] = procs[pid][2]
    return out


def _wait_listening(port: int, check: Callable[[], None], timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while True:
        check()
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=1.0):
                return
        except OSError:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the dashboard did not serve on port {port}") from None
            time.sleep(0.2)


class Beside:
    """What runs beside one measured loop (a :data:`~joint_space_control.lab.bench.ros.Beside`):
    nothing, the dashboard, or the dashboard with its page open; after the run, the CPU
    seconds of each process over the measurement (``cpu_seconds``) and its wall time."""

    #: Without a page: how long the dashboard gets to find the robot and build its panel.
    SETTLE_S = 3.0

    def __init__(
        self,
        dashboard: bool,
        page: bool,
        log: Callable[[str], None],
        nice: int = 0,
        open_at_start: bool = False,
        hogs: int = 0,
    ) -> None:
        self.dashboard = dashboard
        self.page = page and dashboard
        self.nice = nice
        #: The browser started as the measurement starts (a person opening the page beside
        #: a running loop), instead of the page open and plotting before it.
        self.open_at_start = open_at_start
        #: CPU hogs started with the measurement (stopped with it).
        self.hogs = hogs
        self._load = ExitStack()
        self._url = ""
        self._log = log
        self._browser: browser.OpenPage | None = None
        self._roots: dict[str, int] = {}
        self._before: dict[str, dict[int, float]] = {}
        self._t0 = math.nan
        self.cpu_seconds: dict[str, float] = {}
        self.wall_s = math.nan
        #: With a page: whether it showed the robot's plots before the measurement, and why
        #: not (a loop that leaves the browser no CPU: a measured outcome, not an error).
        self.plotting: bool | None = None
        self.not_plotting = ""

    def __call__(self, group: ProcessGroup) -> Any:
        return self._run(group)

    @contextmanager
    def _run(self, group: ProcessGroup) -> Iterator[Beside]:
        with ExitStack() as stack:
            stack.callback(self._load.close)
            if self.dashboard:
                port = free_port()
                node = group.start("dashboard", {"port": port, **SIM_TIME})
                stack.callback(lambda: (node.stop(), group.nodes.pop(node.name, None)))
                _wait_listening(port, group.check_alive)
                self._url = f"http://127.0.0.1:{port}"
                if self.page and self.open_at_start:
                    stack.callback(lambda: self._browser and self._browser.close())
                elif self.page:
                    self._browser = stack.enter_context(
                        browser.page_open(self._url, nice=self.nice)
                    )
            self._roots = {name: n.proc.pid for name, n in group.nodes.items()}
            try:
                yield self
            finally:
                if not math.isnan(self._t0):
                    self.wall_s = time.monotonic() - self._t0
                    self.page_connected()
                    after = _roles(self._roots, self._browser.pid if self._browser else None)
                    self.cpu_seconds = {
                        role: sum(
                            cpu - self._before.get(role, {}).get(pid, 0.0)
                            for pid, cpu in pids.items()
                        )
                        for role, pids in after.items()
                    }

    def ready(self, check: Callable[[], None]) -> None:
        """Once the loop runs: until the page shows the robot's plots (the dashboard builds
        a robot's panel on its first joint state), or :data:`SETTLE_S` without a page (or
        with ``open_at_start``: the browser starts with the measurement)."""
        if self._browser is not None:
            try:
                self._browser.wait_plotting()
            except browser.PageError as err:
                why = str(err).splitlines()[0]  # playwright's call log follows
                self.plotting, self.not_plotting = False, why
                self._log(f"  {why} (measured all the same: the page open, not plotting)")
            else:
                self.plotting = True
                self._log("  the page is open and plotting")
        elif self.dashboard:
            deadline = time.monotonic() + self.SETTLE_S
            while time.monotonic() < deadline:
                check()
                time.sleep(0.1)

    def start(self) -> None:
        """The measurement starts: the processes' CPU times now (and the browser starts,
        with ``open_at_start``)."""
        self._before = _roles(self._roots, self._browser.pid if self._browser else None)
        self._t0 = time.monotonic()
        if self.hogs:
            self._load.enter_context(cpu_hog(self.hogs))
        if self.page and self.open_at_start:
            self._browser = browser.launch(self._url, nice=self.nice)

    def page_connected(self) -> None:
        """With ``open_at_start``, after the measurement: whether the page connected
        (``plotting`` False and ``not_plotting`` why, when it did not)."""
        if self._browser is not None and self.open_at_start:
            why = self._browser.connected()
            self.plotting, self.not_plotting = not why, why


def _median(values: list[float]) -> float:
    ordered = sorted(v for v in values if not math.isnan(v))
    return ordered[(len(ordered) - 1) // 2] if ordered else math.nan


def side_by_side(
    out: Path,
    pairs: int,
    lockstep_seconds: float,
    realtime_seconds: float,
    realtime_robot: str,
    realtime_law: str,
    log: Callable[[str], None],
    measured: Callable[[str, Callable[[], Any]], Any] = lambda _name, part: part(),
    browser_nice: int = 0,
) -> dict[str, Any]:
    """The section's result: every run, the medians, the paired ratio and difference, and
    the CPU seconds of each process (``measured(name, part)`` runs each part: the bench's
    steal meter). ``browser_nice``: the niceness of the page's browser (0: as a user's runs;
    19: every other process of the machine first)."""
    missing = browser.missing()
    page = missing is None
    if not page:
        log(f"dashboard: no page ({missing}): the dashboard alone is measured, without a page")
    runs: list[dict[str, Any]] = []
    for k in range(max(1, pairs)):
        for kind in ("lockstep", "realtime"):
            for beside in (False, True):
                label = "with" if beside else "without"
                side = Beside(beside, page, log, browser_nice)
                log(f"dashboard pair {k + 1}/{pairs}: {kind} {label} the dashboard")
                workdir = out / "runs" / f"dashboard_{kind}_{k}_{label}"
                if kind == "lockstep":
                    (row,) = measured(
                        f"dashboard_lockstep_{label}",
                        lambda w=workdir, s=side: ros.lockstep(
                            w,
                            LOCKSTEP_ROBOT,
                            (LOCKSTEP_LAW,),
                            lockstep_seconds,
                            log,
                            controller_params=SIM_TIME,
                            beside=s,
                        ),
                    )
                    value = {"steps_per_s": row["steps_per_s"], "steps": row["steps"]}
                else:
                    row = measured(
                        f"dashboard_realtime_{label}",
                        lambda w=workdir, s=side: ros.realtime(
                            w,
                            realtime_robot,
                            realtime_law,
                            realtime_seconds,
                            log,
                            thread_priority=REALTIME_PRIORITY,
                            controller_params=SIM_TIME,
                            beside=s,
                        ),
                    )
                    value = {
                        k: row[k]
                        for k in ("on_time_fraction", "too_late_fraction", "brakes", "policy")
                    } | {"lateness_p99_us": row["lateness"]["p99_us"]}
                runs.append(
                    {
                        "kind": kind,
                        "pair": k,
                        "dashboard": beside,
                        "page": side.page,
                        "plotting": side.plotting,
                        "not_plotting": side.not_plotting,
                        **value,
                        "wall_s": side.wall_s,
                        "cpu_seconds": side.cpu_seconds,
                    }
                )
    return {
        **summarise(runs, page, missing, realtime_robot, realtime_law),
        "browser_nice": browser_nice,
    }


def summarise(
    runs: list[dict[str, Any]],
    page: bool,
    missing: str | None,
    realtime_robot: str,
    realtime_law: str,
) -> dict[str, Any]:
    def pick(kind: str, beside: bool, key: str) -> dict[int, float]:
        return {r["pair"]: r[key] for r in runs if r["kind"] == kind and r["dashboard"] == beside}

    steps = {b: pick("lockstep", b, "steps_per_s") for b in (False, True)}
    on_time = {b: pick("realtime", b, "on_time_fraction") for b in (False, True)}
    ratios = [steps[True][k] / steps[False][k] for k in steps[False] if k in steps[True]]
    drops = [
        100 * (on_time[False][k] - on_time[True][k]) for k in on_time[False] if k in on_time[True]
    ]
    cpu: dict[str, dict[str, dict[str, float]]] = {}
    for kind in ("lockstep", "realtime"):
        for beside in (False, True):
            chosen = [r for r in runs if r["kind"] == kind and r["dashboard"] == beside]
            wall = sum(r["wall_s"] for r in chosen)
            seconds: dict[str, float] = {}
            for r in chosen:
                for role, s in r["cpu_seconds"].items():
                    seconds[role] = seconds.get(role, 0.0) + s
            cpu.setdefault(kind, {})["with" if beside else "without"] = {
                "wall_s": wall,
                **{f"{role}_s": s for role, s in seconds.items()},
            }
    return {
        "page": page,
        "page_missing": missing,
        # with-runs whose page did not show the plots in time: (kind, pair, why)
        "not_plotting": [
            (r["kind"], r["pair"], r["not_plotting"]) for r in runs if r.get("plotting") is False
        ],
        "pairs": len(ratios),
        "lockstep": {
            "robot": LOCKSTEP_ROBOT,
            "law": LOCKSTEP_LAW,
            "use_sim_time": True,
            "without_steps_per_s": _median(list(steps[False].values())),
            "with_steps_per_s": _median(list(steps[True].values())),
            "ratio": _median(ratios),
            "ratio_pairs": ratios,
        },
        "realtime": {
            "robot": realtime_robot,
            "law": realtime_law,
            "thread_priority": REALTIME_PRIORITY,
            "use_sim_time": True,
            "without_on_time_fraction": _median(list(on_time[False].values())),
            "with_on_time_fraction": _median(list(on_time[True].values())),
            "drop_points": _median(drops),
            "drop_points_pairs": drops,
        },
        "cpu_seconds": cpu,
        "runs": runs,
    }


def goals(section: dict[str, Any] | None) -> list[tuple[str, float | None, Callable]]:
    """(goal, measured, met) of the dashboard beside the loop; not measured without a page
    (the goal is about the page open), not met where the page did not show its plots beside
    the loop (the loop with a page it starved is not the loop with the page plotting)."""
    measured = section is not None and section.get("page")
    starved = {kind for kind, _, _ in (section or {}).get("not_plotting", [])}
    return [
        (
            "dashboard with its page open: lockstep steps/s >= 0.95 of without (paired)",
            section["lockstep"]["ratio"] if measured else None,
            lambda v: "lockstep" not in starved and v >= STEPS_RATIO_GOAL,
        ),
        (
            "dashboard with its page open: realtime on-time % drops by <= 0.1 point (paired)",
            section["realtime"]["drop_points"] if measured else None,
            lambda v: "realtime" not in starved and v <= ON_TIME_DROP_GOAL,
        ),
    ]


def format_dashboard(section: dict[str, Any]) -> list[str]:
    """The section's lines of the table."""

    def f(v: float, digits: int = 0) -> str:
        return "-" if v is None or math.isnan(v) else f"{v:,.{digits}f}"

    ls, rt = section["lockstep"], section["realtime"]
    nice = section.get("browser_nice", 0)
    beside = (
        "the dashboard with its page open in headless Chromium (SwiftShader WebGL), plotting"
        + (f", the browser at nice {nice}" if nice else "")
        if section["page"]
        else f"the dashboard WITHOUT a page ({section['page_missing']})"
    )
    lines = [
        f"dashboard beside the loop: without / with {beside}; {section['pairs']} alternating "
        "pairs, medians",
        f"  lockstep {ls['robot']} {ls['law']} (use_sim_time): steps/s "
        f"{f(ls['without_steps_per_s'])} / {f(ls['with_steps_per_s'])}, "
        f"ratio {f(ls['ratio'], 3)} (pairs {' '.join(f(x, 3) for x in ls['ratio_pairs'])}; "
        f"goal >= {STEPS_RATIO_GOAL})",
        f"  realtime 1 kHz {rt['robot']} {rt['law']} (thread_priority {rt['thread_priority']}, "
        f"use_sim_time): on time {f(100 * rt['without_on_time_fraction'], 2)} % / "
        f"{f(100 * rt['with_on_time_fraction'], 2)} %, drop {f(rt['drop_points'], 2)} points "
        f"(pairs {' '.join(f(x, 2) for x in rt['drop_points_pairs'])}; goal <= "
        f"{ON_TIME_DROP_GOAL})",
        *(
            f"  NOT PLOTTING: {kind} pair {pair + 1}: {why}"
            for kind, pair, why in section.get("not_plotting", [])
        ),
        "  CPU seconds over the measurements (% of one core):",
    ]
    for kind in ("lockstep", "realtime"):
        for label in ("without", "with"):
            part = section["cpu_seconds"][kind][label]
            wall = part["wall_s"]
            roles = ", ".join(
                f"{key[:-2]} {s:.1f} ({100 * s / wall:.0f} %)"
                for key, s in part.items()
                if key != "wall_s" and wall > 0
            )
            lines.append(f"    {kind:8s} {label:7s} {wall:5.1f} s wall: {roles}")
    return [*lines, ""]
