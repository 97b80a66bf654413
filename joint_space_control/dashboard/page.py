"""The dashboard's web page, built with viser: the robots in 3D, live plots, controls.

No ROS here: the page draws what it is given (:class:`RobotPanel` methods, called by the
node from its own thread) and hands what a person does to the :class:`Actions` it was
built with. viser serves its client from the files inside its wheel
(:func:`client_is_bundled`), so the page needs no internet and nothing is built or fetched
at run time.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from joint_space_control.dashboard.controls import Control
from joint_space_control.dashboard.series import Y_INCREMENTS, decimate, spread

#: Colours of the plotted signals (uPlot strokes).
COLOURS = {
    "q": "#1f77b4",
    "q_d": "#ff7f0e",
    "error": "#d62728",
    "tau": "#111111",
    "tau_feedback": "#2ca02c",
    "tau_model": "#9467bd",
    "tau_gravity": "#8c564b",
    "limit": "#d62728",
}


def client_is_bundled() -> Path:
    """The folder of viser's built web client; a ``RuntimeError`` when the installed viser
    has none (it would then try to build one with Node.js at start)."""
    import viser

    build = Path(viser.__file__).resolve().parent / "client" / "build"
    if not (build / "index.html").is_file():
        raise RuntimeError(
            f"viser's web client is missing ({build}/index.html): reinstall viser from its "
            "wheel (the dashboard never builds or downloads a client)"
        )
    return build


def never_build_client() -> None:
    """Make viser's start-up check only that its bundled client is there: an editable or
    odd install of viser would otherwise run npm to build one, which needs the internet."""
    from viser import _client_autobuild

    def ensure() -> None:
        client_is_bundled()

    _client_autobuild.ensure_client_is_built = ensure


@dataclass
class Actions:
    """What the page can ask for; each returns None on success or the reason it failed."""

    set_parameter: Callable[[str, str, Any], str | None]
    send_setpoint: Callable[[str, Sequence[float], float], str | None]
    send_sinusoid: Callable[[str, Sequence[float], Sequence[float], float, float], str | None]
    plant: Callable[[str], str | None]  # "pause" | "resume" | "reset"
    push: Callable[[str, str, Sequence[float], float], str | None]


@dataclass
class RobotInfo:
    """What a robot panel is built from."""

    key: str  # the robot's namespace ("" for one robot in the root namespace)
    title: str
    joints: tuple[str, ...]
    urdf_path: Path | None
    links: tuple[str, ...] = ()
    base_position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    position_limits: tuple[tuple[float, float], ...] = ()
    effort_limits: tuple[float, ...] = ()
    controllers: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())


def base_rotation(rpy: Sequence[float]) -> Any:
    """The base's orientation from roll, pitch, yaw (fixed axes x, y, z, as URDF and
    ``base_rpy``), as viser's SO3."""
    from viser.transforms import SO3

    return SO3.from_rpy_radians(*(float(a) for a in rpy))


#: viser's default vertical field of view [rad].
FOV = math.radians(50.0)


