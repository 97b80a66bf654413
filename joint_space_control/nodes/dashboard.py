"""``dashboard``: a web page on this machine that shows and tunes the running loop.

The node finds the robots in the graph (:mod:`~joint_space_control.dashboard.graph`): each
plant's joint states, each controller's ``~/state`` and ``~/config``. It feeds the page
(:mod:`~joint_space_control.dashboard.page`) with the robots in 3D, live plots and the loop's
status, and carries out what the page asks only through what any user could call:

- parameters: the standard parameter services (list, describe, get, set) of every
  controller and of the plant, and ``/parameter_events`` for changes made elsewhere;
- a reference: a JointTrajectory on the controller's ``reference`` topic;
- the plant: ``~/pause``, ``~/resume``, ``~/reset`` (std_srvs/Trigger) and a push on
  ``sim_bridge/wrench`` (removed again after its duration).

It cannot endanger the loop: it is a process of its own, never publishes effort, samples
the loop's topics best-effort at most ``sample_rate`` times a second, and sends at most
:data:`SEND_RATE` requests a second (a slider's drag is coalesced to its newest value).
"""

from __future__ import annotations

import json
import math
import os
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import ParameterEvent
from rclpy.executors import SingleThreadedExecutor, TimeoutException
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from joint_space_control.dashboard import graph
from joint_space_control.dashboard.controls import control_for
from joint_space_control.dashboard.page import Actions, Page, PortInUseError, RobotInfo
from joint_space_control.dashboard.series import Window
from joint_space_control.nodes.trajectory_generator import trajectory_message
from joint_space_control.ros import node_main
from joint_space_control.ros import parameters as params
from joint_space_control.ros.diagnostics import DIAGNOSTICS_QOS, DIAGNOSTICS_TOPIC
from joint_space_control.ros.graph import node_names
from joint_space_control.ros.messages import CONFIG_QOS, REFERENCE_QOS, STATE_FIELDS
from joint_space_control.trajectories import shapes

LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")
#: Most requests (parameter sets, references, plant calls) the page sends per second.
SEND_RATE = 20.0
#: How long the node waits for a service's answer [s].
SERVICE_TIMEOUT = 3.0
#: Samples of the loop's topics: only the newest matters; best effort, so the loop's
#: publishers never wait for the page.
SAMPLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT
)

