"""The process harness: real node processes, started and stopped the way a launch file would,
and the clients that drive them from outside. :mod:`processes` starts each node as its own
``python -m`` process in an isolated ROS domain and never lets one outlive its parent;
:mod:`domains` leases each run a domain id no other run on the machine holds, so concurrent
runs never see each other's nodes; :mod:`client` and :mod:`probe` are the client nodes that
wait on the graph, call services and set parameters; :mod:`loop` wires them into a lockstep
:class:`~joint_space_control.processes.loop.ClosedLoop`, started paused so that the
same inputs give the same run however loaded the machine is. A loop knows a run only as
the robots it holds
(:class:`~joint_space_control.workbench.experiments.scenarios.format.RobotSetup`:
description, plant, controller and their parameters), never what a scenario asks or how a
check judges it: the ROS engine of :mod:`~joint_space_control.workbench.experiments.execution`,
``jsc bench``, ``jsc soak``, ``make demo`` and the integration tests all start their nodes
through this one harness.
"""
