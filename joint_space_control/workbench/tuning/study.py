r"""The Optuna study of ``jsc tune``: ask, run, judge, tell. No ROS here: a trial's run goes
through ``submit(label, scenario, run_dir) -> Future[list[RunResult]]`` (the CLI's Dask pool
with ``execute_run``; a stand-in in the unit tests).

- Sampler: TPE (seeded; ``constant_liar`` so that the trials of a batch differ), with
  the specification's clauses as constraints: clause k's normalised violation
  c_k = (value − bound)/|bound| (``<=``; the other way round for ``>=``), ≤ 0 when met
  (analysis/spec.py), set on each trial before it is told (``Trial.set_constraint``, what
  Optuna 5 has in place of the sampler's deprecated ``constraints_func``). TPE models
  feasible and infeasible trials apart.
- Objective (minimised): max_k c_k, the worst clause's normalised violation. It is defined
  for every run, met or not, so it leads the search towards the specification while none
  meets it, and once some do it maximises the smallest margin (the design furthest inside
  the specification, not one on its edge).
- Order: a seeded study is reproducible, the same trials with the same values in the same
  order whatever the number of workers and whichever run finishes first. What TPE suggests
  depends on what the study holds when a trial is asked: the trials told (their values and
  constraints) and, with ``constant_liar``, the ones still running. Telling each trial as its
  run finished, and asking the next one then, made both depend on the machine: on a pool of
  2, trial 4 was asked with three of trials 0–3 told and the fourth running, which one the
  runs decided (on 1 worker: all four told). So the study goes in batches of ``batch`` trials
  (``BATCH``, ``--batch``), a number that is the study's, not the pool's: ask the batch's
  trials one after the other (the ones asked before a trial are running: the same lie at the
  same place every time), run them ``in_flight`` at a time in any order, wait for them all,
  then tell them in trial-number order (and log them so) before asking the next batch. Every
  ask then sees the same trials, and the sampler's seed and its random draws are consumed in
  the same order; a run's own numbers are the same anywhere (lockstep). The price: a batch
  waits for its slowest run, and the workers beyond ``batch`` idle; a trial is suggested
  knowing the batches before its own, not its own batch's finished runs.
- Storage: any Optuna storage URL (``sqlite:///<out>/study.db``), ``load_if_exists``: a study
  interrupted resumes; ``trials`` counts the finished trials (complete, or failed runs), so a
  resumed study runs only what is missing. Trials left running by a killed session and the
  ones Ctrl-C interrupts are failed with ``interrupted`` and not counted; the runs of the
  interrupted batch that had finished are told first (in order), so no finished run is
  lost. A resumed study is reproducible from what it holds (its seed is ``seed`` plus the
  trials stored), not equal to the study that was not interrupted.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import optuna
import yaml
from optuna.trial import FrozenTrial, TrialState

from joint_space_control.analysis.spec import Judgement, fmt_value, judge
from joint_space_control.workbench.tuning.problem import TuneProblem
from joint_space_control.workbench.tuning.space import SearchSpace

Submit = Callable[[str, Any, Path], Future]

INTERRUPTED = "interrupted"
#: The random trials TPE starts with: a quarter of the budget, between 4 and 10 (told; with
#: batches, the batch that reaches them is random to its end).
MIN_STARTUP, MAX_STARTUP = 4, 10
#: Trials asked, run and told together (``jsc tune --batch``): the study depends on it, not
#: on the number of workers; twice the default pool of 2, so each batch keeps it busy twice.
BATCH = 4


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
    trials already stored, so that a resumed study does not draw its first points again.
    ``constant_liar`` counts the running trials as the worst so far: under
    :func:`run_trials` those are the trials of the batch asked before, a given set, so the
    lie is the same on every run of the study and spreads the batch's trials apart."""
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


@dataclass(eq=False)
class _Run:
    """A trial of the batch: its scenario and directory, then its run's future, when it was
    submitted and when its run ended (the future's callback: also when no ``wait`` saw it
    yet), and whether it was told."""

    trial: optuna.Trial
    scenario: Any
    target: Path
    future: Future | None = None
    started: float = 0.0
    ended: float | None = None
    told: bool = False

    def finished(self) -> bool:
        """Its run ended (not cancelled): its result, or its failure, can be told."""
        return self.future is not None and self.future.done() and not self.future.cancelled()

    def seconds(self) -> float:
        """From its submission to the end of its run (now, if the future's callback, which
        Future runs after waking its waiters, has not yet)."""
        return (time.monotonic() if self.ended is None else self.ended) - self.started


