"""``jsc tune``: gains meeting a step-response specification, by an Optuna study of lockstep
runs (problem, search space, study, outputs, figures; session wires them)."""
