"""Numeric ranges, declared once in the ParamSpec tables: carried by the ROS descriptor
(``floating_point_range``/``integer_range``, what rqt_reconfigure and the dashboard draw
sliders from), enforced by :meth:`ParamSpec.check` on one value and on each value of a
per-joint list, refused at runtime by a node with the old value kept, and wide enough for
every value the shipped parameter files and scenarios set."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rclpy
import yaml
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter

from joint_space_control.nodes.pd_gravity_controller import PDGravityControllerNode
from joint_space_control.nodes.reference import parameter_files
from joint_space_control.processes.domains import lease_domain
from joint_space_control.ros.parameters import ParamSpec, declare, descriptor_range
from joint_space_control.workbench.experiments.scenarios import format as scenarios
from sim_bridge.parameters import prefixed
from test.unit.test_parameter_docs import CONFIG, NODES, flat

ZETA = ParamSpec("zeta", 1.0, "damping ratio", dynamic=True, minimum=0.0, maximum=10.0)
RATE = ParamSpec("rate", 1000.0, "rate", unit="Hz", minimum=0.0, exclusive=True, maximum=1e5)
COUNTS = ParamSpec("counts", 0.0, "counts", dynamic=True, minimum=0.0, maximum=1e9, step=1.0)
SEED = ParamSpec("seed", 0, "seed", minimum=0.0, maximum=1000.0, step=1.0)
TIME = ParamSpec("pause_at", 0.0, "a moment", unit="s", minimum=0.0)


def numeric(specs):
    return [s for s in specs if s.type in ("number", "numbers")]


# -- the descriptor ------------------------------------------------------------------------
def test_a_ranged_spec_puts_its_range_in_the_descriptor():
    (fp,) = descriptor_range(ZETA)["floating_point_range"]
    assert (fp.from_value, fp.to_value, fp.step) == (0.0, 10.0, 0.0)
    (fp,) = descriptor_range(COUNTS)["floating_point_range"]
    assert (fp.from_value, fp.to_value, fp.step) == (0.0, 1e9, 1.0)
    # an exclusive minimum is still the range's from_value (ROS ranges are inclusive)
    (fp,) = descriptor_range(RATE)["floating_point_range"]
    assert (fp.from_value, fp.to_value) == (0.0, 1e5)
    (ir,) = descriptor_range(SEED)["integer_range"]
    assert (ir.from_value, ir.to_value, ir.step) == (0, 1000, 1)


def test_a_minimum_only_spec_has_no_range():
    assert descriptor_range(TIME) == {}
    assert descriptor_range(ParamSpec("robot", "planar_2dof", "text")) == {}


def test_the_constraints_text_says_the_whole_range():
    assert ZETA.constraints == ">= 0, <= 10, one value or one per joint"
    assert RATE.bound == "> 0, <= 100000"
    assert COUNTS.bound == ">= 0, <= 1e+09, step 1"
    assert TIME.bound == ">= 0"


# -- check() -------------------------------------------------------------------------------
def test_the_maximum_is_enforced_on_one_value_and_on_each_value_of_a_list():
    assert ZETA.check(10.0, 2).tolist() == [10.0, 10.0]  # the end itself is in the range
    with pytest.raises(ValueError, match=r"'zeta' must be >= 0 and <= 10, got \[12.0\]"):
        ZETA.check([12.0])
    with pytest.raises(ValueError, match=r"'zeta' must be >= 0 and <= 10, got \[0.9, 12.0\]"):
        ZETA.check([0.9, 12.0], 2)
    with pytest.raises(ValueError, match=r"'rate' must be a number > 0 and <= 100000, got"):
        RATE.check(2e5)
    with pytest.raises(ValueError, match="'rate' must be finite"):
        RATE.check(math.inf)


def test_a_step_puts_the_values_on_its_grid():
    assert COUNTS.check([4096, 65536.0], 2).tolist() == [4096.0, 65536.0]
    assert COUNTS.check(4096.000001, 1).tolist() == [4096.000001]  # within rclpy's 1e-6
    with pytest.raises(ValueError, match="'counts' must be >= 0 and <= 1e.09 on a step of 1"):
        COUNTS.check([4096.0, 4096.5], 2)
    assert SEED.check(7) == 7.0
    with pytest.raises(ValueError, match="on a step of 1"):
        SEED.check(2.5)
    # continuous parameters take any value in their range (scenarios set ζ = 0.95)
    assert ZETA.check(0.95, 1).tolist() == [0.95]


# -- every declared parameter ----------------------------------------------------------------
@pytest.mark.parametrize("node", list(NODES))
def test_every_numeric_default_lies_within_its_declared_range(node):
    for spec in numeric(NODES[node]):
        defaults = np.ravel(np.asarray(spec.default, dtype=float))
        if spec.minimum is not None:
            assert np.all(defaults >= spec.minimum), (node, spec.name)
        if spec.maximum is not None:
            assert np.all(defaults <= spec.maximum), (node, spec.name)
            assert spec.minimum is None or spec.minimum < spec.maximum, (node, spec.name)
        if spec.ranged:
            (rng,) = next(iter(descriptor_range(spec).values()))
            assert (rng.from_value, rng.to_value) == (spec.minimum, spec.maximum)


def test_most_numeric_parameters_carry_a_range():
    """Not vacuous: the sliders exist. Those without one are positions (the URDF's joint
    limits bound them), the base pose, CPU numbers, moments on the run's clock and sizes."""
    # the loop's nodes (the dashboard's own settings are not sliders of the page)
    loop = {node: specs for node, specs in NODES.items() if node != "dashboard"}
    unranged = {s.name for specs in loop.values() for s in numeric(specs) if not s.ranged}
    assert unranged == {
        "initial_positions",
        "base_position",
        "base_rpy",
        "cpu_affinity",
        "pause_at",
        "wrench_start",
        "target",
        "center",
        "waypoints",
        "waypoint_times",
        "min_free_space_mb",
    }


