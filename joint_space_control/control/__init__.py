"""The controllers themselves, without ROS: configuration, state and one ``step``.

Each controller is a plain object (as control_toolbox keeps ``Pid`` apart from ``PidROS``):
:class:`~joint_space_control.control.controller.Controller` holds the reference schedule,
the restart logic, the gain design at the first measured configuration, the non-finite gate
and the clamp to the effort limits; the concrete controllers add their law and its state
(integrator, caches). The nodes (:mod:`joint_space_control.nodes`), ``jsc bench``, the
property tests and in-process closed loops all drive these very objects.
"""
