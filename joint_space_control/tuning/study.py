r"""The Optuna study of ``jsc tune``: ask, run, judge, tell. No ROS here: a trial's run goes
through ``submit(label, scenario, run_dir) -> Future[list[RunResult]]`` (the CLI's Dask pool
with ``execute_run``; a stand-in in the unit tests).

- Sampler: TPE (seeded; ``constant_liar`` so that the trials in flight together differ), with
  the specification's clauses as constraints: clause k's normalised violation
  c_k = (value − bound)/|bound| (``<=``; the other way round for ``>=``), ≤ 0 when met
  (analysis/spec.py), set on each trial before it is told (``Trial.set_constraint``, what
  Optuna 5 has in place of the sampler's deprecated ``constraints_func``). TPE models
  feasible and infeasible trials apart.
- Objective (minimised): max_k c_k, the worst clause's normalised violation. It is defined
  for every run, met or not, so it leads the search towards the specification while none
  meets it, and once some do it maximises the smallest margin (the design furthest inside
  the specification, not one on its edge).
- Storage: any Optuna storage URL (``sqlite:///<out>/study.db``), ``load_if_exists``: a study
  interrupted resumes; ``trials`` counts the finished trials (complete, or failed runs), so a
  resumed study runs only what is missing. Trials left running by a killed session and the
  ones Ctrl-C interrupts are failed with ``interrupted`` and not counted.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from pathlib import Path
from typing import Any

import optuna
import yaml
from optuna.trial import FrozenTrial, TrialState

from joint_space_control.analysis.spec import Judgement, fmt_value, judge
from joint_space_control.tuning.problem import TuneProblem
from joint_space_control.tuning.space import SearchSpace

Submit = Callable[[str, Any, Path], Future]

INTERRUPTED = "interrupted"
#: The random trials TPE starts with: a quarter of the budget, between 4 and 10.
MIN_STARTUP, MAX_STARTUP = 4, 10


def startup_trials(trials: int) -> int:
    return max(MIN_STARTUP, min(MAX_STARTUP, trials // 4))


class SettingsMismatchError(ValueError):
    """The stored study was made for another robot, specification or search space."""


def open_study(
    storage: str, name: str, seed: int, trials: int, settings: dict[str, Any]
) -> optuna.Study:
    """Create the study, or load it (``load_if_exists``) when ``settings`` (robot, controller,
    spec, space, step, duration) are those it was made with; raises
    :class:`SettingsMismatchError` otherwise. The sampler's seed is ``seed`` plus the number of
    trials already stored, so that a resumed study does not draw its first points again."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(
        storage=storage, study_name=name, direction="minimize", load_if_exists=True
    )
    stored = study.user_attrs.get("settings")
    if stored is None:
        study.set_user_attr("settings", settings)
    elif stored != settings:
        keys = set(stored) | set(settings)
        changed = sorted(k for k in keys if stored.get(k) != settings.get(k))
        raise SettingsMismatchError(
            f"study '{name}' in {storage} was made with other settings ({', '.join(changed)}: "
            f"{', '.join(f'{k}={stored.get(k)!r}' for k in changed)}); use another --study or "
            "--out, or the same options"
        )
    study.sampler = optuna.samplers.TPESampler(
        seed=seed + len(study.trials),
        n_startup_trials=startup_trials(trials),
        multivariate=True,
        constant_liar=True,
    )
    return study


def objective(judgement: Judgement) -> float:
    """What the study minimises: Σ of the positive normalised violations over clauses and
    joints while the spec is not met (every joint counts, so progress on one is seen while
    another is still the worst), else the worst clause's violation (≤ 0: minus the smallest
    margin). Continuous where a run comes to meet the spec (both are 0 there)."""
    return judgement.excess if judgement.excess > 0.0 else judgement.worst


def is_finished(trial: FrozenTrial) -> bool:
    """Counts towards ``--trials``: complete, or a run that failed (not an interruption)."""
    if trial.state == TrialState.COMPLETE:
        return True
    return trial.state == TrialState.FAIL and not trial.user_attrs.get(INTERRUPTED, False)


def fail_stale(study: optuna.Study) -> int:
    """Fail the trials a killed session left running (one ``jsc tune`` per study at a time);
    how many."""
    stale = [t for t in study.trials if t.state == TrialState.RUNNING]
    for t in stale:
        study._storage.set_trial_user_attr(t._trial_id, INTERRUPTED, True)
        study.tell(t.number, state=TrialState.FAIL)
    return len(stale)


def is_feasible(trial: FrozenTrial) -> bool:
    return trial.state == TrialState.COMPLETE and all(c <= 0.0 for c in trial.constraints.values())


