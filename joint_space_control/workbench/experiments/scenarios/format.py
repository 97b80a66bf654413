"""Experiment scenarios (``config/experiments/*.yaml``): loading and validation, no ROS.

A scenario names one question of THEORY.md §5 and everything needed to answer it by a run:

```yaml
title: PD + g(q) set-point                # one line for `jsc experiment --list`
question: 1                                # THEORY.md §5 experiment number
robot: planar_2dof
mode: lockstep                             # the only mode (reproducible runs)
duration: 4.0                              # simulated time [s]
short_duration: 1.0                        # CI form (`--short`)
plant: {initial_positions: [0, 0]}         # sim_bridge parameters
controller: pd_gravity_controller          # or inverse_dynamics_controller
parameters: {kp: [2000, 1000], kd: [900, 300]}
reference: {shape: step, target: [0.5, -0.3]}   # step | sinusoid | quintic | waypoints
changes:                                   # optional, at simulation times (lockstep)
  - {at: 4.0, controller: {gravity_compensation: full}}
  - {at: 8.0, plant: {payload_mass: 5.0}}
  - {at: 12.0, update: iterative_gravity}  # u ← u + K_P (q_d − q), from the measured q
figures: [overlay]                         # optional extra figures (presentation/figures.py)
variants:                                  # optional: one run per value (a sweep)
  name: omega                              # label of the swept quantity
  key: reference.omega                     # what each value replaces
  values: [0.5, 1.0, 2.0]
  short: [omega=0.5, omega=2]              # optional: the runs of the short form (default:
                                           # the first and the last)
  # or several settings per run:
  # runs: [{label: id, set: {parameters.law: inverse_dynamics, parameters.omega_n: 10}}]
  # (``controller: inverse_dynamics_controller`` in ``set`` switches the executable)
checks: [...]                              # theory checks, see judging/theory.py
```

A **grid** sweeps the product of two or more axes, in row-major order (the last axis varies
fastest), and draws one heat map per metric (workbench/experiments/presentation/sweep_figures.py):
the
first axis gives the rows (y), the second the columns (x), each further axis a row of panels
per value:

```yaml
variants:
  name: mismatch_x_stiffness               # optional (default: the axis names joined by ×)
  grid:
    - {key: parameters.model_mass_scale, values: [0.6, 0.8, 1.0, 1.2, 1.4],
       label: controller mass scale, unit: "×"}
    - {key: parameters.omega_n, values: [5, 10, 20, 40, 80], label: "ω_n", unit: rad/s,
       scale: log}                         # linear (default) | log: drawn evenly, labelled
    # name: defaults to the last part of the key; also: [other keys set to the same value],
    # e.g. {key: plant.payload_mass, also: [parameters.model_payload_mass], ...}
  boundary: saturation_onset               # optional: a theory boundary on every heat map
                                           # (judging/boundaries.py)
  short: [...]                             # optional run labels (default: the corners)
```

A grid run is labelled ``model_mass_scale=0.6,omega_n=5`` (``name=value`` per axis).

Several robots in one world (one ``sim_bridge``, docs/robots.md "Several robots") replace
``robot``, ``controller``, ``parameters`` and ``reference`` with ``robots``, a mapping from
each robot's name (the namespace of its topics and its controller) to its own settings;
``plant`` is then the world's sim_bridge parameters (``physics_rate``, …), and every check
judges each robot as it would a run of its own:

```yaml
robots:
  iiwa: {robot: iiwa, plant: {initial_positions: [...]}, controller: pd_gravity_controller,
         parameters: {...}, reference: {shape: step, target: [...]}}
  arm: {robot: planar_2dof, plant: {base_position: [2.2, 0, 0]}, ...}
```

(no ``changes``, ``variants`` or ``figures`` with ``robots`` yet.)

Parameter names are the nodes' own (docs/parameters.md); a scenario is checked here for
structure and the values by the nodes when they start, as any parameter file would be.
"""

