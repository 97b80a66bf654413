"""Experiments: the theory's questions asked of real runs, and the machinery that runs them.

One layer of the package (test/unit/test_layers.py), its modules grouped by job, each job a
subpackage: :mod:`~joint_space_control.processes` starts and drives node processes
(the lockstep ``ClosedLoop``); :mod:`~joint_space_control.workbench.experiments.scenarios` reads
the
scenario files; :mod:`~joint_space_control.workbench.experiments.execution` turns a scenario's
variants
into recorded, analysed runs on either engine (node processes, or the same objects in
process); :mod:`~joint_space_control.workbench.experiments.judging` sets every measured number
beside
the theory's prediction; :mod:`~joint_space_control.workbench.experiments.presentation` draws the
figures and writes the summaries and the results page. At the top sit the entry points of the
commands built on them: :mod:`~joint_space_control.workbench.experiments.experiment`
(``jsc experiment``: runs, checks, figures), :mod:`~joint_space_control.lab.soaks.soak`
(``jsc soak``) and :mod:`~joint_space_control.processes.demo` (``make demo``).
"""
