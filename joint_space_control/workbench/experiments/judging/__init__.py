"""Judging runs against the theory: every measured number set beside the prediction it is
checked against, with a verdict and the tolerance that gave it. :mod:`theory` holds the
checks of THEORY.md §5's experiments (final error, the PD offset, gravity bounds, the
second-order response, …) and the registry of every check a scenario's ``checks`` can name;
:mod:`practical` the checks of §4's practical specifications (disturbances, the sampled loop,
bandwidth, measurement noise, friction, repeatability); :mod:`outcome` what a check sees of a
run (:class:`~joint_space_control.workbench.experiments.judging.outcome.RunView`) and what it says
(:class:`~joint_space_control.workbench.experiments.judging.outcome.Outcome`); :mod:`boundaries`
the
theory's curves on a grid's heat maps (K_P = α, the saturation onset of ω_n), which the
``saturation_boundary`` check judges too. Pure: metrics, recorded states and the robot model
in, outcomes out; no ROS, so the judgement of a run can be redone and tested on synthetic
runs.
"""