from __future__ import annotations

import copy
import itertools
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from joint_space_control.paths import experiments_dir
from joint_space_control.trajectories import shapes
from joint_space_control.trajectories.reference import Trajectory
from joint_space_control.workbench.experiments.judging import boundaries
from joint_space_control.workbench.experiments.presentation.figures import FIGURES

CONTROLLERS = ("pd_gravity_controller", "inverse_dynamics_controller")
UPDATES = ("iterative_gravity",)
_TOP_KEYS = {
    "title",
    "question",
    "robot",
    "mode",
    "duration",
    "short_duration",
    "plant",
    "controller",
    "parameters",
    "reference",
    "changes",
    "variants",
    "checks",
    "figures",
    "notes",
    "robots",
}
#: With ``robots``: what each robot of the world sets (``robot``, ``controller`` and
#: ``reference`` required), and the top-level keys that only one robot can have.
_ROBOT_KEYS = {"robot", "plant", "controller", "parameters", "reference"}
_ONE_ROBOT_KEYS = (
    "robot",
    "controller",
    "parameters",
    "reference",
    "changes",
    "variants",
    "figures",
)
_ROBOT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")  # sim_bridge's rule: a namespace


@dataclass(frozen=True)
class Change:
    """What happens at simulation time ``at`` [s]."""

    at: float
    controller: dict[str, Any] = field(default_factory=dict)
    plant: dict[str, Any] = field(default_factory=dict)
    update: str | None = None


SCALES = ("linear", "log")


@dataclass(frozen=True)
class Axis:
    """One axis of a grid: the setting ``key`` (and each of ``also``) takes each of
    ``values`` in turn. ``label`` and ``unit`` name it on the heat maps; on a ``log`` axis
    the values are drawn evenly spaced and the boundaries interpolated in log(value)."""

    key: str
    name: str
    label: str
    unit: str
    scale: str
    values: tuple[Any, ...]
    also: tuple[str, ...] = ()

    @property
    def keys(self) -> tuple[str, ...]:
        return (self.key, *self.also)

    def settings(self, value: Any) -> dict[str, Any]:
        """What a run at ``value`` sets: ``{key: value}`` for each of :attr:`keys`."""
        return {k: value for k in self.keys}

    @property
    def title(self) -> str:
        """``label [unit]`` (the heat maps' axis title)."""
        return f"{self.label} [{self.unit}]" if self.unit else self.label

    @property
    def numeric(self) -> bool:
        """Numbers in strictly monotonic order: positions between the values are defined."""
        if not all(_number(v) for v in self.values):
            return False
        d = np.diff(self._scaled(np.array(self.values, dtype=float)))
        return bool(np.all(d > 0) or np.all(d < 0))

    def _scaled(self, values: np.ndarray) -> np.ndarray:
        return np.log10(values) if self.scale == "log" else values

    def positions(self, values: Any) -> np.ndarray:
        """Where ``values`` lie along the drawn axis, whose k-th value is at k: piecewise
        linear in the value (in log10 of it on a log axis) between neighbouring grid values,
        extended linearly beyond the ends (NaN where the value cannot be placed: an
        unordered or non-numeric axis, a value ≤ 0 on a log axis)."""
        if not self.numeric:
            listed = values if isinstance(values, list | tuple) else [values]
            found = [next((k for k, v in enumerate(self.values) if v == x), None) for x in listed]
            return np.array([math.nan if k is None else k for k in found], dtype=float)
        x = np.atleast_1d(np.asarray(values, dtype=float))
        grid = self._scaled(np.array(self.values, dtype=float))
        with np.errstate(invalid="ignore", divide="ignore"):
            sx = self._scaled(x)
        if len(grid) == 1:
            return np.where(np.isclose(sx, grid[0]), 0.0, math.nan)
        order = np.argsort(grid)
        g, k = grid[order], np.arange(len(grid), dtype=float)[order]
        inside = np.interp(sx, g, k)
        low = k[0] + (sx - g[0]) * (k[1] - k[0]) / (g[1] - g[0])
        high = k[-1] + (sx - g[-1]) * (k[-1] - k[-2]) / (g[-1] - g[-2])
        out = np.where(sx < g[0], low, np.where(sx > g[-1], high, inside))
        return np.where(np.isfinite(sx), out, math.nan)

    def values_at(self, positions: Any) -> np.ndarray:
        """The inverse of :meth:`positions` on a numeric axis: the value at each position."""
        p = np.atleast_1d(np.asarray(positions, dtype=float))
        grid = self._scaled(np.array(self.values, dtype=float))
        if len(grid) == 1:
            scaled = np.full(p.shape, grid[0])
        else:
            k = np.arange(len(grid), dtype=float)
            scaled = np.interp(p, k, grid)
            scaled = np.where(p < 0, grid[0] + p * (grid[1] - grid[0]), scaled)
            last = len(grid) - 1
            scaled = np.where(p > last, grid[-1] + (p - last) * (grid[-1] - grid[-2]), scaled)
        return 10.0**scaled if self.scale == "log" else scaled