def frame_camera(boxes: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Camera (position, look_at) from the front-right and a little above (z up), looking at
    the centre of every box (lower, upper corners [m]), as close as it can be with every
    corner within the vertical field of view (the horizontal one is wider on a landscape
    view)."""
    lower = np.min([b[0] for b in boxes], axis=0)
    upper = np.max([b[1] for b in boxes], axis=0)
    centre = 0.5 * (lower + upper)
    direction = np.array([0.45, -1.5, 0.75])
    direction /= np.linalg.norm(direction)
    corners = [
        np.array([x, y, z]) - centre
        for lo, hi in boxes
        for x in (lo[0], hi[0])
        for y in (lo[1], hi[1])
        for z in (lo[2], hi[2])
    ]
    # a corner v is in view from centre + d·w when |v − (v·w)w| ≤ (d − v·w) tan(FOV/2)
    need = [
        v @ direction + np.linalg.norm(v - (v @ direction) * direction) / math.tan(FOV / 2)
        for v in corners
    ]
    distance = max(max(need), 0.5)
    return centre + distance * direction, centre


class ParameterPanel:
    """The controls of one node's parameters, built from their descriptors."""

    def __init__(
        self, gui: Any, node: str, controls: Sequence[Control], values: dict, actions: Actions
    ) -> None:
        self.node = node
        self._controls = {c.name: c for c in controls}
        self._values = dict(values)
        self._handles: dict[str, list[Any]] = {}
        self._actions = actions
        self._gui = gui
        self.message = gui.add_markdown(" ")
        for control in controls:
            self._handles[control.name] = self._add(control, values[control.name])

    # -- building ----------------------------------------------------------------------
    def _add(self, control: Control, value: Any) -> list[Any]:
        gui = self._gui
        hint = control.hint or None
        if control.kind == "shown":
            text = _short(value)
            handle = gui.add_text(control.label, initial_value=text, disabled=True, hint=hint)
            return [handle]
        if control.kind == "checkbox":
            handles = [gui.add_checkbox(control.label, initial_value=bool(value), hint=hint)]
        elif control.kind == "dropdown":
            handles = [
                gui.add_dropdown(control.label, control.options, initial_value=value, hint=hint)
            ]
        elif control.kind == "text":
            handles = [gui.add_text(control.label, initial_value=str(value), hint=hint)]
        else:
            items = control.element_values(value)
            labels = [f"{control.label}[{e}]" for e in control.elements] or [control.label]
            handles = [
                self._number(control, label, v, hint)
                for label, v in zip(labels, items, strict=True)
            ]
        for handle in handles:
            handle.on_update(lambda event, c=control: self._changed(c, event))
        return handles

    def _number(self, control: Control, label: str, value: float, hint: str | None) -> Any:
        step = control.ui_step()
        if control.kind == "slider":
            lo, hi = control.minimum, control.maximum
            v = min(max(float(value), lo), hi)
            return self._gui.add_slider(
                label, min=lo, max=hi, step=step, initial_value=v, hint=hint
            )
        return self._gui.add_number(label, initial_value=float(value), step=step, hint=hint)

    # -- changes -----------------------------------------------------------------------
    def _changed(self, control: Control, event: Any) -> None:
        if event.client is None:  # set by the node (a value in force), not by a person
            return
        handles = self._handles[control.name]
        items = [h.value for h in handles]
        value = control.parameter_value(items)
        reason = self._actions.set_parameter(self.node, control.name, value)
        if reason is None:
            self.message.content = f"`{control.name}` = {_short(value)}"
            return
        self.message.content = f"**{control.name} rejected**: {reason}"
        event.client.add_notification(
            f"{self.node}: {control.name} rejected", reason, auto_close_seconds=8.0, color="red"
        )
        self.show(control.name, self._values[control.name])  # back to the value in force

    def show(self, name: str, value: Any) -> None:
        """The value in force of ``name`` (a change seen on /parameter_events)."""
        self._values[name] = value
        control = self._controls.get(name)
        if control is None:
            return
        handles = self._handles[name]
        if control.kind == "shown":
            handles[0].value = _short(value)
            return
        if control.kind in ("slider", "number"):
            items = control.element_values(value)
            if len(items) != len(handles):
                return
            for handle, item in zip(handles, items, strict=True):
                v = float(item)
                if control.kind == "slider":
                    v = min(max(v, control.minimum), control.maximum)
                handle.value = v
            return
        handles[0].value = bool(value) if control.kind == "checkbox" else value

    def value(self, name: str) -> Any:
        return self._values.get(name)


def _short(value: Any, limit: int = 60) -> str:
    if isinstance(value, float):
        text = f"{value:.6g}"
    elif isinstance(value, list | tuple):
        text = "[" + ", ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in value) + "]"
    else:
        text = str(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


#: Smallest joint motion [rad] redrawn in 3D (a tenth of a milliradian).
MOVED = 1e-4

#: The plots of a robot, one per joint each: (title, signals drawn, unit).
PLOTS = (
    ("Position", ("q", "q_d"), "rad"),
    ("Error", ("error",), "rad"),
    ("Torque", ("tau", "tau_feedback", "tau_model", "tau_gravity"), "N·m"),
)


#: The plots' options: x in seconds (not dates); the y axis ticked every 1, 2 or 5 × 10ⁿ, no
#: finer than the 3 decimals uPlot labels ticks with, 64 px wide (room for "-0.206"); the
#: padding viser would use. Never changed once sent: new options make viser build the chart
#: anew, and a chart built anew while its data streams in can keep a time window that the
#: data has left (a blank plot). viser rebuilt it at every change of the panel's width too
#: (a scroll bar coming or going) unless the padding is given: its default is a new array at
#: every render, which its wrapper of uPlot takes for new options.
PLOT_SCALES = {"x": {"time": False}}
PLOT_AXES = ({}, {"size": 64, "incrs": Y_INCREMENTS})
PLOT_PADDING = (0, 24, 0, 0)
#: The last series of every plot: not drawn (no stroke, no points), its values widen the
#: data the y axis is ranged on to what the axis can label (:func:`spread`). Labelled in
#: the legend as what it is (uPlot would call an unlabelled series "Value").
SPREAD = {"label": "(axis)", "stroke": "rgba(0,0,0,0)", "width": 0, "points": {"show": False}}


class RobotPanel:
    """One robot: its 3D model, its plots, its reference and push controls, and the
    parameter panels of the nodes that serve it."""

    def __init__(
        self, server: Any, tab: Any, info: RobotInfo, actions: Actions, budget: int
    ) -> None:
        self.info = info
        self._server = server
        self._tab = tab
        self._actions = actions
        self._budget = budget
        self.parameters: dict[str, ParameterPanel] = {}
        root = f"/robots/{info.key.strip('/') or 'robot'}"
        server.scene.add_frame(
            root,
            position=info.base_position,
            wxyz=base_rotation(info.base_rpy).wxyz,
            show_axes=False,
        )
        self._urdf = None
        self._cfg_index: dict[str, int] = {}
        self.box: tuple[np.ndarray, np.ndarray] | None = None
        if info.urdf_path is not None:
            self._load_urdf(root, info)
        with tab:
            self.status = server.gui.add_markdown("waiting for the loop's diagnostics …")
            if info.notes:  # what could not be shown (no 3D model), said where it is missing
                server.gui.add_markdown("\n\n".join(info.notes))
            if self._urdf is not None:
                shown = server.gui.add_checkbox(f"show {info.title} in 3D", initial_value=True)
                shown.on_update(lambda _event: setattr(self._urdf, "show_visual", shown.value))
            self._plots = self._add_plots()
            self._add_push()
        self.has_reference = False
        if info.controllers:
            self.add_reference()

    # -- 3D ----------------------------------------------------------------------------
    def _load_urdf(self, root: str, info: RobotInfo) -> None:
        import yourdfpy
        from viser.extras import ViserUrdf

        urdf = yourdfpy.URDF.load(str(info.urdf_path), load_meshes=True, build_scene_graph=True)
        coloured = any(v.material is not None for link in urdf.robot.links for v in link.visuals)
        # a description without materials would be drawn white on the page's white
        colour = None if coloured else (0.55, 0.62, 0.72)
        self._urdf = ViserUrdf(self._server, urdf, root_node_name=root, mesh_color_override=colour)
        if not self.info.links:
            self.info.links = tuple(link.name for link in urdf.robot.links)
        joints = [urdf.joint_map.get(name) for name in self.info.joints]
        limits = [j.limit if j is not None else None for j in joints]
        if not self.info.effort_limits:  # no controller's ~/config: the URDF's
            self.info.effort_limits = tuple(
                float(x.effort) if x is not None and x.effort else math.nan for x in limits
            )
        if not self.info.position_limits:
            self.info.position_limits = tuple(
                (float(x.lower), float(x.upper))
                if x is not None and x.lower is not None and x.upper is not None
                else (-math.pi, math.pi)
                for x in limits
            )
        names = self._urdf.get_actuated_joint_names()
        self._cfg_index = {name: k for k, name in enumerate(names)}
        self._cfg = np.zeros(len(names))
        self._urdf.update_cfg(self._cfg)
        if urdf.scene is None or urdf.scene.is_empty:
            self.info.notes = (
                *self.info.notes,
                "nothing to draw: the description has no visual geometry that could be loaded",
            )
        else:
            lo, hi = (np.asarray(b, dtype=float) for b in urdf.scene.bounds)
            corners = np.array(
                [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
            )
            rot = base_rotation(info.base_rpy).as_matrix()
            world = corners @ rot.T + np.asarray(info.base_position)
            self.box = (world.min(axis=0), world.max(axis=0))

    def show_configuration(self, positions: np.ndarray) -> None:
        """Move the 3D robot to the joint ``positions`` (the robot's joint order)."""
        if self._urdf is None:
            return
        cfg = self._cfg.copy()
        for name, q in zip(self.info.joints, positions, strict=True):
            k = self._cfg_index.get(name)
            if k is not None and math.isfinite(q):
                cfg[k] = q
        if np.max(np.abs(cfg - self._cfg), initial=0.0) < MOVED:
            return  # nothing a person could see moved: no new frame for the browser to draw
        self._cfg = cfg
        self._urdf.update_cfg(cfg)

    # -- plots -------------------------------------------------------------------------
    def _add_plots(self) -> dict[str, list[Any]]:
        gui = self._server.gui
        plots: dict[str, list[Any]] = {}
        limits = list(self.info.effort_limits) or [math.nan] * len(self.info.joints)
        with gui.add_folder("Plots"):
            tabs = gui.add_tab_group()
            for title, signals, unit in PLOTS:
                with tabs.add_tab(title):
                    handles = []
                    for j, joint in enumerate(self.info.joints):
                        series = [{"label": "t [s]"}]
                        series += [
                            {"label": s, "stroke": COLOURS[s], "width": 1.5} for s in signals
                        ]
                        if title == "Torque":
                            series += [
                                {
                                    "label": f"±limit {limits[j]:g}",
                                    "stroke": COLOURS["limit"],
                                    "dash": [6, 4],
                                    "width": 1,
                                },
                                {
                                    "label": "",
                                    "stroke": COLOURS["limit"],
                                    "dash": [6, 4],
                                    "width": 1,
                                },
                            ]
                        series.append(dict(SPREAD))
                        data = [np.zeros(2) for _ in series[:-1]]
                        data.append(spread(data[1:], 2))
                        handles.append(
                            gui.add_uplot(
                                tuple(data),
                                tuple(series),
                                title=f"{joint} [{unit}]",
                                scales=PLOT_SCALES,
                                axes=PLOT_AXES,
                                padding=PLOT_PADDING,
                                aspect=2.2,
                            )
                        )
                    plots[title] = handles
        return plots

    def show_signals(self, t: np.ndarray, signals: dict[str, np.ndarray]) -> None:
        """Plot the window: ``t`` [s] and, per signal, a (samples × joints) array. A signal
        not given (no controller: no q_d) or a limit not known is hidden, not sent as NaN
        (uPlot would take NaN for a value and lose its axis range). The last series widens
        the data the y axis is ranged on to at least ``LEAST_SPAN`` (:func:`spread`)."""
        if len(t) < 2:
            return
        limits = list(self.info.effort_limits)
        for title, names, _unit in PLOTS:
            present = [n for n in names if n in signals]
            if not present:
                continue
            for j, handle in enumerate(self._plots[title]):
                y = np.column_stack([signals[n][:, j] for n in present])
                tt, yy = decimate(t, y, self._budget)
                columns = {n: yy[:, k] for k, n in enumerate(present)}
                filler = yy[:, 0]  # any column: the series it fills is hidden
                data = [tt] + [columns.get(n, filler) for n in names]
                shown = [n in columns for n in names]
                if title == "Torque":
                    lim = limits[j] if j < len(limits) else math.nan
                    known = math.isfinite(lim)
                    data += (
                        [np.full(len(tt), lim), np.full(len(tt), -lim)] if known else [filler] * 2
                    )
                    shown += [known, known]
                data.append(
                    spread([d for d, v in zip(data[1:], shown, strict=True) if v], len(tt))
                )
                shown.append(True)
                self._show_series(handle, shown)
                handle.data = tuple(np.ascontiguousarray(d, dtype=np.float64) for d in data)

    def _show_series(self, handle: Any, shown: list[bool]) -> None:
        """Hide the series without data (sent again only when that changes)."""
        series = handle.series
        wanted = (series[0], *({**s, "show": v} for s, v in zip(series[1:], shown, strict=True)))
        if [s.get("show", True) for s in series[1:]] != shown:
            handle.series = wanted

    # -- reference and push ------------------------------------------------------------
    def add_reference(self) -> None:
        """The set-point and sinusoid controls (once a controller serves the robot)."""
        if self.has_reference:
            return
        self.has_reference = True
        gui = self._server.gui
        with self._tab:
            self._build_reference(gui)

    def _build_reference(self, gui: Any) -> None:
        limits = list(self.info.position_limits) or [(-math.pi, math.pi)] * len(self.info.joints)
        with gui.add_folder("Reference"):
            self._targets = []
            self._targets_set = False
            for joint, (lo, hi) in zip(self.info.joints, limits, strict=True):
                lo = lo if math.isfinite(lo) else -math.pi
                hi = hi if math.isfinite(hi) else math.pi
                target = gui.add_slider(
                    f"q_d {joint} [rad]",
                    min=lo,
                    max=hi,
                    step=0.001,
                    initial_value=min(max(0.0, lo), hi),
                )
                target.on_update(self._target_typed)
                self._targets.append(target)
            self._duration = gui.add_number(
                "move duration [s]",
                initial_value=1.0,
                min=0.0,
                max=60.0,
                step=0.1,
                hint="0: a step",
            )
            send = gui.add_button("Send set-point")
            send.on_click(lambda event: self._report(event, self._send_setpoint()))
            self._amplitude = gui.add_number(
                "sinusoid Δ [rad]", initial_value=0.2, min=0.0, max=math.pi, step=0.01
            )
            self._omega = gui.add_number(
                "sinusoid ω [rad/s]", initial_value=2.0, min=0.0, max=100.0, step=0.1
            )
            self._sin_duration = gui.add_number(
                "sinusoid duration [s]", initial_value=10.0, min=0.1, max=200.0, step=0.1
            )
            sine = gui.add_button("Send sinusoid q̄ + Δ sin ωt", hint="q̄: the set-points above")
            sine.on_click(lambda event: self._report(event, self._send_sinusoid()))
            self.reference_message = gui.add_markdown(" ")

    def _target_typed(self, event: Any) -> None:
        """A person set a set-point: from now on the sliders are theirs (never moved to
        the set-point in force, which could overwrite what they typed before sending)."""
        if event.client is not None:
            self._targets_set = True

    def hold_targets(self, q_d: np.ndarray) -> None:
        """Start the set-point sliders at the set-point in force (once, and only before a
        person has set one)."""
        if getattr(self, "_targets_set", True) or not np.all(np.isfinite(q_d)):
            return
        for handle, value in zip(self._targets, q_d, strict=True):
            handle.value = min(max(float(value), handle.min), handle.max)
        self._targets_set = True

    def _send_setpoint(self) -> str | None:
        targets = [h.value for h in self._targets]
        return self._actions.send_setpoint(self.info.key, targets, float(self._duration.value))

    def _send_sinusoid(self) -> str | None:
        centre = [h.value for h in self._targets]
        amplitude = [float(self._amplitude.value)] * len(centre)
        return self._actions.send_sinusoid(
            self.info.key,
            centre,
            amplitude,
            float(self._omega.value),
            float(self._sin_duration.value),
        )

    def _add_push(self) -> None:
        gui = self._server.gui
        links = self.info.links or ("",)
        with gui.add_folder("Push", expand_by_default=False):
            self._link = gui.add_dropdown("link", links, initial_value=links[-1])
            self._force = gui.add_vector3(
                "force [N] (world x, y, z)", initial_value=(0.0, 0.0, -200.0), step=1.0
            )
            self._push_time = gui.add_number(
                "push duration [s]", initial_value=0.2, min=0.001, max=10.0, step=0.01
            )
            push = gui.add_button("Push")
            push.on_click(
                lambda event: self._report(
                    event,
                    self._actions.push(
                        self.info.key,
                        self._link.value,
                        list(self._force.value),
                        float(self._push_time.value),
                    ),
                )
            )

    def _report(self, event: Any, reason: str | None) -> None:
        if reason is not None and event.client is not None:
            event.client.add_notification("refused", reason, auto_close_seconds=8.0, color="red")

    # -- parameters --------------------------------------------------------------------
    def add_parameters(
        self, node: str, controls: Sequence[Control], values: dict
    ) -> ParameterPanel:
        gui = self._server.gui
        with self._tab, gui.add_folder(f"Parameters of {node}", expand_by_default=False):
            panel = ParameterPanel(gui, node, controls, values, self._actions)
        self.parameters[node] = panel
        return panel


class PortInUseError(RuntimeError):
    pass


class OneLineErrors(logging.Filter):
    """A library's error logged with its traceback becomes one line with the reason: a
    client that connects and says nothing (a port scanner, a health check, a browser that
    gives up) made the web server log three chained tracebacks per connection."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and record.exc_info[1] is not None:
            reason = record.exc_info[1]
            while reason.__cause__ is not None:  # the first cause says what happened
                reason = reason.__cause__
            record.msg = f"{record.getMessage()}: {type(reason).__name__}: {reason}"
            record.args, record.exc_info, record.exc_text = (), None, None
        return True


#: The web server's own logger (websockets, under viser).
WEB_SERVER_LOGGER = "websockets.server"


class Page:
    """The page: a world panel (time, pause/resume/reset, the plant's parameters) and one
    tab per robot."""

    def __init__(self, host: str, port: int, actions: Actions, budget: int = 400) -> None:
        import viser

        client_is_bundled()
        never_build_client()
        server_log = logging.getLogger(WEB_SERVER_LOGGER)
        if not any(isinstance(f, OneLineErrors) for f in server_log.filters):
            server_log.addFilter(OneLineErrors())
        self.server = viser.ViserServer(
            host=host, port=port, label="joint_space_control", verbose=False
        )
        if self.server.get_port() != port:  # viser moves on to the next free port
            self.server.stop()
            raise PortInUseError(f"port {port} on {host} is in use (give another with -p port:=N)")
        self.url = f"http://{'localhost' if host in ('127.0.0.1', '::1') else host}:{port}"
        self._actions = actions
        self._budget = budget
        self.robots: dict[str, RobotPanel] = {}
        gui = self.server.gui
        gui.configure_theme(
            control_layout="fixed",
            control_width="large",
            dark_mode=False,
            show_logo=False,
            show_share_button=False,
        )
        self.server.scene.set_up_direction("+z")
        with gui.add_folder("World"):
            self.world_status = gui.add_markdown("looking for a plant in the ROS graph …")
            buttons = gui.add_button_group("plant", ("pause", "resume", "reset"))
            buttons.on_click(lambda event: self._plant(event, buttons.value))
        self.world_parameters: ParameterPanel | None = None
        self._tabs = gui.add_tab_group()
        self._floor = None

    def _plant(self, event: Any, what: str) -> None:
        reason = self._actions.plant(what)
        if reason is not None and event.client is not None:
            event.client.add_notification(
                f"{what} failed", reason, auto_close_seconds=8.0, color="red"
            )

    def add_robot(self, info: RobotInfo) -> RobotPanel:
        tab = self._tabs.add_tab(info.title)
        panel = RobotPanel(self.server, tab, info, self._actions, self._budget)
        self.robots[info.key] = panel
        self.frame()
        return panel

    def add_world_parameters(
        self, node: str, controls: Sequence[Control], values: dict
    ) -> ParameterPanel:
        gui = self.server.gui
        with gui.add_folder(f"Parameters of {node}", expand_by_default=False):
            self.world_parameters = ParameterPanel(gui, node, controls, values, self._actions)
        return self.world_parameters

    def frame(self) -> None:
        """Point the camera at every robot, with a floor under them."""
        boxes = [p.box for p in self.robots.values() if p.box is not None]
        if not boxes:
            return
        position, look_at = frame_camera(boxes)
        camera = self.server.initial_camera
        camera.position = tuple(position)
        camera.look_at = tuple(look_at)
        for client in self.server.get_clients().values():
            client.camera.position = tuple(position)
            client.camera.look_at = tuple(look_at)
        lower = np.min([b[0] for b in boxes], axis=0)
        upper = np.max([b[1] for b in boxes], axis=0)
        size = float(max(upper[0] - lower[0], upper[1] - lower[1], 1.0)) * 2.0
        centre = 0.5 * (lower + upper)
        self._floor = self.server.scene.add_grid(
            "/floor",
            width=size,
            height=size,
            position=(float(centre[0]), float(centre[1]), min(0.0, float(lower[2]))),
            cell_size=0.1 if size < 4 else 0.5,
        )

    def close(self) -> None:
        self.server.stop()