def _check(specs: dict[str, ParamSpec], values: dict, where: str) -> int:
    checked = 0
    for name, value in values.items():
        spec = specs.get(name)
        if spec is None or spec.type not in ("number", "numbers"):
            continue
        if isinstance(value, list) and not value:
            continue  # empty: "not given"
        try:
            spec.check(value)
        except ValueError as err:
            raise AssertionError(f"{where}: {err}") from err
        checked += 1
    return checked


@pytest.mark.parametrize("path", sorted(CONFIG.glob("*.yaml")), ids=lambda p: p.name)
def test_every_value_of_the_parameter_files_is_within_its_range(path):
    (node,) = [n for n in NODES if path.name in parameter_files(n)]
    for entry in yaml.safe_load(path.read_text()).values():
        values = flat(entry["ros__parameters"])
        robots = values.get("robots", []) if node == "sim_bridge" else []
        specs = {s.name: s for s in NODES[node]}
        specs |= {s.name: s for name in robots for s in prefixed(name)}
        assert _check(specs, values, path.name) > 0


CONTROLLER = {s.name: s for s in NODES["pd_gravity_controller"]}
CONTROLLER |= {s.name: s for s in NODES["inverse_dynamics_controller"]}
PLANT = {s.name: s for s in NODES["sim_bridge"]}
GENERATOR = {s.name: s for s in NODES["trajectory_generator"]}


@pytest.mark.parametrize("name", sorted(scenarios.available()))
def test_every_value_a_scenario_sets_is_within_its_range(name):
    """Every run of every variant (the grids' corners and all between), every scheduled
    change; the reference's settings where they are the trajectory generator's."""
    checked = 0
    for label, run in scenarios.load(name).runs():
        where = f"{name}/{label}"
        for setup in run.setups():
            checked += _check(PLANT, {**run.plant, **setup.plant}, where)
            checked += _check(CONTROLLER, setup.parameters, where)
            checked += _check(GENERATOR, setup.reference, where)
        for change in run.changes:
            checked += _check(PLANT, change.plant, where)
            checked += _check(CONTROLLER, change.controller, where)
    assert checked > 0