@dataclass(frozen=True)
class Variants:
    """A sweep: runs labelled ``label`` each setting ``{"section.name": value}``."""

    name: str
    runs: list[tuple[str, dict[str, Any]]]
    short: list[int]
    """Indices of the runs kept in the short (CI) form: the first and the last (a grid: its
    corners), or the ones ``variants.short`` names (a check that needs several runs of a
    group, say)."""
    axes: tuple[Axis, ...] = ()
    """A grid's axes (empty: a 1-D sweep or a list of runs)."""
    grid_index: tuple[tuple[int, ...], ...] = ()
    """A grid: each run's index along :attr:`axes`, in the order of :attr:`runs`."""
    boundary: str | None = None
    """A grid: the theory boundary drawn on its heat maps
    (workbench/experiments/judging/boundaries.py)."""

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a.values) for a in self.axes)

    def describe(self) -> str:
        """``5 runs``, or ``25 runs (5×5 grid)``."""
        runs = f"{len(self.runs)} runs"
        if self.axes:
            runs += f" ({'×'.join(str(n) for n in self.shape)} grid)"
        return runs


@dataclass(frozen=True)
class RobotSetup:
    """One robot of a run: its namespace ``name`` ("": the root, the one-robot scenario),
    description, plant (sim_bridge parameters), controller executable and parameters, and
    reference."""

    name: str
    robot: str
    plant: dict[str, Any]
    controller: str
    parameters: dict[str, Any]
    reference: dict[str, Any]