PARAMETERS = (
    params.ParamSpec(
        "host",
        "127.0.0.1",
        "Address the page is served on; anyone who reaches it can command the robot",
        read_only=True,
    ),
    params.ParamSpec("port", 8080, "Port of the page", read_only=True, minimum=1.0),
    params.ParamSpec(
        "window", 10.0, "Plotted window of simulation time", unit="s", minimum=0.0, exclusive=True
    ),
    params.ParamSpec(
        "points", 400, "Most points per plotted signal sent to the browser", minimum=10.0
    ),
    params.ParamSpec(
        "refresh_rate",
        4.0,
        "Plot and status updates per second (wall time)",
        unit="Hz",
        minimum=0.0,
        exclusive=True,
    ),
    params.ParamSpec(
        "view_rate",
        10.0,
        "3D view updates per second (wall time); a robot that has not moved is not redrawn",
        read_only=True,
        unit="Hz",
        minimum=0.0,
        exclusive=True,
        maximum=100.0,
    ),
    params.ParamSpec(
        "sample_rate",
        100.0,
        "Most samples per second taken of each topic of the loop (wall time)",
        read_only=True,
        unit="Hz",
        minimum=0.0,
        exclusive=True,
    ),
    params.ParamSpec(
        "niceness",
        10,
        "Scheduling niceness of the dashboard's process (0: as the loop's nodes; up to 19, "
        "the lowest priority): the loop's processes first when the cores are busy",
        read_only=True,
        minimum=0.0,
        maximum=19.0,
        step=1.0,
    ),
)
#: What the node subscribes to, publishes and calls, all found in the ROS graph: (kind,
#: name, type, meaning), rendered into docs/reference by joint_space_control.nodes.reference.
#: Besides, it serves the page over HTTP on ``host``:``port``.
INTERFACE = (
    (
        "subscribes",
        "<robot>/joint_states",
        "sensor_msgs/msg/JointState",
        "every plant's joint states, sampled best effort at most `sample_rate` times a second",
    ),
    (
        "subscribes",
        "<controller>/state",
        "std_msgs/msg/Float64MultiArray",
        "every controller's state (reference, error, torque split), sampled the same way",
    ),
    (
        "subscribes",
        "<controller>/config",
        "std_msgs/msg/String",
        "every controller's configuration (latched): its robot, limits and gains",
    ),
    (
        "subscribes",
        "/diagnostics",
        "diagnostic_msgs/msg/DiagnosticArray",
        "the loop's status shown on the page",
    ),
    (
        "subscribes",
        "/parameter_events",
        "rcl_interfaces/msg/ParameterEvent",
        "parameter changes made elsewhere, shown on the page's controls",
    ),
    (
        "subscribes",
        "robot_description",
        "std_msgs/msg/String",
        "only for a plant started with `robot:=topic`: the URDF text drawn in 3D",
    ),
    (
        "publishes",
        "<controller's reference topic>",
        "trajectory_msgs/msg/JointTrajectory",
        "a set-point or a sinusoid sent from the page",
    ),
    (
        "publishes",
        "<robot>/<plant>/wrench",
        "geometry_msgs/msg/WrenchStamped",
        "a push on a link sent from the page, removed again after its duration",
    ),
    (
        "calls",
        "<plant>/pause, <plant>/resume, <plant>/reset",
        "std_srvs/srv/Trigger",
        "the page's pause, resume and reset buttons",
    ),
    (
        "calls",
        "<node>/list_parameters",
        "rcl_interfaces/srv/ListParameters",
        "the parameters of every controller and of the plant, shown as controls",
    ),
    (
        "calls",
        "<node>/describe_parameters",
        "rcl_interfaces/srv/DescribeParameters",
        "their descriptors: type, range (a slider's ends), read-only",
    ),
    (
        "calls",
        "<node>/get_parameters",
        "rcl_interfaces/srv/GetParameters",
        "their values, and the plant's robot parameters for the 3D model",
    ),
    (
        "calls",
        "<node>/set_parameters",
        "rcl_interfaces/srv/SetParameters",
        f"a value changed on the page (at most {SEND_RATE:g} requests a second); a refusal "
        "shows the node's reason",
    ),
)


@dataclass
class RobotState:
    key: str
    topic: str
    plant: str
    window: Window
    joints: tuple[str, ...] = ()
    panel: Any = None
    building: bool = False


@dataclass
class ControllerState:
    node: str
    robot: str
    reference_topic: str | None
    window: Window
    config: dict = field(default_factory=dict)
    joints: tuple[str, ...] = ()
    reference_pub: Any = None
    parameters_shown: bool = False