def run_trials(
    study: optuna.Study,
    space: SearchSpace,
    problem: TuneProblem,
    submit: Submit,
    out: Path,
    trials: int,
    in_flight: int,
    log: Callable[[str], None] = print,
    batch: int = BATCH,
    plan: Callable[[optuna.Study], None] | None = None,
) -> int:
    """Run the study to ``trials`` finished trials, ``batch`` at a time (see the module's
    docstring): ask the batch's trials, run them ``in_flight`` at a time, then tell them in
    trial-number order; how many this call finished. Whatever stops it (KeyboardInterrupt:
    the caller then cancels its pool) the batch's runs that finished are still told, in
    order, the others failed and marked ``interrupted``, and the exception propagates.
    ``plan(study)``, called before each batch is asked, may enqueue trials from the ones
    told (the asks take enqueued trials first): a function of the study's contents, so the
    study stays reproducible."""
    if batch < 1:
        raise ValueError(f"the batch must be >= 1 trial, got {batch}")
    finished = sum(is_finished(t) for t in study.trials)
    distributions = space.distributions()
    runs: list[_Run] = []  # the batch
    done_here = 0

    def tell(run: _Run) -> None:
        nonlocal finished, done_here
        assert run.future is not None
        run.trial.set_user_attr("seconds", run.seconds())
        _tell(study, problem, run.trial, run.future, log)
        run.told = True
        finished += 1
        done_here += 1
        log(f"  {finished}/{trials} finished")

    try:
        while finished < trials:
            runs = []
            if plan is not None:
                plan(study)
            for _ in range(min(batch, trials - finished)):
                trial = study.ask(distributions)
                # in the batch before it is prepared: failed if preparing it fails
                runs.append(_Run(trial, None, trial_dir(out, trial.number)))
                runs[-1].scenario = _prepare(space, problem, trial, runs[-1].target)
            _run_batch(runs, submit, in_flight)
            for run in runs:  # in trial-number order, whichever run finished first
                tell(run)
    except BaseException:
        for run in runs:
            if run.told or _is_told(study, run.trial):
                continue
            if run.finished():  # its result is kept
                try:
                    tell(run)
                    continue
                except Exception:  # noqa: BLE001 - telling it failed: failed as the others
                    if _is_told(study, run.trial):
                        continue
            run.trial.set_user_attr(INTERRUPTED, True)
            study.tell(run.trial, state=TrialState.FAIL, skip_if_finished=True)
        raise
    return done_here


def _prepare(space: SearchSpace, problem: TuneProblem, trial: optuna.Trial, target: Path) -> Any:
    """The trial's directory, its ``scenario.yaml`` and its second-order numbers (user
    attributes); the scenario to run."""
    if target.exists():  # a trial number of an earlier, deleted study
        shutil.rmtree(target)
    target.mkdir(parents=True)
    gains = space.node_gains(trial.params)
    data = problem.scenario_data(gains, title=f"trial {trial.number}")
    (target / "scenario.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    scenario = problem.scenario(gains, f"trial_{trial.number:04d}", target / "scenario.yaml")
    trial.set_user_attr("run_dir", str(target))
    omega, zeta = space.second_order(trial.params)
    trial.set_user_attr("omega_n", omega.tolist())
    trial.set_user_attr("zeta", zeta.tolist())
    return scenario


def _run_batch(runs: list[_Run], submit: Submit, in_flight: int) -> None:
    """Run the batch, ``in_flight`` runs at a time in trial order (another one submitted as
    soon as one finishes, so no run waits in the pool's queue and a trial's ``seconds`` is
    its run's wall time), until every run ended; nothing is told here."""
    queue = list(runs)
    pending: set[Future] = set()
    while queue or pending:
        while queue and len(pending) < max(1, in_flight):
            run = queue.pop(0)
            run.started = time.monotonic()
            run.future = submit(f"trial {run.trial.number}", run.scenario, run.target)
            run.future.add_done_callback(lambda _, run=run: _ended(run))
            pending.add(run.future)
        _, pending = wait(pending, return_when=FIRST_COMPLETED)


def _ended(run: _Run) -> None:
    if run.ended is None:
        run.ended = time.monotonic()


def _is_told(study: optuna.Study, trial: optuna.Trial) -> bool:
    return study._storage.get_trial(trial._trial_id).state.is_finished()


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