@dataclass(frozen=True)
class Scenario:
    name: str
    path: Path
    title: str
    question: int
    robot: str
    mode: str
    duration: float
    short_duration: float
    plant: dict[str, Any]
    controller: str
    parameters: dict[str, Any]
    reference: dict[str, Any]
    changes: list[Change]
    variants: Variants | None
    checks: list[dict[str, Any]]
    notes: str = ""
    figures: tuple[str, ...] = ()
    """Extra figures of the experiment (workbench/experiments/presentation/figures.py), beside the
    standard ones."""
    robots: tuple[RobotSetup, ...] = ()
    """Several robots in one world (each in its namespace); then ``robot`` and
    ``controller`` name them all joined by " + " (for listings), ``plant`` holds the world's
    parameters and ``parameters`` and ``reference`` are empty."""

    def setups(self) -> tuple[RobotSetup, ...]:
        """The robots of a run: the world's, or the one robot in the root namespace."""
        if self.robots:
            return self.robots
        return (
            RobotSetup(
                "", self.robot, self.plant, self.controller, self.parameters, self.reference
            ),
        )

    def of_robot(self, setup: RobotSetup) -> Scenario:
        """The one-robot scenario of ``setup`` in this world (named ``<name>/<robot name>``;
        its plant: the world's parameters and the robot's): what a check sees of it."""
        if not setup.name:
            return self
        return Scenario(
            **{
                **self.__dict__,
                "name": f"{self.name}/{setup.name}",
                "robot": setup.robot,
                "plant": {**self.plant, **setup.plant},
                "controller": setup.controller,
                "parameters": setup.parameters,
                "reference": setup.reference,
                "robots": (),
            }
        )

    def on_engine(self, engine: str) -> Scenario:
        """The scenario with its plant on the physics engine ``engine`` (sim_bridge's
        ``engine``, a world parameter: one robot's plant or a world's)."""
        return Scenario(**{**self.__dict__, "plant": {**self.plant, "engine": engine}})

    def run_duration(self, short: bool) -> float:
        return self.short_duration if short else self.duration

    def changes_within(self, duration: float) -> list[Change]:
        return [c for c in self.changes if c.at < duration]

    def with_settings(self, label: str, settings: dict[str, Any]) -> Scenario:
        """The scenario with ``{"section.name": value}`` applied (and no variants);
        ``controller`` (no section) replaces the controller executable."""
        data: dict[str, Any] = {
            "plant": copy.deepcopy(self.plant),
            "parameters": copy.deepcopy(self.parameters),
            "reference": copy.deepcopy(self.reference),
        }
        for key, value in settings.items():
            if key == "controller":
                data["controller"] = value
                continue
            section, _, name = key.partition(".")
            data[section][name] = value
        return Scenario(
            **{**self.__dict__, **data, "name": f"{self.name}/{label}", "variants": None}
        )

    def runs(self, short: bool = False) -> list[tuple[str, Scenario]]:
        """(label, scenario) of every run: one, or one per variant (the first and last in
        the short form)."""
        if self.variants is None:
            return [("run", self)]
        chosen = self.variants.short if short else range(len(self.variants.runs))
        return [
            (self.variants.runs[i][0], self.with_settings(*self.variants.runs[i])) for i in chosen
        ]


