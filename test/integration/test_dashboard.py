"""The dashboard as a person sees it: sim_bridge (realtime), a controller and the dashboard
as processes, the page in Debian's Chromium (headless, software WebGL) driven by playwright.

What a person does on the page reaches the nodes only through the standard parameter
services and the documented topics and services, so every check reads the result back from
the nodes themselves (parameter service, ``~/config``, the joint states), not from the page.
The screenshots go to ``JSC_SCREENSHOTS`` when it names a folder (the README's figure is
one of them), else beside the test's logs.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import socket
import subprocess
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from rclpy.parameter import parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.lab.bench.browser import PLOTTING_TEXT
from joint_space_control.ros.messages import REFERENCE_QOS, stamp_to_ns

from .browser import chromium
from .conftest import SETPOINTS
from .test_faults import ROBOT, Rig, rig  # noqa: F401  (the fixture)

pytestmark = [pytest.mark.integration, pytest.mark.realtime, pytest.mark.browser]

CONTROLLER = "/pd_gravity_controller"
#: The loop's rate [Hz], the same on every machine. What the test judges (the page shows the
#: loop and what was sent, a value set on the page is the node's, a refused one is said,
#: pause and resume, the loop survives the dashboard) holds at any rate; at 100 Hz the
#: plant, the controller and the dashboard leave the software-rendered page most of the two
#: cores, so that the page's redraws are what its waits measure.
RATE = 100.0
#: The test's limits, not estimates of a machine's speed: a click, a typed value or a
#: redraw the page has not answered within PAGE_TIMEOUT_MS [ms] is a page a person could not
#: use, and the test fails there; its first build (viser's bundle, loaded in a browser at
#: niceness 19 that draws WebGL in software) has PAGE_LOAD_TIMEOUT_MS [ms].
PAGE_TIMEOUT_MS = 120_000
PAGE_LOAD_TIMEOUT_MS = 180_000
#: The robot counts as drawn on more than this share of the 3D view's pixels (~5,000).
DRAWN_SHARE = 0.005
#: The browser's niceness, as docs/dashboard.md tells users on the loop's machine: Chromium
#: drawing WebGL in software takes most of a core, and at niceness 0 it came before the
#: dashboard (niceness 10), whose robot panel a CI run's page then waited for in vain.
BROWSER_NICE = 19
#: How often [ms] a wait for a redraw looks at the page again, and how long [ms] a robot
#: left unticked is looked at for its pixels to go before it is ticked again (its meshes may
#: not be drawn yet: robot_mask).
REDRAW_POLL_MS = 250
REDRAW_TRY_MS = 5_000
#: Data spanning less than this [rad] counts as spanning this (a joint at rest, drawn in the
#: middle of an axis wider than its data): see axis_faults.
FLAT = 0.01
#: The y axes of the plots on show (one per joint), as uPlot drew them: uPlot writes its
#: tick labels on the canvas, not in the DOM, so they are read from the uPlot instances that
#: viser registers for its own end-to-end tests (window.__viserTestpoints.uplots): an
#: axis's _values are the labels written at its _splits. With them, the axis's range, the
#: smallest and largest value of the series drawn (not those of the series that only widens
#: the axis, drawn 0 px wide), and the time window shown and that of the data.
Y_AXES_JS = """() => Object.values(window.__viserTestpoints?.uplots ?? {})
    .map(({chart}) => chart)
    .filter(chart => chart.root.getBoundingClientRect().height > 0)
    .map(chart => {
        const drawn = chart.data.slice(1).filter((_, k) => {
            const s = chart.series[k + 1];
            return s.show && s.width > 0;
        }).flatMap(column => Array.from(column));
        const t = chart.data[0];
        return {
            title: chart.root.querySelector('.u-title')?.textContent,
            labels: chart.axes[1]._values, ticks: chart.axes[1]._splits,
            low: chart.scales.y.min, high: chart.scales.y.max,
            data: [Math.min(...drawn), Math.max(...drawn)],
            window: [chart.scales.x.min, chart.scales.x.max], times: [t[0], t[t.length - 1]],
        };
    })"""


def what_the_loop_says(rig: Rig, page, references: list, configs: list[str]) -> str:  # noqa: F811
    """What the loop and the page say when a wait of the page test timed out (for CI's log):
    the last position, the references sent, the controller's configurations (omega_n) and
    status, the plant's status, the nodes' last log lines, the page."""
    q = rig.probe.recording.positions
    omega_n = [json.loads(c).get("omega_n") for c in configs]
    lines = [
        f"last q {q[-1] if q else None} at {rig.probe.latest_time():.3f} s",
        f"omega_n of the controller's ~/config seen: {omega_n}",
    ]
    for msg in references:
        points = [(stamp_to_ns(p.time_from_start) * 1e-9, list(p.positions)) for p in msg.points]
        lines.append(
            f"reference stamped {stamp_to_ns(msg.header.stamp) * 1e-9:.9f} s: "
            f"{len(points)} points, last {points[-1] if points else None}"
        )
    for name in (f"{CONTROLLER.lstrip('/')}: control loop", "sim_bridge: control loop"):
        try:
            status = rig.probe.wait_for_diagnostics([name], timeout=5.0)
            lines.append(f"{name}: {status[name]}")
        except TimeoutError:
            lines.append(f"{name}: no status in 5 s")
    for name, node in rig.group.nodes.items():
        lines.append(f"--- {name} log (end):\n" + "\n".join(node.log().splitlines()[-15:]))
    lines.append("--- page:\n" + page_state(page)[-2000:])
    return "\n".join(lines)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def screenshot_dir(tmp_path: Path) -> Path:
    folder = Path(os.environ.get("JSC_SCREENSHOTS", tmp_path / "screenshots"))
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def wait_for_page(rig: Rig, url: str) -> None:  # noqa: F811
    def answers() -> bool:
        try:
            urllib.request.urlopen(url, timeout=0.5).close()
            return True
        except OSError:
            return False

    rig.probe.spin_until(answers, 60.0, f"the dashboard on {url}", rig.group.check_alive)


def page_state(page) -> str:
    """What the page and the machine were doing, for a failure's message: the page's text,
    its canvases and the busiest processes (a starved page or dashboard shows here)."""
    text = page.evaluate("document.body ? document.body.innerText : ''")
    canvases = page.evaluate("document.querySelectorAll('canvas').length")
    busiest = subprocess.run(
        ["ps", "-eo", "pid,ni,pcpu,etime,comm", "--sort=-pcpu"],
        capture_output=True,
        text=True,
        check=False,
    ).stdout.splitlines()[:8]
    return (
        f"{canvases} canvases, text {text[:600]!r}; load {os.getloadavg()}; "
        f"busiest processes: {busiest}"
    )


def open_page(browser, url: str):
    page = browser.new_page(viewport={"width": 1500, "height": 950})
    page.set_default_timeout(PAGE_TIMEOUT_MS)
    outside = []
    page.on(
        "request",
        lambda r: (
            outside.append(r.url)
            if not r.url.startswith(
                ("http://127.0.0.1", "http://localhost", "ws://", "data:", "blob:")
            )
            else None
        ),
    )
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    start = time.monotonic()
    page.goto(url, timeout=PAGE_LOAD_TIMEOUT_MS)
    try:
        page.get_by_text(PLOTTING_TEXT, exact=True).first.wait_for(timeout=PAGE_LOAD_TIMEOUT_MS)
    except PlaywrightTimeout:
        raise AssertionError(
            f"no robot's plots on the page after {time.monotonic() - start:.0f} s: "
            f"{page_state(page)}"
        ) from None
    print(f"the page was built in {time.monotonic() - start:.1f} s")
    # the "software WebGL" notice of headless Chromium covers the scene's corner
    page.evaluate(
        "document.querySelectorAll('.mantine-Notification-closeButton').forEach(b => b.click())"
    )
    return page, outside


def number_box(page, label: str):
    """The number input of the control labelled ``label`` (a slider's box or a number)."""
    label = page.get_by_text(label, exact=True)
    row = label.locator("xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]")
    return row.locator("input:not([type=hidden])").last


def type_value(page, label: str, value: float) -> None:
    box = number_box(page, label)
    box.fill(f"{value}")
    box.press("Enter")


def scene_pixels(page) -> np.ndarray:
    """The 3D view (left of the control panel) as an RGB array."""
    from PIL import Image

    box = page.evaluate(
        """() => {
            const r = [...document.querySelectorAll('canvas')].map(c => c.getBoundingClientRect())
                .sort((a, b) => b.width * b.height - a.width * a.height)[0];
            return {x: r.x, y: r.y, width: r.width, height: r.height};
        }"""
    )  # the largest canvas: the 3D view
    png = page.screenshot(clip=box)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)


def plots_box(page) -> dict:
    """The box around the plots on show (the Position tab's, one per joint)."""
    plots = page.locator(".uplot:visible")
    first, last = plots.first.bounding_box(), plots.last.bounding_box()
    bottom = last["y"] + last["height"]
    return {
        "x": first["x"],
        "y": first["y"],
        "width": first["width"],
        "height": bottom - first["y"],
    }


def region(page, selector: str) -> bytes:
    """A PNG of the first element matching ``selector``, cut from a page screenshot (an
    element screenshot waits for a quiet page, which a live 3D view never is)."""
    box = page.locator(selector).first.bounding_box()
    return page.screenshot(clip=box)


def redrawn(page, take, changed, what: str, timeout_ms: float = PAGE_TIMEOUT_MS):
    """What ``take()`` gives once ``changed(it)`` holds: a redraw is waited for, not slept
    for. An AssertionError after ``timeout_ms`` (the page did not show it)."""
    deadline = time.monotonic() + timeout_ms / 1000
    while True:
        found = take()
        if changed(found):
            return found
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not on the page after {timeout_ms / 1000:g} s")
        page.wait_for_timeout(REDRAW_POLL_MS)


def robot_mask(page, title: str, least: float = DRAWN_SHARE) -> np.ndarray:
    """The pixels of the 3D view that the robot ``title`` draws: those that change when a
    person unticks "show <title> in 3D" and come back when it is ticked again. Each redraw
    is waited for; until the robot draws more than ``least`` of the view (its meshes still
    loading), the person unticks and ticks it again, for :data:`PAGE_TIMEOUT_MS` at most."""
    page.get_by_role("tab", name=title).click()
    box = page.get_by_label(f"show {title} in 3D")
    deadline = time.monotonic() + PAGE_TIMEOUT_MS / 1000
    while True:
        shown = scene_pixels(page)

        def differs(pixels: np.ndarray, shown=shown) -> np.ndarray:
            return np.abs(pixels - shown).max(axis=2) > 40

        box.click()
        hidden = scene_pixels(page)
        with contextlib.suppress(AssertionError):  # not drawn yet: untick and tick again
            hidden = redrawn(
                page, lambda: scene_pixels(page), lambda p: np.mean(differs(p)) > least,
                f"{title} hidden", REDRAW_TRY_MS,
            )  # fmt: skip
        box.click()
        again = redrawn(
            page, lambda: scene_pixels(page),
            lambda p, h=hidden: np.mean(differs(p) & differs(h)) <= np.mean(differs(h)) / 2,
            f"{title} shown again",
        )  # fmt: skip
        mask = differs(hidden) & ~differs(again)
        if np.mean(mask) > least or time.monotonic() > deadline:
            return mask


def axis_faults(axis: dict) -> list[str]:
    """What is wrong with a plot's y axis (:data:`Y_AXES_JS`): its labels are not 2 or more
    distinct numbers, each the value ticked; the data or the ticks are not within the axis;
    the ticks do not span the data (to a tick spacing); they are not at the data's scale
    (spaced more than twice the data's span, or the axis more than 3 times as wide; a span
    below :data:`FLAT` counts as that); or the time window shown is not the data's (a blank
    plot)."""
    labels, ticks = axis["labels"] or [], axis["ticks"] or []
    try:
        values = [float(label.replace(",", "")) for label in labels]
    except ValueError:
        return [f"labels not numbers: {labels}"]
    if len(set(values)) < 2 or len(set(values)) != len(values) or len(ticks) != len(values):
        return [f"labels not 2 or more distinct numbers, one per tick: {labels} at {ticks}"]
    step = min(abs(b - a) for a, b in zip(values, values[1:], strict=False))
    lo, hi = axis["data"]
    span = max(hi - lo, FLAT)
    faults = []
    if values != pytest.approx(ticks, abs=step / 10):
        faults.append(f"labels {labels} do not say the values ticked, {ticks}")
    if not axis["low"] <= lo <= hi <= axis["high"]:
        faults.append(f"data [{lo}, {hi}] not within the axis [{axis['low']}, {axis['high']}]")
    if not (axis["low"] - step / 10 <= min(values) and max(values) <= axis["high"] + step / 10):
        faults.append(f"ticks {values} beyond the axis [{axis['low']}, {axis['high']}]")
    if min(values) > lo + step or max(values) < hi - step:
        faults.append(f"ticks {values} do not span the data [{lo}, {hi}]")
    (start, end), (first, last) = axis["window"], axis["times"]
    slack = 0.1 * (last - first)
    if start is None or end is None or start > first + slack or end < last - slack:
        faults.append(f"time window [{start}, {end}] not that of the data, [{first}, {last}]")
    if step > 2 * span or axis["high"] - axis["low"] > 3 * span:
        faults.append(
            f"ticks every {step:g} on [{axis['low']}, {axis['high']}] for data [{lo}, {hi}]"
        )
    return faults


def ticks_at_the_data_scale(page, what: str) -> list[dict]:
    """The y axes of the plots on show once each is ticked at its data's scale
    (:func:`axis_faults`), waited for up to :data:`REDRAW_TRY_MS` (a redraw under way); an
    AssertionError saying what is wrong otherwise."""
    deadline = time.monotonic() + REDRAW_TRY_MS / 1000
    while True:
        axes = page.evaluate(Y_AXES_JS)
        faults = {a["title"]: axis_faults(a) for a in axes}
        if axes and not any(faults.values()):
            return axes
        if time.monotonic() > deadline:
            detail = "; ".join(f"{t}: {', '.join(f)}" for t, f in faults.items() if f)
            raise AssertionError(f"{what}: {detail or 'no plot on show'} ({axes})")
        page.wait_for_timeout(REDRAW_POLL_MS)


_clients: dict[tuple[int, str], AsyncParameterClient] = {}


def get_parameter(rig: Rig, node: str, name: str):  # noqa: F811
    """``name`` as ``node``'s parameter service answers (one client per node and rig)."""
    key = (id(rig), node)
    if key not in _clients:
        _clients[key] = AsyncParameterClient(rig.probe.node, node)
    future = _clients[key].get_parameters([name])
    rig.probe.spin_until(future.done, 30.0, f"{node} get_parameters", rig.group.check_alive)
    return parameter_value_to_python(future.result().values[0])


def stopped_time(rig: Rig, timeout: float = 30.0) -> float:  # noqa: F811
    """The simulated time once the plant has stopped it, as the plant says in its own
    diagnostics (published on the steady clock every second, paused or not): the same
    ``sim_time_s`` in statuses 2.5 s apart. The probe's joint states are no witness of
    that: they queue behind a loaded machine, so a second without one proves nothing and
    a burst of old ones may arrive after the pause (a CI run saw both)."""
    status = "sim_bridge: control loop"
    deadline = time.monotonic() + timeout
    last = float(rig.diagnostics("sim_bridge", lambda s: True)["sim_time_s"])
    while time.monotonic() < deadline:
        rig.probe.spin_for(2.5)
        now = float(rig.probe.wait_for_diagnostics([status])[status]["sim_time_s"])
        if now == last:
            return now
        last = now
    raise AssertionError(f"simulated time still advancing after {timeout:g} s: {last:.3f} s")


def tune_and_move(
    rig: Rig,  # noqa: F811
    page,
    configs: list[str],
    references: list,
    shots: Path,
) -> None:
    """The page test's steps, once the page is open: the robot drawn and the plots moving,
    omega_n set from the page changing K_P, a refused value, a set-point sent as typed and
    reached, pause and resume."""
    page.get_by_text(f"{CONTROLLER}:").first.wait_for()  # the controller is found

    # the robot is drawn: ~5,000 pixels that vanish when it is hidden and come back when
    # shown (robot_mask waits for each redraw), and the plots advance
    share = float(np.mean(robot_mask(page, "robot")))
    print(f"robot drawn on {100 * share:.1f} % of the 3D view")
    assert share > DRAWN_SHARE, share
    before = region(page, ".uplot canvas")
    redrawn(
        page, lambda: region(page, ".uplot canvas"), lambda now: now != before,
        "the position plot moving",
    )  # fmt: skip
    # the joints at rest, within a fraction of a milliradian: each position plot ticked in
    # distinct numbers (uPlot's own axis: "-0, -0, 0", or for a joint at rest within 1e-9
    # rad of a round value, no tick and no line)
    ticks_at_the_data_scale(page, "the position plots at rest")

    # a parameter set in the page is the node's parameter, and changes the gains in force
    rig.probe.spin_until(lambda: bool(configs), 10.0, f"{CONTROLLER}/config")
    kp_before = np.array(json.loads(configs[-1])["kp"])
    page.get_by_text(f"Parameters of {CONTROLLER}").click()
    type_value(page, "omega_n[joint1]", 5.0)
    type_value(page, "omega_n[joint2]", 5.0)
    rig.probe.spin_until(
        lambda: list(get_parameter(rig, CONTROLLER, "omega_n")) == [5.0, 5.0],
        20.0,
        "omega_n = [5, 5] on the controller",
    )
    rig.probe.spin_until(
        lambda: json.loads(configs[-1]).get("omega_n") == [5.0, 5.0],
        30.0,
        "the gains designed from omega_n = [5, 5] in ~/config",
    )
    kp_after = np.array(json.loads(configs[-1])["kp"])
    ratio = kp_after / kp_before
    print(f"K_P {kp_before} -> {kp_after} (x{ratio})")
    assert np.all((ratio > 0.2) & (ratio < 0.3)), ratio  # K_P ∝ ω_n²: ×1/4 at the same q

    # a value the node refuses: its reason on the page, the value in force kept
    type_value(page, "state_timeout", 0.0)
    page.get_by_text("state_timeout rejected").first.wait_for()
    assert get_parameter(rig, CONTROLLER, "state_timeout") == pytest.approx(1.0)

    # set-points from the page move the arm there
    target = SETPOINTS[ROBOT]
    type_value(page, "move duration [s]", 1.0)  # a minimum-jerk move, within the limits
    type_value(page, "q_d joint1 [rad]", target[0])
    type_value(page, "q_d joint2 [rad]", target[1])
    # what a person sees before sending: the values typed, still in their boxes
    shown = [float(number_box(page, f"q_d joint{k} [rad]").input_value()) for k in (1, 2)]
    assert shown == pytest.approx(target), (shown, target)
    sent = len(references)
    page.get_by_role("button", name="Send set-point").click()
    rig.probe.spin_until(lambda: len(references) > sent, 30.0, "the page's set-point sent")
    assert list(references[-1].points[-1].positions) == pytest.approx(target), references[-1]

    def arrived() -> bool:
        q = rig.probe.recording.positions
        return bool(q) and np.max(np.abs(np.array(q[-1]) - target)) < 1e-3

    rig.probe.spin_until(arrived, 30.0, "the arm at the page's set-point", rig.group.check_alive)
    page.wait_for_timeout(2500)
    page.screenshot(path=str(shots / "dashboard.png"))
    # joint2 on its way from 0 to -0.3 rad in the window (or the end of it): its plot ticked
    # like -0.3, -0.2, -0.1, 0; the plots' screenshot beside the page's
    axes = ticks_at_the_data_scale(page, "the position plots after the move")
    print("position plots' y ticks:", {a["title"]: a["labels"] for a in axes})
    page.locator(".uplot:visible").first.scroll_into_view_if_needed()
    page.screenshot(path=str(shots / "dashboard_plots.png"), clip=plots_box(page))

    # pause stops simulated time, resume runs it again
    page.get_by_role("button", name="pause").click()
    paused_at = stopped_time(rig)
    # the probe takes the states still on their way up to the plant's last (to the
    # diagnostics' 4 decimals of sim_time_s, and a state or a few that may not have
    # gone out: a loaded machine queues them, and a probe starved of CPU beside the
    # browser was once 8.5 s of states behind), then none later comes for 1.5 s
    lag = max(0.0105, 2.5 / RATE + 0.0005)  # 2.5 periods of the plant's states, 10 ms at least
    rig.probe.spin_until(
        lambda: rig.probe.latest_time() >= paused_at - lag,
        60.0,
        f"the probe to take the states up to the pause at {paused_at:.4f} s",
        rig.group.check_alive,
    )
    rig.probe.spin_for(1.5)
    last = rig.probe.latest_time()
    assert paused_at - lag <= last <= paused_at + 1e-9, (last, paused_at)
    page.get_by_role("button", name="resume").click()
    rig.probe.spin_until(
        lambda: rig.probe.latest_time() > paused_at + 0.5, 10.0, "time running again"
    )


@pytest.mark.long  # minutes of a realtime loop beside the page: make test-long
@pytest.mark.timeout(900)  # the page's limits (PAGE_LOAD_TIMEOUT_MS, PAGE_TIMEOUT_MS) and more
def test_the_page_shows_and_tunes_the_loop_and_the_loop_survives_it(rig: Rig, tmp_path):  # noqa: F811
    """The loop at :data:`RATE`: the page shows the robot drawn and the plots moving, a
    parameter set on the page is the node's and changes the gains in force, a refused value
    is said and the old one kept, a set-point sent from the page is reached, pause stops
    simulated time and resume runs it again; then the loop runs on with the dashboard hung,
    then killed."""
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    rig.group.start(
        "sim_bridge",
        {"robot": ROBOT, "mode": "realtime", "command_timeout": 2.0, "publish_rate": RATE},
    )
    rig.group.start(
        "pd_gravity_controller",
        # state_timeout 1 s: Chromium drawing WebGL in software takes most of a core here,
        # and the controller's joint states then miss the default 0.1 s now and then (the
        # controller stops and restarts holding where it is, dropping the set-point sent);
        # measured by jsc bench --sections dashboard, not hidden: docs/dashboard.md
        {
            "robot": ROBOT,
            "use_sim_time": True,
            "omega_n": 10.0,
            "zeta": 1.0,
            "state_timeout": 1.0,
            "rate": RATE,
        },
    )
    rig.group.start("dashboard", {"port": port})
    configs: list[dict] = []
    rig.probe.node.create_subscription(
        String,
        f"{CONTROLLER}/config",
        lambda m: configs.append(m.data),
        QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
    )
    references: list = []  # what the page sends, for a failure's message
    rig.probe.node.create_subscription(
        JointTrajectory, "reference", references.append, REFERENCE_QOS
    )
    wait_for_page(rig, url)
    shots = screenshot_dir(tmp_path)
    # the probe spins in a thread of its own while the browser is driven: left seconds
    # behind the plant's and the controller's topics it can stall for good
    # (test_probe_catches_up.py)
    with rig.probe.spinning_in_background(), chromium(nice=BROWSER_NICE) as browser:
        page, outside = open_page(browser, url)
        try:
            tune_and_move(rig, page, configs, references, shots)
        except TimeoutError as err:
            report = what_the_loop_says(rig, page, references, configs)
            raise AssertionError(f"{err}\n{report}") from None
        assert outside == [], outside

    # the loop does not depend on the dashboard: hung, then killed, it runs on
    dashboard = rig.group.nodes["dashboard"]
    for how in (signal.SIGSTOP, signal.SIGKILL):
        start = rig.probe.latest_time()
        dashboard.signal(how)
        rig.probe.spin_for(2.0)
        status = rig.diagnostics("sim_bridge", lambda s: True)
        assert rig.probe.latest_time() > start + 1.0
        assert status["owner"] == CONTROLLER and not status["braking"], status
    dashboard.signal(signal.SIGCONT)
    rig.group.nodes.pop("dashboard").stop()


@pytest.mark.long  # ~50 s of a realtime loop beside a page (make test: within 10 minutes)
@pytest.mark.timeout(900)
def test_two_robots_in_one_world_are_both_drawn(rig: Rig, tmp_path):  # noqa: F811
    import yaml

    from joint_space_control.paths import config_file

    port = free_port()
    url = f"http://127.0.0.1:{port}"
    world = yaml.safe_load(config_file("two_robots.yaml").read_text())
    sim_params = next(iter(world.values()))["ros__parameters"]
    rig.group.start("sim_bridge", sim_params)
    rig.group.start("dashboard", {"port": port})
    wait_for_page(rig, url)
    with chromium(nice=BROWSER_NICE) as browser:
        page, outside = open_page(browser, url)
        for robot in sim_params["robots"]:
            page.get_by_role("tab", name=robot).wait_for()
        page.wait_for_timeout(4000)
        page.screenshot(path=str(screenshot_dir(tmp_path) / "dashboard_two_robots.png"))
        masks = {robot: robot_mask(page, robot, 0.0005) for robot in sim_params["robots"]}
        shares = {robot: float(np.mean(m)) for robot, m in masks.items()}
        overlap = float(np.mean(masks["iiwa"] & masks["arm"]))
        print(f"drawn: {shares}, overlap {overlap:.4f}")
        # each robot draws pixels of its own (> ~500 of the ~10⁶): the iiwa is small beside
        # the 2 m arm, with both in view
        assert min(shares.values()) > 0.0005, shares
        assert overlap < 0.2 * min(shares.values()), overlap
        assert outside == [], outside
