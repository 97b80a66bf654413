"""Running runs: a scenario's variants turned into recorded, analysed runs, on either engine.
:mod:`runner` makes each variant a run (its parameter files, its bag, its ``report/``) and
hands it as a picklable task to a
:class:`~joint_space_control.workbench.experiments.execution.distributed.RunPool`
(:mod:`distributed`:
threads here, or the workers of a Dask cluster, with one retry and a cancellation that stops
every node); a run executes on the ROS engine (the node processes of
:mod:`~joint_space_control.processes`) or on :mod:`inprocess`, the same plant,
controller objects and recording in one process with no ROS graph. Because a lockstep run
does not depend on timing, both engines must give the same numbers to the last bit;
:mod:`equivalence` says where two experiments differ, leaving out only what the recording's
clock decides. :mod:`values` gives a run's parameter values as its nodes hold them (the
declared defaults under the scenario's) and the models they build, so that the engine, the
checks and the boundaries never type a default twice.
"""
