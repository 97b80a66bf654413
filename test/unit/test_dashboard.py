"""The dashboard's pure parts: a parameter's descriptor → its control (ranges, steps,
choices, per-joint lists, read-only), the rolling window and its decimation, the plots'
y axes, and the robots found from graph names. No browser, no ROS graph: descriptors are the
rcl_interfaces messages a node's describe_parameters service answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from joint_space_control.dashboard import graph
from joint_space_control.dashboard.controls import Control, choices, control_for
from joint_space_control.dashboard.series import (
    LEAST_SPAN,
    Y_INCREMENTS,
    Window,
    decimate,
    spread,
)

JOINTS = ("joint1", "joint2")


def descriptor(name: str, **fields) -> ParameterDescriptor:
    return ParameterDescriptor(name=name, **fields)


def test_a_double_with_a_declared_range_is_a_slider_within_it_and_its_step():
    d = descriptor(
        "zeta", floating_point_range=[FloatingPointRange(from_value=0.0, to_value=10.0, step=0.5)]
    )
    c = control_for(d, 1.0, JOINTS)
    assert (c.kind, c.minimum, c.maximum, c.step, c.elements) == ("slider", 0.0, 10.0, 0.5, ())
    assert c.ui_step() == 0.5
    assert c.parameter_value([2.5]) == 2.5 and isinstance(c.parameter_value([2]), float)


def test_a_continuous_range_gets_a_fine_slider_step_and_no_range_a_number_box():
    ranged = descriptor(
        "omega_n", floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1000.0)]
    )
    omega = control_for(ranged, 10.0)
    assert omega.ui_step() == pytest.approx(0.01)  # 12.5 typed is 12.5, not 12 or 13
    assert round(12.5 / omega.ui_step()) * omega.ui_step() == pytest.approx(12.5)
    small = descriptor(
        "zeta", floating_point_range=[FloatingPointRange(from_value=0.0, to_value=10.0)]
    )
    assert control_for(small, 1.0).ui_step() == pytest.approx(1e-4)
    free = control_for(descriptor("x"), 3.0)
    assert (free.kind, free.minimum, free.maximum) == ("number", None, None)


def test_integers_use_the_integer_range_and_are_sent_as_integers():
    d = descriptor("priority", integer_range=[IntegerRange(from_value=1, to_value=99, step=1)])
    c = control_for(d, 50)
    assert (c.kind, c.minimum, c.maximum, c.integer) == ("slider", 1.0, 99.0, True)
    assert c.parameter_value([7.0]) == 7 and isinstance(c.parameter_value([7.0]), int)


def test_per_joint_lists_get_one_control_per_joint_and_dynamic_numbers_too():
    rng = [FloatingPointRange(from_value=0.0, to_value=1e6)]
    kp = control_for(
        descriptor("kp", dynamic_typing=True, floating_point_range=rng), [4000.0, 2000.0], JOINTS
    )
    assert kp.elements == JOINTS and kp.kind == "slider"
    assert kp.element_values([4000.0, 2000.0]) == [4000.0, 2000.0]
    assert kp.parameter_value([1.0, 2.0]) == [1.0, 2.0]
    # one value for all joints (kp:=100, an integer given on the command line) → one per joint
    one = control_for(descriptor("kp", dynamic_typing=True, floating_point_range=rng), 100, JOINTS)
    assert one.elements == JOINTS and not one.integer
    assert one.element_values(100) == [100, 100]
    # a list of another length (a force's 3 components) is labelled by index
    force = control_for(descriptor("wrench_force"), [0.0, 0.0, 1.0], JOINTS)
    assert force.elements == ("0", "1", "2") and force.kind == "number"


def test_choices_are_a_dropdown_and_plain_strings_a_text_box():
    d = descriptor("gravity_compensation", additional_constraints="one of: full | none | desired")
    c = control_for(d, "full")
    assert (c.kind, c.options) == ("dropdown", ("full", "none", "desired"))
    assert control_for(descriptor("output"), "runs/a").kind == "text"
    assert choices("one of: a | b, [unit]") == ("a", "b")
    assert choices(">= 0, one value or one per joint") == ()


def test_read_only_and_uneditable_types_are_shown_with_the_reason():
    ro = control_for(descriptor("robot", read_only=True), "planar_2dof")
    assert (ro.kind, ro.why_not) == ("shown", "read-only")
    names = control_for(descriptor("topics"), ["a", "b"])
    assert names.kind == "shown" and "names" in names.why_not
    empty = control_for(descriptor("effort_limits"), [])
    assert empty.kind == "shown" and "empty" in empty.why_not
    assert control_for(descriptor("use_sim_time"), False).kind == "checkbox"


def test_hint_carries_description_and_constraints():
    c = control_for(
        descriptor("zeta", description="damping ratio", additional_constraints=">= 0"), 1.0
    )
    assert c.hint == "damping ratio; >= 0"
    assert isinstance(c, Control) and c.label == "zeta"


def test_window_keeps_the_last_seconds_in_order_and_restarts_when_time_goes_back():
    w = Window(1, seconds=1.0, capacity=50)
    for k in range(120):  # more than the ring holds
        w.append(0.01 * k, np.array([k]))
    t, y = w.view()
    assert np.all(np.diff(t) > 0) and t[-1] == pytest.approx(1.19)
    assert len(t) == 50 and y[-1, 0] == 119
    w.append(0.0, np.array([-1.0]))  # a reset of the simulation
    t, y = w.view()
    assert len(t) == 1 and y[0, 0] == -1.0


def test_decimation_stays_within_the_budget_and_keeps_every_peak():
    t = np.linspace(0.0, 10.0, 10_001)
    y = np.column_stack((np.sin(t), np.zeros_like(t)))
    y[3_333, 1] = 5.0  # a one-sample spike
    y[7_777, 0] = -3.0
    td, yd = decimate(t, y, 300)
    assert len(td) <= 300
    assert np.all(np.diff(td) > 0)
    assert yd[:, 1].max() == 5.0 and yd[:, 0].min() == -3.0
    assert td[0] == 0.0
    short_t, short_y = decimate(t[:10], y[:10], 300)
    assert len(short_t) == 10 and np.array_equal(short_y, y[:10])


def uplot_ticks(low: float, high: float, height: float) -> list[str]:
    """The y tick labels uPlot draws for data from ``low`` to ``high`` on a plot ``height``
    px high with the page's axis options: its range (the data and 10 % more each side), the
    smallest of ``Y_INCREMENTS`` at least 30 px apart, its multiples within the range,
    written with at most 3 decimals (Intl.NumberFormat's default)."""
    pad = 0.1 * (high - low)
    low, high = low - pad, high + pad
    step = next(i for i in Y_INCREMENTS if i * height / (high - low) >= 30)
    ks = range(math.ceil(low / step - 1e-9), math.floor(high / step + 1e-9) + 1)
    return [f"{k * step:,.3f}".rstrip("0").rstrip(".") for k in ks]


def test_the_y_axis_ticks_are_never_finer_than_its_labels_write():
    """uPlot writes tick labels with at most 3 decimals: its own spacings went down to
    0.0001 ("-0, -0, 0" for a joint 0.1 mrad from 0). The page's are 1, 2 or 5 × 10ⁿ from
    0.001 up, so the labels of two ticks always differ."""
    assert list(Y_INCREMENTS) == sorted(Y_INCREMENTS) and Y_INCREMENTS[0] == 0.001
    for incr in Y_INCREMENTS:
        mantissa = incr / 10 ** math.floor(math.log10(incr))
        assert min(abs(mantissa - m) for m in (1, 2, 5)) < 1e-9, incr
        assert round(incr, 3) == incr  # written exactly with 3 decimals
    assert Y_INCREMENTS[-1] >= 1e9  # torques, however large
    # data spanning LEAST_SPAN or more, anywhere, on the page's plot (~110 px) or expanded
    for low, span in [(-0.3, 0.0), (-0.3, 0.3), (0.0, 2e-4), (1000.0, 0.004), (-2000.0, 4000.0)]:
        middle, half = low + span / 2, max(span, LEAST_SPAN) / 2
        for height in (100, 110, 400, 700):
            labels = uplot_ticks(middle - half, middle + half, height)
            assert len(labels) >= 2 and len(set(labels)) == len(labels), (low, span, labels)


def test_flat_data_is_spread_to_the_least_span_about_its_middle_wider_data_is_left():
    rest = np.full(50, -0.3) + 1e-10 * np.sin(np.arange(50))  # a joint at rest
    widened = spread([rest, np.full(50, np.nan)], 50)
    assert widened.min() == pytest.approx(-0.3 - LEAST_SPAN / 2)
    assert widened.max() == pytest.approx(-0.3 + LEAST_SPAN / 2)
    moving = np.linspace(0.0, -0.3, 50)
    left = spread([rest, moving], 50)
    assert np.all((left >= -0.3 - 1e-9) & (left <= 0.0))  # within the data: no effect
    assert np.array_equal(spread([np.full(3, np.nan)], 3), np.zeros(3))


def test_the_plots_options_are_sent_once_and_flat_data_gets_an_axis_it_can_label():
    """Every plot's last series, not drawn, spreads the data its y axis is ranged on; the
    options are never sent again (viser builds a chart anew for new options, and one built
    while its data streams in kept a time window the data had left: a blank plot), and the
    padding is given (viser's default made it build the chart anew at every change of the
    panel's width)."""
    from types import SimpleNamespace
    from unittest.mock import MagicMock

    from joint_space_control.dashboard.page import (
        PLOT_AXES,
        PLOT_PADDING,
        PLOT_SCALES,
        RobotInfo,
        RobotPanel,
    )

    plots = []

    def add_uplot(data, series, **options):
        plots.append(SimpleNamespace(data=data, series=series, **options))
        return plots[-1]

    server = MagicMock()
    server.gui.add_uplot.side_effect = add_uplot
    info = RobotInfo("", "robot", JOINTS, None, effort_limits=(2000.0, 1000.0))
    panel = RobotPanel(server, MagicMock(), info, MagicMock(), budget=400)
    assert len(plots) == 3 * len(JOINTS)
    t = np.linspace(10.0, 20.0, 1001)
    q = np.column_stack((np.full_like(t, -0.3) + 1e-10 * np.sin(t), np.linspace(0.0, -0.3, 1001)))
    fields = ("q", "q_d", "error", "tau", "tau_feedback", "tau_model", "tau_gravity")
    panel.show_signals(t, {f: q for f in fields})
    for plot in plots:
        assert plot.scales is PLOT_SCALES and plot.axes is PLOT_AXES  # sent once
        assert plot.padding is PLOT_PADDING  # given: viser's default rebuilt the chart
        assert PLOT_AXES[1]["incrs"] == Y_INCREMENTS and "range" not in PLOT_SCALES.get("y", {})
        axis_series = plot.series[-1]
        assert axis_series["width"] == 0 and not axis_series["points"]["show"]  # not drawn
        assert len(plot.data) == len(plot.series)
    position_at_rest, position_moving = (np.column_stack(p.data[1:]) for p in plots[:2])
    assert np.ptp(position_at_rest) == pytest.approx(LEAST_SPAN)  # about -0.3
    assert np.mean(position_at_rest) == pytest.approx(-0.3)
    assert np.ptp(position_moving) == pytest.approx(0.3)  # left as it is


TOPICS = [
    ("/joint_states", ["sensor_msgs/msg/JointState"]),
    ("/sim_bridge/true_joint_states", ["sensor_msgs/msg/JointState"]),
    ("/arm/joint_states", ["sensor_msgs/msg/JointState"]),
    ("/pd_gravity_controller/config", ["std_msgs/msg/String"]),
    ("/pd_gravity_controller/state", ["std_msgs/msg/Float64MultiArray"]),
    ("/arm/inverse_dynamics_controller/config", ["std_msgs/msg/String"]),
    ("/arm/inverse_dynamics_controller/state", ["std_msgs/msg/Float64MultiArray"]),
    ("/other/config", ["std_msgs/msg/String"]),  # no state: not a controller
    ("/wrong/joint_states", ["std_msgs/msg/String"]),
]


def test_robots_and_controllers_are_found_from_topic_names_and_types():
    robots = graph.robot_topics(TOPICS)
    assert robots == {"": "/joint_states", "/arm": "/arm/joint_states"}
    assert graph.controller_nodes(TOPICS) == [
        "/arm/inverse_dynamics_controller",
        "/pd_gravity_controller",
    ]
    subs = [("/arm/reference", [graph.TRAJECTORY]), ("/arm/joint_states", [graph.JOINT_STATE])]
    assert graph.robot_of(subs, robots) == "/arm"
    assert graph.topic_of(subs, graph.TRAJECTORY) == "/arm/reference"
    assert graph.robot_of([("/x", [graph.JOINT_STATE])], robots) is None
    assert graph.split_name("/arm/ctl") == ("ctl", "/arm")
    assert graph.split_name("/ctl") == ("ctl", "/")
    assert graph.parameter_prefix("/arm", ["iiwa", "arm"]) == "arm."
    assert graph.parameter_prefix("", []) == ""


def test_the_camera_looks_at_the_robots_and_sees_every_corner():
    from joint_space_control.dashboard.page import frame_camera

    boxes = [
        (np.array([-0.2, -0.2, 0.0]), np.array([0.2, 0.2, 1.3])),
        (np.array([2.0, -0.1, 0.0]), np.array([4.2, 0.1, 0.2])),
    ]
    position, look_at = frame_camera(boxes)
    assert np.allclose(look_at, [2.0, 0.0, 0.65])
    axis = (look_at - position) / np.linalg.norm(look_at - position)
    corners = [
        np.array([x, y, z])
        for lo, hi in boxes
        for x in (lo[0], hi[0])
        for y in (lo[1], hi[1])
        for z in (lo[2], hi[2])
    ]
    for corner in corners:  # within viser's 50° vertical field of view, in front
        ray = corner - position
        angle = np.degrees(np.arccos(ray @ axis / np.linalg.norm(ray)))
        assert angle < 25.0 + 1e-9, (corner, angle)
    assert position[2] > look_at[2]  # from above


def test_a_client_that_says_nothing_is_one_line_in_the_log_not_three_tracebacks(caplog):
    """A TCP connection closed before its HTTP request (a port probe) made the web server
    log three chained tracebacks (found by jsc soak --faults); the page's filter keeps the
    line and the first cause's reason."""
    import logging

    from joint_space_control.dashboard.page import WEB_SERVER_LOGGER, OneLineErrors

    logger = logging.getLogger(WEB_SERVER_LOGGER + ".test")
    logger.addFilter(OneLineErrors())
    try:
        try:
            try:
                raise EOFError("stream ends after 0 bytes, before end of line")
            except EOFError as first:
                raise EOFError("connection closed while reading HTTP request line") from first
        except EOFError as second:
            raise ValueError("did not receive a valid HTTP request") from second
    except ValueError:
        with caplog.at_level(logging.ERROR, logger=logger.name):
            logger.error("opening handshake failed", exc_info=True)
    (record,) = caplog.records
    assert record.exc_info is None and "\n" not in caplog.text.strip()
    assert record.getMessage() == (
        "opening handshake failed: EOFError: stream ends after 0 bytes, before end of line"
    )
