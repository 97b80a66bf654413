"""The scenario format: what an experiment is, as a file, before anything runs. :mod:`format`
reads ``config/experiments/*.yaml`` into a
:class:`~joint_space_control.workbench.experiments.scenarios.format.Scenario` (the robot or the
world of
several, the controller and its parameters, the reference, timed changes, the variants of a
sweep or a grid, the checks and figures it asks for) and refuses a malformed one with a line
that names the key, so that a typo fails at ``jsc experiment --list`` rather than an hour
into a sweep; :mod:`params_file` lays a ROS 2 parameter file (``--params-file``, e.g. the
gains ``jsc tune`` wrote) over a scenario's controller parameters, read as rcl reads it for
one node. No ROS here: the values themselves are checked by the nodes when they start, as any
parameter file's would be.
"""