def _label(value: Any) -> str:
    if isinstance(value, list):
        return "_".join(_label(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _settings_key(key: str, what: str, value: Any = None) -> str:
    if key == "controller":
        if value not in CONTROLLERS:
            raise ValueError(f"{what}: 'controller' must be one of {CONTROLLERS}, got {value!r}")
        return key
    section, _, field_name = key.partition(".")
    if section not in ("plant", "parameters", "reference") or not field_name:
        raise ValueError(
            f"{what}: keys must be controller, plant.X, parameters.X or reference.X: {key!r}"
        )
    return key


def available() -> dict[str, Path]:
    """Installed scenarios (package data, see paths.py) by name, in name order."""
    return {p.stem: p for p in sorted(experiments_dir().glob("*.yaml"))}


def find(name_or_file: str) -> Path:
    path = Path(name_or_file)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        return path
    known = available()
    if name_or_file in known:
        return known[name_or_file]
    raise ValueError(
        f"no scenario {name_or_file!r}: use a YAML file or one of {', '.join(known) or 'none'}"
    )


def load(name_or_file: str) -> Scenario:
    path = find(name_or_file)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ValueError(f"{path}: cannot read the scenario: {err}") from err
    try:
        return parse(data, path.stem, path)
    except (TypeError, KeyError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from err


def _mapping(data: Any, what: str) -> dict[str, Any]:
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"'{what}' must be a mapping, got {data!r}")
    return dict(data)


def _time(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise ValueError(f"'{what}' must be a number > 0, got {value!r}")
    return float(value)


def parse(data: Any, name: str, path: Path) -> Scenario:
    data = _mapping(data, "scenario")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ValueError(f"unknown keys {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    robots = _robots(data)
    required = ("title", "question", "duration")
    if not robots:
        required += ("robot", "controller", "reference")
    for key in required:
        if key not in data:
            raise ValueError(f"missing '{key}'")
    duration = _time(data["duration"], "duration")
    short = _time(data.get("short_duration", min(duration, 1.0)), "short_duration")
    if robots:
        data = {
            **data,
            "robot": " + ".join(r.robot for r in robots),
            "controller": " + ".join(r.controller for r in robots),
            "reference": {},
        }
    elif data["controller"] not in CONTROLLERS:
        raise ValueError(f"'controller' must be one of {CONTROLLERS}, got {data['controller']!r}")
    mode = data.get("mode", "lockstep")
    if mode != "lockstep":
        raise ValueError(f"'mode' must be lockstep (the only reproducible one), got {mode!r}")
    changes = []
    for k, raw in enumerate(data.get("changes") or []):
        raw = _mapping(raw, f"changes[{k}]")
        extra = set(raw) - {"at", "controller", "plant", "update"}
        if extra:
            raise ValueError(f"changes[{k}]: unknown keys {sorted(extra)}")
        update = raw.get("update")
        if update is not None and update not in UPDATES:
            raise ValueError(f"changes[{k}]: 'update' must be one of {UPDATES}")
        changes.append(
            Change(
                _time(raw.get("at"), f"changes[{k}].at"),
                _mapping(raw.get("controller"), f"changes[{k}].controller"),
                _mapping(raw.get("plant"), f"changes[{k}].plant"),
                update,
            )
        )
    times = [c.at for c in changes]
    if times != sorted(set(times)):
        raise ValueError("'changes' must be at strictly increasing times")
    variants = None
    if data.get("variants") is not None:
        variants = _variants(_mapping(data["variants"], "variants"), data)
    scenario = Scenario(
        name=name,
        path=path,
        title=str(data["title"]),
        question=int(data["question"]),
        robot=str(data["robot"]),
        mode=mode,
        duration=duration,
        short_duration=short,
        plant=_mapping(data.get("plant"), "plant"),
        controller=data["controller"],
        parameters=_mapping(data.get("parameters"), "parameters"),
        reference=_mapping(data["reference"], "reference"),
        changes=changes,
        variants=variants,
        checks=[_mapping(c, "checks[]") for c in data.get("checks") or []],
        notes=str(data.get("notes", "")),
        figures=_figures(data.get("figures")),
        robots=robots,
    )
    for _, run in scenario.runs():
        for setup in run.setups():  # fails early on a bad reference
            try:
                build_reference(setup.reference, None, run.duration)
            except ValueError as err:
                if not setup.name:
                    raise
                raise ValueError(f"robots.{setup.name}: {err}") from None
    return scenario


_VARIANT_FORMS = ("key", "runs", "grid")


def _variants(v: dict[str, Any], data: dict[str, Any]) -> Variants:
    """``variants``: one key over values, a list of runs, or a grid of axes."""
    forms = [f for f in _VARIANT_FORMS if f in v]
    if len(forms) > 1:
        raise ValueError(f"'variants' takes one of key + values, runs or grid, got {forms}")
    if "boundary" in v and "grid" not in v:
        raise ValueError("'variants.boundary' needs a grid (it is drawn on the heat maps)")
    axes: tuple[Axis, ...] = ()
    index: tuple[tuple[int, ...], ...] = ()
    boundary = None
    name_ = str(v.get("name", "variant"))
    if "grid" in v:  # the product of the axes, row-major
        axes = _axes(v["grid"])
        name_ = str(v.get("name", " × ".join(a.name for a in axes)))
        index = tuple(itertools.product(*(range(len(a.values)) for a in axes)))
        runs = []
        for ks in index:
            picked = [(a, a.values[k]) for a, k in zip(axes, ks, strict=True)]
            label = ",".join(f"{a.name}={_label(x)}" for a, x in picked)
            runs.append((label, {k: x for a, x in picked for k in a.keys}))
        if v.get("boundary") is not None:
            boundary = str(v["boundary"])
            boundaries.validate(boundary, axes, data)
    elif "key" in v:  # one key, several values
        key = _settings_key(str(v["key"]), "variants.key")
        values = v.get("values")
        if not isinstance(values, list) or not values:
            raise ValueError("'variants.values' must be a non-empty list")
        runs = [(f"{name_}={_label(x)}", {key: x}) for x in values]
    else:  # several settings per run
        raw_runs = v.get("runs")
        if not isinstance(raw_runs, list) or not raw_runs:
            raise ValueError("'variants' needs key + values, or runs")
        runs = []
        for k, run in enumerate(raw_runs):
            run = _mapping(run, f"variants.runs[{k}]")
            settings = _mapping(run.get("set"), f"variants.runs[{k}].set")
            for key, value in settings.items():
                _settings_key(key, f"variants.runs[{k}].set", value)
            runs.append((str(run.get("label", k)), settings))
    labels = [label for label, _ in runs]
    if len(set(labels)) != len(labels):
        raise ValueError(f"variant labels must differ: {labels}")
    short_runs = sorted({0, len(runs) - 1})
    if axes:  # the corners
        ends = [sorted({0, len(a.values) - 1}) for a in axes]
        short_runs = [index.index(c) for c in itertools.product(*ends)]
    if v.get("short") is not None:  # the runs the short form keeps, by label
        keep = v["short"]
        if not isinstance(keep, list) or not keep or any(k not in labels for k in keep):
            raise ValueError(f"'variants.short' must list run labels among {labels}")
        short_runs = sorted(labels.index(k) for k in set(keep))
    return Variants(name_, runs, short_runs, axes, index, boundary)


_AXIS_KEYS = {"key", "values", "name", "label", "unit", "scale", "also"}


def _axes(raw: Any) -> tuple[Axis, ...]:
    """The axes of ``variants.grid``, checked: two or more, each with its own keys."""
    if not isinstance(raw, list) or len(raw) < 2:
        raise ValueError(
            "'variants.grid' must list two or more axes ({key: ..., values: [...]}); "
            "one axis: use variants.key + values"
        )
    axes: list[Axis] = []
    seen: set[str] = set()
    for k, spec in enumerate(raw):
        what = f"variants.grid[{k}]"
        spec = _mapping(spec, what)
        if extra := set(spec) - _AXIS_KEYS:
            raise ValueError(
                f"{what}: unknown keys {sorted(extra)}; allowed: {sorted(_AXIS_KEYS)}"
            )
        if "key" not in spec:
            raise ValueError(f"{what}: missing 'key'")
        values = spec.get("values")
        if not isinstance(values, list) or not values:
            raise ValueError(f"{what}.values must be a non-empty list")
        also = spec.get("also") or []
        if not isinstance(also, list):
            raise ValueError(f"{what}.also must be a list of keys, got {also!r}")
        keys = [str(spec["key"]), *(str(a) for a in also)]
        for key in keys:
            for value in values if key == "controller" else [None]:
                _settings_key(key, what, value)
            if key in seen:
                raise ValueError(f"{what}: key {key!r} is swept by another axis already")
            seen.add(key)
        scale = spec.get("scale", "linear")
        if scale not in SCALES:
            raise ValueError(f"{what}.scale must be one of {SCALES}, got {scale!r}")
        if scale == "log" and not all(_number(x) and x > 0 for x in values):
            raise ValueError(f"{what}: a log axis needs numbers > 0, got {values}")
        name_ = str(spec.get("name", keys[0].rpartition(".")[2]))
        if name_ in {a.name for a in axes}:
            raise ValueError(f"{what}: axis name {name_!r} is used twice (name the axes)")
        axes.append(
            Axis(
                keys[0],
                name_,
                str(spec.get("label", name_)),
                str(spec.get("unit", "")),
                scale,
                tuple(values),
                tuple(keys[1:]),
            )
        )
    return tuple(axes)


def _robots(data: dict[str, Any]) -> tuple[RobotSetup, ...]:
    """The ``robots`` of a world, checked (empty: a one-robot scenario)."""
    if data.get("robots") is None:
        return ()
    raw = _mapping(data["robots"], "robots")
    if not raw:
        raise ValueError("'robots' must name at least one robot")
    if both := [k for k in _ONE_ROBOT_KEYS if k in data]:
        raise ValueError(
            f"with 'robots', {both} belong to each robot or are not supported: give robot, "
            "plant, controller, parameters and reference under each robot's name"
        )
    setups = []
    for name, spec in raw.items():
        what = f"robots.{name}"
        if not isinstance(name, str) or not _ROBOT_NAME.fullmatch(name):
            raise ValueError(
                f"'robots': {name!r} is not a name (a letter, then letters, digits or _): "
                "it is the namespace of the robot's topics"
            )
        spec = _mapping(spec, what)
        if extra := set(spec) - _ROBOT_KEYS:
            raise ValueError(
                f"{what}: unknown keys {sorted(extra)}; allowed: {sorted(_ROBOT_KEYS)}"
            )
        for key in ("robot", "controller", "reference"):
            if key not in spec:
                raise ValueError(f"{what}: missing '{key}'")
        if spec["controller"] not in CONTROLLERS:
            raise ValueError(
                f"{what}: 'controller' must be one of {CONTROLLERS}, got {spec['controller']!r}"
            )
        setups.append(
            RobotSetup(
                name,
                str(spec["robot"]),
                _mapping(spec.get("plant"), f"{what}.plant"),
                spec["controller"],
                _mapping(spec.get("parameters"), f"{what}.parameters"),
                _mapping(spec["reference"], f"{what}.reference"),
            )
        )
    return tuple(setups)


def _figures(value: Any) -> tuple[str, ...]:
    names = [] if value is None else value
    if not isinstance(names, list) or any(n not in FIGURES for n in names):
        raise ValueError(f"'figures' must be a list of {sorted(FIGURES)}, got {value!r}")
    return tuple(names)


_REFERENCE_KEYS = {
    "step": {"target"},
    "sinusoid": {"center", "amplitude", "omega", "phase", "duration", "sample_period"},
    "quintic": {"target", "duration"},
    "waypoints": {"positions", "times"},
}


def build_reference(spec: dict[str, Any], q0: np.ndarray | None, duration: float) -> Trajectory:
    """The reference trajectory of a scenario (times from 0). ``q0`` is the plant's initial
    configuration: the sinusoid's default centre and the quintic's start."""
    shape = spec.get("shape")
    if shape not in _REFERENCE_KEYS:
        raise ValueError(f"reference shape must be one of {sorted(_REFERENCE_KEYS)}: {shape!r}")
    unknown = set(spec) - _REFERENCE_KEYS[shape] - {"shape"}
    if unknown:
        raise ValueError(f"reference '{shape}': unknown keys {sorted(unknown)}")
    try:
        if shape == "step":
            return shapes.step(spec["target"])
        if shape == "sinusoid":
            amplitude = spec["amplitude"]
            center = spec.get("center")
            if center is None:
                center = q0 if q0 is not None else np.zeros(np.size(amplitude))
            return shapes.sinusoid(
                center,
                amplitude,
                spec["omega"],
                spec.get("phase", 0.0),
                spec.get("duration", duration),
                spec.get("sample_period", shapes.DEFAULT_SAMPLE_PERIOD),
            )
        if shape == "quintic":
            return shapes.quintic(q0, spec["target"], spec["duration"])
        return shapes.waypoints(spec["positions"], spec["times"])
    except KeyError as err:
        raise ValueError(f"reference '{shape}' needs {err}") from None