# -- a node --------------------------------------------------------------------------------
@pytest.fixture
def context(request):
    """A context of its own domain, with ``-p kp:=[100.0, 50.0]`` (or the ``--ros-args`` a
    test gives through indirect parametrization)."""
    args = getattr(request, "param", ["-p", "kp:=[100.0, 50.0]"])
    lease = lease_domain()
    ctx = Context()
    rclpy.init(args=["--ros-args", *args], context=ctx, domain_id=lease.domain_id)
    try:
        yield ctx
    finally:
        rclpy.shutdown(context=ctx)
        lease.release()


def test_a_node_refuses_a_double_out_of_range_and_keeps_the_old_value(context):
    node = Node("ranges", context=context, start_parameter_services=False)
    try:
        declare(node, [ZETA, RATE])
        (fp,) = node.describe_parameter("zeta").floating_point_range
        assert (fp.from_value, fp.to_value) == (0.0, 10.0)
        assert node.describe_parameter("zeta").additional_constraints.startswith(">= 0, <= 10")
        (result,) = node.set_parameters([Parameter("zeta", value=12.0)])
        assert result.successful is False
        assert "zeta" in result.reason and "Max: 10.0" in result.reason
        assert node.get_parameter("zeta").value == 1.0
        (result,) = node.set_parameters([Parameter("zeta", value=0.95)])
        assert result.successful and node.get_parameter("zeta").value == 0.95
    finally:
        node.destroy_node()


def test_a_controller_refuses_a_per_joint_list_out_of_range_and_keeps_the_old_gains(context):
    """rclpy does not check arrays against a range: the node's on-set callback does (check);
    every refusal, rclpy's too, is counted in ``rejected.parameters``."""
    node = PDGravityControllerNode(context=context, start_parameter_services=False)
    try:
        before = node.config
        (result,) = node.set_parameters([Parameter("kp", value=[100.0, 2e6])])
        assert result.successful is False
        assert "'kp' must be >= 0 and <= 1e+06" in result.reason
        assert list(node.get_parameter("kp").value) == [100.0, 50.0]
        assert node.config is before
        # a double out of range is refused by rclpy before the callback: counted all the same
        (result,) = node.set_parameters([Parameter("zeta", value=12.0)])
        assert result.successful is False and "Max: 10.0" in result.reason
        assert node.config is before and node.counts["rejected.parameters"] == 2
    finally:
        node.close()
        node.destroy_node()


@pytest.mark.parametrize("context", [["-p", "rate:=250"]], indirect=True)
def test_a_whole_number_for_a_double_is_taken_at_start_and_at_runtime(context):
    """``rate: 250`` in a params file or ``-p rate:=250`` is an INTEGER to rclpy, which
    refused it for a DOUBLE parameter (the node stopped); ``ros2 param set ... rate 300``
    too. Both are taken as doubles; an integer parameter stays one, a string is refused."""
    node = Node("whole", context=context, start_parameter_services=False)
    try:
        declare(node, [RATE, SEED])
        rate = node.get_parameter("rate")
        assert rate.type_ == Parameter.Type.DOUBLE and rate.value == 250.0
        (result,) = node.set_parameters([Parameter("rate", value=300)])
        assert result.successful, result.reason
        assert node.get_parameter("rate").type_ == Parameter.Type.DOUBLE
        assert node.get_parameter("rate").value == 300.0
        (result,) = node.set_parameters([Parameter("seed", value=7)])
        assert result.successful and node.get_parameter("seed").value == 7
        assert node.get_parameter("seed").type_ == Parameter.Type.INTEGER
        (result,) = node.set_parameters([Parameter("rate", value="fast")])
        assert result.successful is False and node.get_parameter("rate").value == 300.0
    finally:
        node.destroy_node()
