"""The workbench: what a student or researcher explores the laws with.

``experiments`` (``jsc experiment``: the theory's questions as scenario files, run on the
nodes or in process, judged against the theory, written up as the results page) and
``tuning`` (``jsc tune``: gains that meet a step-response specification, found by an
Optuna study). It depends on the product only; the lab depends on it.
"""