def port_free(host: str, port: int) -> bool:
    """Whether a server can listen on ``host``:``port`` now."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        # as the server binds (asyncio): connections of an earlier server in TIME_WAIT
        # do not make the port busy, a listening socket does
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def wait_future(future: Any, timeout: float = SERVICE_TIMEOUT) -> Any:
    """The result of a service future completed by the executor thread; None on time-out."""
    done = threading.Event()
    future.add_done_callback(lambda _f: done.set())
    if not done.wait(timeout):
        future.cancel()
        return None
    return future.result()


class PacedExecutor(SingleThreadedExecutor):
    """Runs whatever is ready, then sleeps out the rest of ``period``: each topic of the
    loop (a queue of one) is taken at most once a period, however fast the loop runs."""

    def __init__(self, period: float = 0.01) -> None:
        super().__init__()
        self._period = period
        self._next = 0.0

    def add_node(self, node: Node) -> bool:
        self._period = getattr(node, "sample_period", self._period)
        return super().add_node(node)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        pause = self._next - time.monotonic()
        if pause > 0:
            time.sleep(min(pause, timeout_sec if timeout_sec is not None else pause))
            if self._next - time.monotonic() > 0:
                return
        self._next = time.monotonic() + self._period
        wait = timeout_sec
        while time.monotonic() < self._next:
            try:
                handler, _entity, _node = self.wait_for_ready_callbacks(timeout_sec=wait)
            except TimeoutException:
                return
            handler()
            if handler.exception() is not None:
                raise handler.exception()
            wait = 0.0


class Dashboard(Node):
    """The node behind the page (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("dashboard", **kwargs)
        params.declare(self, PARAMETERS)
        values = params.current_values(self, PARAMETERS)
        host = values["host"]
        port = int(params.value(values, "port"))
        if port > 65535 or port != params.value(values, "port"):
            raise ValueError(f"'port' must be an integer 1..65535, got {values['port']!r}")
        if not port_free(host, port):
            raise ValueError(f"port {port} on {host} is in use (give another: -p port:=N)")
        if host not in LOCAL_HOSTS:
            self.get_logger().warning(
                f"serving on {host}: anyone who reaches {host}:{port} can command the robot "
                "(change gains, send references, pause and push the plant)"
            )
        # best effort beside the loop: behind its nodes for the CPU (docs/dashboard.md)
        niceness = int(params.value(values, "niceness"))
        os.setpriority(os.PRIO_PROCESS, 0, max(niceness, os.getpriority(os.PRIO_PROCESS, 0)))
        self._window = params.value(values, "window")
        self._lock = threading.RLock()
        self._robots: dict[str, RobotState] = {}
        self._controllers: dict[str, ControllerState] = {}
        self._parameter_panels: dict[str, Any] = {}
        self._param_clients: dict[str, AsyncParameterClient] = {}
        self._diagnostics: dict[str, dict[str, str]] = {}
        self._wrench_pubs: dict[str, Any] = {}
        self._plant_clients: dict[str, Any] = {}
        self._send_lock = threading.Lock()
        self._seq_lock = threading.Lock()
        self._seq: dict[tuple[str, str], int] = {}
        self._last_send = 0.0
        self.sample_period = 1.0 / params.value(values, "sample_rate")
        actions = Actions(
            set_parameter=self.set_parameter,
            send_setpoint=self.send_setpoint,
            send_sinusoid=self.send_sinusoid,
            plant=self.call_plant,
            push=self.push,
        )
        try:
            self.page = Page(host, port, actions, budget=int(params.value(values, "points")))
        except PortInUseError as err:
            raise ValueError(str(err)) from None
        self.url = self.page.url
        self.create_subscription(
            DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diagnostics, DIAGNOSTICS_QOS
        )
        self.create_subscription(
            ParameterEvent, "/parameter_events", self._on_parameter_event, 100
        )
        self.create_timer(1.0 / params.value(values, "refresh_rate"), self._refresh)
        self.create_timer(1.0 / params.value(values, "view_rate"), self._move_robots)
        self._stop = threading.Event()
        self._discovery = threading.Thread(
            target=self._discover_loop, name="jsc-discovery", daemon=True
        )
        self._discovery.start()
        self.get_logger().info(f"dashboard: {self.url} (robots found from the ROS graph)")

    # -- discovery (its own thread: it waits for services the executor answers) ---------
    def _discover_loop(self) -> None:
        while not self._stop.wait(0.5):
            try:
                self._discover()
            except Exception as err:  # noqa: BLE001 - the page must outlive any one robot
                self.get_logger().warning(f"discovery: {type(err).__name__}: {err}")
                self._stop.wait(1.0)

    def _discover(self) -> None:
        topics = self.get_topic_names_and_types()
        robots = graph.robot_topics(topics)
        me = self.get_fully_qualified_name()
        for key, topic in robots.items():
            if key in self._robots:
                continue
            plants = sorted(node_names(self.get_publishers_info_by_topic(topic)) - {me})
            if plants:
                self._add_robot(key, topic, plants[0])
        for node in graph.controller_nodes(topics):
            if node in self._controllers:
                continue
            name, namespace = graph.split_name(node)
            try:
                subscriptions = self.get_subscriber_names_and_types_by_node(name, namespace)
            except Exception:  # noqa: BLE001 - the node left the graph meanwhile
                continue
            key = graph.robot_of(subscriptions, robots)
            if key is not None:
                self._add_controller(node, key, graph.topic_of(subscriptions, graph.TRAJECTORY))
        for robot in list(self._robots.values()):
            if robot.panel is None and robot.joints and not robot.building:
                robot.building = True  # once: a panel that failed is not built again
                self._build_panel(robot)
            elif robot.panel is not None and self._controller_of(robot.key) is not None:
                robot.panel.add_reference()  # a controller that came after the plant
        for node in self._nodes_to_describe():
            self._describe(node)

    def _add_robot(self, key: str, topic: str, plant: str) -> None:
        robot = RobotState(key, topic, plant, self._new_window(0))
        with self._lock:
            self._robots[key] = robot
        self.create_subscription(
            JointState, topic, lambda msg, r=robot: self._on_joint_state(r, msg), SAMPLE_QOS
        )

    def _add_controller(self, node: str, key: str, reference: str | None) -> None:
        ctrl = ControllerState(node, key, reference, self._new_window(0))
        with self._lock:
            self._controllers[node] = ctrl
        self.create_subscription(
            String, f"{node}/config", lambda msg, c=ctrl: self._on_config(c, msg), CONFIG_QOS
        )
        self.create_subscription(
            Float64MultiArray,
            f"{node}/state",
            lambda msg, c=ctrl: self._on_state(c, msg),
            SAMPLE_QOS,
        )
        if reference is not None:
            ctrl.reference_pub = self.create_publisher(JointTrajectory, reference, REFERENCE_QOS)

    def _plant_values(self, robot: RobotState) -> params.ParamValues:
        """The robot parameters the plant was started with (its parameter service)."""
        client = self._param_client(robot.plant)
        got = wait_future(client.get_parameters(["robots"]))
        names = [] if got is None else parameter_value_to_python(got.values[0]) or []
        prefix = graph.parameter_prefix(robot.key, list(names))
        wanted = [s.name for s in params.ROBOT_PARAMETERS] + ["base_position", "base_rpy"]
        got = wait_future(client.get_parameters([prefix + n for n in wanted]))
        if got is None:
            raise TimeoutError(f"{robot.plant} did not answer get_parameters")
        values = {n: parameter_value_to_python(v) for n, v in zip(wanted, got.values, strict=True)}
        defaults = {s.name: s.default for s in params.ROBOT_PARAMETERS}
        merged = {n: (defaults.get(n) if v is None else v) for n, v in values.items()}
        return params.ParamValues(params.ROBOT_PARAMETERS, merged)

    def _build_panel(self, robot: RobotState) -> None:
        notes = []
        urdf_path: Path | None = None
        base_position, base_rpy = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
        try:
            values = self._plant_values(robot)
            spec = params.robot_spec(values, node=self)
            urdf_path = spec.urdf_path
            notes += spec.warnings  # meshes not found: said on the page, where they are missing
            base_position = tuple(float(v) for v in values["base_position"] or (0.0, 0.0, 0.0))
            base_rpy = tuple(float(v) for v in values["base_rpy"] or (0.0, 0.0, 0.0))
        except (ValueError, TimeoutError, KeyError, TypeError) as err:
            notes.append(f"no 3D model: {err}")
            self.get_logger().warning(f"{robot.key or '/'}: no 3D model: {err}")
        ctrls = [c for c in self._controllers.values() if c.robot == robot.key]
        config = next((c.config for c in ctrls if c.config), {})
        info = RobotInfo(
            key=robot.key,
            title=robot.key.strip("/") or "robot",
            joints=robot.joints,
            urdf_path=urdf_path,
            base_position=base_position,
            base_rpy=base_rpy,
            position_limits=tuple(tuple(p) for p in config.get("position_limits", ())),
            effort_limits=tuple(float(e) for e in config.get("effort_limits", ())),
            controllers=tuple(c.node for c in ctrls),
            notes=tuple(notes),
        )
        panel = self.page.add_robot(info)
        robot.panel = panel
        self.get_logger().info(
            f"robot {robot.key or '/'}: {len(robot.joints)} joints, plant {robot.plant}, "
            f"controllers {list(info.controllers) or 'none'}"
        )

    # -- parameters ----------------------------------------------------------------------
    def _param_client(self, node: str) -> AsyncParameterClient:
        client = self._param_clients.get(node)
        if client is None:
            client = AsyncParameterClient(self, node)
            self._param_clients[node] = client
        return client

    def _nodes_to_describe(self) -> list[str]:
        nodes = []
        plants = {r.plant for r in self._robots.values() if r.panel is not None}
        nodes += sorted(plants)
        for ctrl in self._controllers.values():
            robot = self._robots.get(ctrl.robot)
            if robot is not None and robot.panel is not None:
                nodes.append(ctrl.node)
        return [n for n in nodes if n not in self._parameter_panels]

    def _describe(self, node: str) -> None:
        client = self._param_client(node)
        listed = wait_future(client.list_parameters())
        if listed is None:
            return
        names = sorted(listed.result.names)
        described = wait_future(client.describe_parameters(names))
        got = wait_future(client.get_parameters(names))
        if described is None or got is None:
            return
        values = {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}
        ctrl = self._controllers.get(node)
        if ctrl is not None:
            joints = ctrl.joints or self._robots[ctrl.robot].joints
        else:
            joints = next(
                (r.joints for r in self._robots.values() if r.plant == node and r.joints), ()
            )
        controls = [control_for(d, values[d.name], joints) for d in described.descriptors]
        if ctrl is not None:
            panel = self._robots[ctrl.robot].panel.add_parameters(node, controls, values)
        else:
            panel = self.page.add_world_parameters(node, controls, values)
        self._parameter_panels[node] = panel
        offered = sum(c.kind != "shown" for c in controls)
        self.get_logger().info(f"{node}: {len(controls)} parameters, {offered} with a control")

    def _on_parameter_event(self, event: ParameterEvent) -> None:
        panel = self._parameter_panels.get(event.node)
        if panel is None:
            return
        for p in (*event.new_parameters, *event.changed_parameters):
            panel.show(p.name, parameter_value_to_python(p.value))

    def set_parameter(self, node: str, name: str, value: Any) -> str | None:
        """Set one parameter through ``node``'s parameter service: None when it took it,
        else the node's reason. A value superseded by a newer one for the same parameter
        while it waited to be sent is dropped (a slider's drag)."""
        key = (node, name)
        with self._seq_lock:
            seq = self._seq[key] = self._seq.get(key, 0) + 1
        with self._send_lock:
            if self._seq[key] != seq:
                return None
            self._pace()
            future = self._param_client(node).set_parameters([Parameter(name, value=value)])
            result = wait_future(future)
        if result is None:
            return f"{node} did not answer within {SERVICE_TIMEOUT:g} s"
        outcome = result.results[0]
        return None if outcome.successful else (outcome.reason or "rejected")

    def _pace(self) -> None:
        """Hold the caller until 1/SEND_RATE has passed since the last request (lock held)."""
        pause = self._last_send + 1.0 / SEND_RATE - time.monotonic()
        if pause > 0:
            time.sleep(pause)
        self._last_send = time.monotonic()

    # -- references, plant, push ---------------------------------------------------------
    def _controller_of(self, key: str) -> ControllerState | None:
        ctrls = [
            c for c in self._controllers.values() if c.robot == key and c.reference_pub is not None
        ]
        return ctrls[0] if ctrls else None

    def _send_reference(self, key: str, build: Callable[[int], Any]) -> str | None:
        ctrl = self._controller_of(key)
        if ctrl is None:
            return "no controller with a reference topic serves this robot"
        joints = ctrl.joints or self._robots[key].joints
        try:
            traj = build(len(joints))
            msg = trajectory_message(traj, joints)
        except ValueError as err:
            return str(err)
        with self._send_lock:
            self._pace()
            ctrl.reference_pub.publish(msg)
        return None

    def send_setpoint(self, key: str, targets: Sequence[float], duration: float) -> str | None:
        if duration > 0:
            return self._send_reference(key, lambda n: shapes.quintic(None, targets, duration, n))
        return self._send_reference(key, lambda n: shapes.step(targets, n))

    def send_sinusoid(
        self,
        key: str,
        centre: Sequence[float],
        amplitude: Sequence[float],
        omega: float,
        duration: float,
    ) -> str | None:
        limits = self._position_limits(key)
        if limits is not None:
            lo, hi = limits
            c, a = np.asarray(centre), np.abs(np.asarray(amplitude))
            if np.any(c - a < lo) or np.any(c + a > hi):
                return "q̄ ± Δ leaves the joint limits: lower Δ or move q̄"
        return self._send_reference(
            key, lambda n: shapes.sinusoid(centre, amplitude, omega, 0.0, duration, n=n)
        )

    def _position_limits(self, key: str) -> tuple[np.ndarray, np.ndarray] | None:
        ctrl = self._controller_of(key)
        limits = ctrl.config.get("position_limits") if ctrl is not None else None
        if not limits:
            return None
        arr = np.array(limits, dtype=float)
        return arr[:, 0], arr[:, 1]

    def _plant(self) -> str | None:
        plants = sorted({r.plant for r in self._robots.values()})
        return plants[0] if plants else None

    def call_plant(self, what: str) -> str | None:
        plant = self._plant()
        if plant is None:
            return "no plant in the graph"
        name = f"{plant}/{what}"
        client = self._plant_clients.get(name)
        if client is None:
            client = self._plant_clients[name] = self.create_client(Trigger, name)
        if not client.wait_for_service(timeout_sec=1.0):
            return f"{name} is not offered"
        with self._send_lock:
            self._pace()
            result = wait_future(client.call_async(Trigger.Request()))
        if result is None:
            return f"{name} did not answer within {SERVICE_TIMEOUT:g} s"
        return None if result.success else result.message

    def push(self, key: str, link: str, force: Sequence[float], duration: float) -> str | None:
        robot = self._robots.get(key)
        if robot is None:
            return "unknown robot"
        name, _ = graph.split_name(robot.plant)
        topic = f"{key}/{name}/wrench"
        values = np.asarray(force, dtype=float)
        if values.shape != (3,) or not np.all(np.isfinite(values)):
            return "the force needs 3 finite components"
        if not math.isfinite(duration) or duration <= 0:
            return "the duration must be > 0"
        pub = self._wrench_pubs.get(topic)
        if pub is None:
            pub = self._wrench_pubs[topic] = self.create_publisher(WrenchStamped, topic, 10)
        msg = WrenchStamped()
        msg.header.frame_id = link
        msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = values.tolist()
        with self._send_lock:
            self._pace()
            pub.publish(msg)
        off = WrenchStamped()
        off.header.frame_id = link
        timer = threading.Timer(duration, pub.publish, args=(off,))
        timer.daemon = True
        timer.start()
        return None

    # -- incoming samples ----------------------------------------------------------------
    def _new_window(self, channels: int) -> Window:
        """A window of ``channels`` series holding what the plots show: ``window`` seconds
        at ``sample_rate``, twice over (a simulation up to twice slower than real time still
        fills its window). A fixed 20,000 rows made the resident memory climb for minutes
        as they were first written (the fault soak's hour counted it as growth)."""
        capacity = max(100, math.ceil(2.0 * self._window / self.sample_period))
        return Window(channels, self._window, capacity)

    def _on_joint_state(self, robot: RobotState, msg: JointState) -> None:
        n = len(msg.name)
        if not robot.joints:
            if n == 0 or len(msg.position) != n:
                return
            robot.joints = tuple(msg.name)
            robot.window = self._new_window(2 * n)
        if tuple(msg.name) != robot.joints or len(msg.position) != n:
            return
        effort = msg.effort if len(msg.effort) == n else [math.nan] * n
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        robot.window.append(t, np.concatenate((msg.position, effort)))

    def _on_config(self, ctrl: ControllerState, msg: String) -> None:
        try:
            config = json.loads(msg.data)
        except ValueError:
            return
        ctrl.config = config
        joints = tuple(config.get("joints", ()))
        if joints != ctrl.joints:
            ctrl.joints = joints
            ctrl.window = self._new_window(len(STATE_FIELDS) * len(joints))

    def _on_state(self, ctrl: ControllerState, msg: Float64MultiArray) -> None:
        n = len(ctrl.joints)
        data = msg.data
        if n == 0 or len(data) != 1 + len(STATE_FIELDS) * n:
            return
        ctrl.window.append(data[0], np.asarray(data[1:]))

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            node = status.name.split(":")[0]
            self._diagnostics[node] = {kv.key: kv.value for kv in status.values}

    # -- the page ------------------------------------------------------------------------
    def _move_robots(self) -> None:
        for robot in list(self._robots.values()):
            if robot.panel is None or not len(robot.window):
                continue
            _t, y = robot.window.view()
            robot.panel.show_configuration(y[-1, : len(robot.joints)])

    def _refresh(self) -> None:
        for robot in list(self._robots.values()):
            if robot.panel is None:
                continue
            ctrl = next(
                (c for c in self._controllers.values() if c.robot == robot.key and len(c.window)),
                None,
            )
            n = len(robot.joints)
            if ctrl is not None and tuple(ctrl.joints) == robot.joints:
                t, y = ctrl.window.view()
                rows = y.reshape(len(y), len(STATE_FIELDS), n)
                signals = {f: rows[:, k, :] for k, f in enumerate(STATE_FIELDS)}
                if len(t):
                    robot.panel.hold_targets(signals["q_d"][-1])
            else:
                t, y = robot.window.view()
                signals = {"q": y[:, :n], "tau": y[:, n:]}
            robot.panel.show_signals(t, signals)
            robot.panel.status.content = self._robot_status(robot)
        self.page.world_status.content = self._world_status()

    def _world_status(self) -> str:
        plant = self._plant()
        if plant is None:
            return "no plant in the ROS graph yet (looking for …/joint_states publishers)"
        d = self._diagnostics.get(graph.split_name(plant)[0], {})
        if not d:
            return f"plant **{plant}**: waiting for its /diagnostics"
        ticks = float(d.get("ticks", "nan"))
        late = float(d.get("late", "nan"))
        on_time = f"{100.0 * (1.0 - late / ticks):.1f} %" if ticks > 0 else "– (no ticks)"
        return (
            f"plant **{plant}**, mode **{d.get('mode', '?')}**, "
            f"simulated time **{float(d.get('sim_time_s', 'nan')):.2f} s**, "
            f"real-time factor **{float(d.get('real_time_factor', 'nan')):.2f}**, "
            f"on time **{on_time}**"
        )

    def _robot_status(self, robot: RobotState) -> str:
        d = self._diagnostics.get(graph.split_name(robot.plant)[0], {})
        prefix = (
            f"{robot.key.strip('/')}."
            if robot.key and f"{robot.key.strip('/')}.owner" in d
            else ""
        )
        rejected = {
            k[len(prefix) :]: v
            for k, v in d.items()
            if k.startswith(prefix + "rejected.") and v not in ("0", "")
        }
        lines = [
            f"**{robot.key or '/'}** · joints {', '.join(robot.joints)}",
            f"owner **{d.get(prefix + 'owner') or 'none'}**, brakes "
            f"**{'on' if d.get(prefix + 'braking', d.get('braking')) == '1' else 'off'}**"
            + (f", rejected {rejected}" if rejected else ", nothing rejected"),
        ]
        for ctrl in self._controllers.values():
            if ctrl.robot != robot.key:
                continue
            c = ctrl.config
            cd = self._diagnostics.get(graph.split_name(ctrl.node)[0], {})
            gains = ""
            if c.get("kp") is not None:
                kp = ", ".join(f"{v:.4g}" for v in c["kp"])
                kd = ", ".join(f"{v:.4g}" for v in c["kd"])
                gains = f" · K_P [{kp}] · K_D [{kd}]"
            ctrl_rejected = {
                k: v for k, v in cd.items() if k.startswith("rejected.") and v not in ("0", "")
            }
            lines.append(
                f"**{ctrl.node}**: {c.get('law', '?')}, trigger {c.get('trigger', '?')}"
                f"{gains} (from {c.get('gains_from', '?')})"
                + (f", rejected {ctrl_rejected}" if ctrl_rejected else "")
            )
        return "\n\n".join(lines)

    def close(self) -> None:
        self._stop.set()
        self.page.close()


def main(args: list[str] | None = None) -> None:
    node_main.run_node(Dashboard, args, executor=PacedExecutor)


if __name__ == "__main__":
    main()