def best_trial(study: optuna.Study) -> FrozenTrial | None:
    """The feasible trial with the lowest objective, else (none feasible) the complete trial
    closest to the specification (lowest objective); None without a complete trial."""
    complete = [t for t in study.trials if t.state == TrialState.COMPLETE]
    feasible = [t for t in complete if is_feasible(t)]
    pool = feasible or complete
    return min(pool, key=lambda t: (t.value, t.number)) if pool else None


def trial_dir(out: Path, number: int) -> Path:
    return out / "trials" / f"trial_{number:04d}"


def run_trials(
    study: optuna.Study,
    space: SearchSpace,
    problem: TuneProblem,
    submit: Submit,
    out: Path,
    trials: int,
    in_flight: int,
    log: Callable[[str], None] = print,
) -> int:
    """Ask and run trials, ``in_flight`` at a time, until ``trials`` are finished; how many
    this call finished. On KeyboardInterrupt the trials in flight are failed (marked
    ``interrupted``) and the interrupt propagates (the caller cancels its pool)."""
    finished = sum(is_finished(t) for t in study.trials)
    distributions = space.distributions()
    pending: dict[Future, tuple[optuna.Trial, float]] = {}
    asked: list[optuna.Trial] = []  # asked, not yet told
    done_here = 0
    try:
        while finished + len(pending) < trials or pending:
            while len(pending) < max(1, in_flight) and finished + len(pending) < trials:
                trial = study.ask(distributions)
                asked.append(trial)
                target = trial_dir(out, trial.number)
                if target.exists():  # a trial number of an earlier, deleted study
                    shutil.rmtree(target)
                target.mkdir(parents=True)
                gains = space.node_gains(trial.params)
                data = problem.scenario_data(gains, title=f"trial {trial.number}")
                (target / "scenario.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
                scenario = problem.scenario(
                    gains, f"trial_{trial.number:04d}", target / "scenario.yaml"
                )
                trial.set_user_attr("run_dir", str(target))
                omega, zeta = space.second_order(trial.params)
                trial.set_user_attr("omega_n", omega.tolist())
                trial.set_user_attr("zeta", zeta.tolist())
                pending[submit(f"trial {trial.number}", scenario, target)] = (
                    trial,
                    time.monotonic(),
                )
            done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for future in done:
                trial, started = pending.pop(future)
                trial.set_user_attr("seconds", time.monotonic() - started)
                _tell(study, problem, trial, future, log)
                asked.remove(trial)
                finished += 1
                done_here += 1
                log(f"  {finished}/{trials} finished")
    except BaseException:
        for trial in asked:
            trial.set_user_attr(INTERRUPTED, True)
            study.tell(trial, state=TrialState.FAIL, skip_if_finished=True)
        raise
    return done_here


def _tell(
    study: optuna.Study,
    problem: TuneProblem,
    trial: optuna.Trial,
    future: Future,
    log: Callable[[str], None],
) -> None:
    gains = _gains_text(trial)
    try:
        results = future.result()
        errors = [r.error for r in results if r.error]
        if errors:
            raise RuntimeError(errors[0])
        judgement = judge(problem.spec, results[0].controller)
    except Exception as err:  # noqa: BLE001 - a failed run is a failed trial, the study goes on
        reason = f"{type(err).__name__}: {err}".splitlines()[0][:300]
        trial.set_user_attr("error", reason)
        study.tell(trial, state=TrialState.FAIL)
        log(f"trial {trial.number}: {gains}: run FAILED: {reason}")
        return
    trial.set_user_attr("values", [m.value for m in judgement.values])
    trial.set_user_attr("joints", [m.joint for m in judgement.values])
    trial.set_user_attr("violations", list(judgement.violations))
    for k, (clause, joints) in enumerate(
        zip(problem.spec.clauses, judgement.by_joint, strict=True)
    ):
        for joint, violation in joints.items():
            trial.set_constraint(f"{k}:{clause}@{joint}", violation)
    study.tell(trial, objective(judgement))
    verdict = "meets the spec" if judgement.met else "misses the spec"
    log(
        f"trial {trial.number}: {gains}: {verdict} (objective {objective(judgement):+.3g}); "
        f"{_values_text(problem, judgement)}"
    )


def _gains_text(trial: optuna.Trial | FrozenTrial) -> str:
    omega = trial.user_attrs.get("omega_n", [])
    zeta = trial.user_attrs.get("zeta", [])
    return (
        "ω_n = ["
        + ", ".join(f"{w:.3g}" for w in omega)
        + "] rad/s, ζ = ["
        + ", ".join(f"{z:.3g}" for z in zeta)
        + "]"
    )


def _values_text(problem: TuneProblem, judgement) -> str:
    return ", ".join(
        f"{clause.metric} {fmt_value(m.value, clause.unit)}"
        for clause, m in zip(problem.spec.clauses, judgement.values, strict=True)
    )
