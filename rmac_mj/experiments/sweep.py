"""Sweeps: a grid of hyperparameter settings, each run as a ``reproduce`` result directory.

A sweep file is TOML with three tables::

    [protocol]                  # any reproduce option, plus fixed hyperparameters "ALGO.FIELD"
    algorithms = ["rmac"]
    experiments = 10
    evaluate_every = 10
    [grid]                      # every combination of these values
    "rmac.alpha_r" = [0.005, 0.01, 0.02]
    "rmac.critic_weights" = [[1, 0.1], [1, 0.3]]
    [[variant]]                 # optional: named sets of overrides, crossed with the grid
    name = "oldest"
    "rmac.critic_replacement" = "oldest"

Hyperparameter keys are ``ALGO.FIELD`` with nested fields allowed (``rmac.exploration.sigma``); they
name fields of the learner's config dataclass (:func:`rmac_mj.agents.config_class`). The whole file is
validated before anything runs: an unknown section or key, a value of the wrong type, an unknown
algorithm or hyperparameter, or a value the config rejects raises :class:`SweepFileError` (a
:class:`~rmac_mj.errors.UserInputError`, one line naming the key).

Each configuration (variant x grid point) is a :class:`~rmac_mj.experiments.runner.Protocol` run into
``OUT/<name>/``, a directory named after the swept values (``alpha_r=0.01__critic_weights=1,0.1``);
``OUT/sweep.json`` is the index (file, configurations, directories). All experiments of all
configurations share one worker pool or one Dask cluster (:func:`runner.run_protocols`); every
configuration uses the same seeds, so configurations differ only by their settings (common random
numbers: differences between them are paired). ``OUT/sweep.csv`` has one row per configuration and
learner (:data:`COLUMNS`) and ``OUT/sweep_<metric>.png`` plots each metric against each swept parameter.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import itertools
import json
import math
import pathlib
import re
import sys
from typing import Any, Callable, Iterable

import numpy as np

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from rmac_mj import constraints
from rmac_mj.agents import ALGORITHMS, config_class, config_from_dict
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.experiments import results, runner

#: The tables a sweep file may have.
SECTIONS = ("protocol", "grid", "variant")
#: Protocol options a [protocol] table may set (the fields of runner.Protocol but agent_configs).
PROTOCOL_KEYS = ("algorithms", "experiments", "trials", "seed", "evaluate_every", "domain", "task",
                 "task_kwargs", "snapshot_trials")
#: The "first minutes" of simulated time over which the early return is averaged (trials: as many
#: as end within them, by the task's trial length, ``summary.json``'s ``trial_seconds``).
FIRST_MINUTES = 5.0


class SweepFileError(UserInputError):
    """A sweep (or --config) file that cannot be run: the message names the file and the key."""


@dataclasses.dataclass(frozen=True)
class Configuration:
    """One point of a sweep.

    Attributes:
      name: its directory name under the sweep's output, built from ``variant`` and ``values``.
      variant: the [[variant]] name, or None when the file has none.
      values: grid key -> the value of this point, in the file's order.
      protocol: what is run.
    """

    name: str
    variant: str | None
    values: dict[str, Any]
    protocol: runner.Protocol


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A validated sweep file.

    Attributes:
      path: the file read.
      options: the [protocol] options (Protocol fields).
      fixed: the [protocol] hyperparameters, ``"ALGO.FIELD" -> value``.
      grid: ``"ALGO.FIELD" -> list of values``, in the file's order.
      variants: ``(name, {"ALGO.FIELD": value})`` per [[variant]], in the file's order.
      configurations: every variant crossed with every grid point (variant-major, then the grid in
        ``itertools.product`` order of its keys).
    """

    path: pathlib.Path
    options: dict[str, Any]
    fixed: dict[str, Any]
    grid: dict[str, list]
    variants: tuple[tuple[str, dict[str, Any]], ...]
    configurations: tuple[Configuration, ...]

    @property
    def parameters(self) -> list[str]:
        """The swept parameters: "variant" (when there are variants) and the grid keys."""
        return (["variant"] if self.variants else []) + list(self.grid)

    def as_dict(self) -> dict[str, Any]:
        """The parsed file as JSON data (what a resumed sweep must match)."""
        return {"protocol": results.as_jsonable(self.options),
                "fixed": results.as_jsonable(self.fixed),
                "grid": results.as_jsonable(self.grid),
                "variants": [{"name": name, **results.as_jsonable(values)}
                             for name, values in self.variants]}


@dataclasses.dataclass(frozen=True)
class SingleConfiguration:
    """A ``reproduce --config`` file: protocol options and the learners' hyperparameter overrides."""

    options: dict[str, Any]
    agent_configs: dict[str, dict]


# ----------------------------------------------------------------------------------------------------
# Reading and validating a file.

def read_toml(path: str | pathlib.Path) -> dict[str, Any]:
    """The TOML document at ``path``; a missing or malformed file is a :class:`UserInputError`."""
    path = pathlib.Path(path)
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise MissingInputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise SweepFileError(f"{path}: is a directory, not a TOML file") from None
    except tomllib.TOMLDecodeError as error:
        raise SweepFileError(f"{path}: not valid TOML: {error}") from None
    except UnicodeDecodeError:
        raise SweepFileError(f"{path}: not valid TOML: not UTF-8 text") from None


def load_sweep(path: str | pathlib.Path) -> Sweep:
    """Read and validate a sweep file; raise :class:`SweepFileError` naming the first bad key."""
    path = pathlib.Path(path)
    document = read_toml(path)
    check = _Checker(path)
    options, fixed = check.protocol(document)
    algorithms = options.get("algorithms", runner.Protocol().algorithms)
    grid = {}
    for key, values in flatten(check.table(document, "grid")).items():
        where = f'[grid] "{key}"'
        hint = check.hyperparameter(key, algorithms, where)
        if not isinstance(values, list):
            raise check.error(where, f"expected a list of values to sweep, e.g. [{_toml(values)}, ...]; "
                                     f"got {_toml(values)}")
        if not values:
            raise check.error(where, "the list of values is empty")
        for value in values:
            check.value(value, hint, f"{where} value {_toml(value)}", key, fixed)
        if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
            raise check.error(where, f"repeats a value in {_toml(values)}")
        if key in fixed:
            raise check.error(where, "is also set in [protocol]; set it in one place")
        grid[key] = values
    variants = check.variants(document, algorithms, fixed, grid)
    configurations = _configurations(check, options, fixed, grid, variants)
    return Sweep(path=path, options=options, fixed=fixed, grid=grid, variants=variants,
                 configurations=configurations)


def load_configuration(path: str | pathlib.Path) -> SingleConfiguration:
    """Read a ``reproduce --config`` file: the sweep tables with single values.

    A [grid] entry gives one value (a one-element list is taken as that value); a list of several
    values, or more than one [[variant]], is refused: that is a sweep.
    """
    path = pathlib.Path(path)
    document = read_toml(path)
    check = _Checker(path)
    options, fixed = check.protocol(document)
    algorithms = options.get("algorithms", runner.Protocol().algorithms)
    overrides = dict(fixed)
    for key, value in flatten(check.table(document, "grid")).items():
        where = f'[grid] "{key}"'
        hint = check.hyperparameter(key, algorithms, where)
        if constraints.unmet(value, hint) is not None and isinstance(value, list):
            if len(value) != 1:
                raise check.error(where, f"lists {len(value)} values; --config runs one configuration "
                                         "(give one value, or run the file with `rmac-mj sweep`)")
            value = value[0]
        check.value(value, hint, where, key, fixed)
        if key in fixed:
            raise check.error(where, "is also set in [protocol]; set it in one place")
        overrides[key] = value
    variants = check.variants(document, algorithms, fixed, {k: [v] for k, v in overrides.items()
                                                            if k not in fixed})
    if len(variants) > 1:
        raise check.error("[[variant]]", f"{len(variants)} variants; --config runs one configuration "
                                         "(keep one, or run the file with `rmac-mj sweep`)")
    for _, values in variants:
        overrides.update(values)
    agent_configs = nest(overrides)
    check.agents(check.protocol_object(options, agent_configs, ""), "configuration")
    return SingleConfiguration(options=options, agent_configs=agent_configs)


def nest(flat: dict[str, Any]) -> dict[str, dict]:
    """``{"rmac.exploration.sigma": 0.5}`` -> ``{"rmac": {"exploration": {"sigma": 0.5}}}``."""
    nested: dict[str, Any] = {}
    for key, value in flat.items():
        *parents, last = key.split(".")
        node = nested
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = merge(node[last], value) if isinstance(node.get(last), dict) else value
    return nested


def merge(base: dict, overrides: dict) -> dict:
    """A deep copy of ``base`` with ``overrides`` applied (nested dicts merged, other values replaced)."""
    merged = json.loads(json.dumps(base))
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = merge(merged[key], value)
        else:
            merged[key] = json.loads(json.dumps(value))
    return merged


def flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """TOML dotted keys nest (``rmac.alpha_r = 1`` is ``{"rmac": {"alpha_r": 1}}``): back to
    ``"rmac.alpha_r"``, so a quoted and a bare key mean the same. Inline tables flatten the same way
    (an override of some fields of a nested config)."""
    flat = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


def _toml(value: Any) -> str:
    """A value as the user wrote it (TOML-like), for messages and names."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    return repr(value)


class _Checker:
    """Validation of one file; every message starts with the file's path and names the key."""

    def __init__(self, path: pathlib.Path):
        self.path = path
        self._spaces: dict[str, tuple] = {}

    def error(self, where: str, message: str) -> SweepFileError:
        return SweepFileError(f"{self.path}: {where}: {message}")

    def table(self, document: dict, section: str) -> dict:
        value = document.get(section, {})
        if not isinstance(value, dict):
            raise self.error(f"[{section}]", f"expected a table, got {_toml(value)}")
        return value

    def protocol(self, document: dict) -> tuple[dict[str, Any], dict[str, Any]]:
        """The [protocol] options and fixed hyperparameters; also rejects unknown sections."""
        for section in document:
            if section not in SECTIONS:
                close = difflib.get_close_matches(section, SECTIONS, n=1)
                hint = f" (did you mean [{close[0]}]?)" if close else ""
                raise self.error(f"[{section}]", f"unknown section{hint}; a sweep file has "
                                                 "[protocol], [grid] and [[variant]]")
        if "variant" in document and not (isinstance(document["variant"], list) and
                                          all(isinstance(v, dict) for v in document["variant"])):
            raise self.error("[variant]", "variants are an array of tables: write [[variant]]")
        options, hyper = {}, {}
        for key, value in self.table(document, "protocol").items():
            if key in PROTOCOL_KEYS:
                options[key] = self.option(key, value)
            elif "." in key or key in ALGORITHMS:
                hyper.update(flatten({key: value}))
            else:
                close = difflib.get_close_matches(key, PROTOCOL_KEYS, n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                raise self.error(f"[protocol] {key}", f"unknown key{hint}; known: "
                                 f"{', '.join(PROTOCOL_KEYS)}, or a hyperparameter \"ALGO.FIELD\"")
        algorithms = options.get("algorithms", runner.Protocol().algorithms)
        for key, value in hyper.items():
            where = f'[protocol] "{key}"'
            self.value(value, self.hyperparameter(key, algorithms, where), where, key)
        self.protocol_object(options, nest(hyper), "[protocol]")
        return options, hyper

    def option(self, key: str, value: Any) -> Any:
        where = f"[protocol] {key}"
        if key == "algorithms":
            if isinstance(value, str):
                value = [a.strip() for a in value.split(",") if a.strip()]
            if not (isinstance(value, list) and value and all(isinstance(a, str) for a in value)):
                raise self.error(where, f'expected a list of algorithm names, e.g. ["rmac"]; '
                                        f"got {_toml(value)}")
            for name in value:
                if name not in ALGORITHMS:
                    raise self.error(where, f"unknown algorithm {name!r}; available: "
                                            f"{', '.join(ALGORITHMS)}")
            return tuple(value)
        if key in ("experiments", "trials", "seed", "evaluate_every"):
            minimum = 1 if key in ("experiments", "trials") else 0
            if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
                raise self.error(where, f"expected an integer >= {minimum}, got {_toml(value)}")
            return value
        if key in ("domain", "task"):
            if not isinstance(value, str):
                raise self.error(where, f"expected a string, got {_toml(value)}")
            return value
        if key == "task_kwargs":
            if not isinstance(value, dict):
                raise self.error(where, f"expected a table, got {_toml(value)}")
            return value
        if key == "snapshot_trials":
            if not (isinstance(value, list) and all(isinstance(t, int) and not isinstance(t, bool)
                                                    and t >= 1 for t in value)):
                raise self.error(where, f"expected a list of trial numbers >= 1, got {_toml(value)}")
            return tuple(value)
        raise AssertionError(key)  # pragma: no cover - PROTOCOL_KEYS and this function agree

    def protocol_object(self, options: dict, agent_configs: dict, where: str) -> runner.Protocol:
        """Build the Protocol; a value its validation rejects is reported against ``where``."""
        from rmac_mj import tasks

        domain = options.get("domain", runner.Protocol().domain)
        task = options.get("task", runner.Protocol().task)
        if domain not in tasks.TASKS_BY_DOMAIN:
            raise self.error("[protocol] domain", f"unknown domain {domain!r}; available: "
                                                  f"{', '.join(tasks.TASKS_BY_DOMAIN)}")
        if task not in tasks.TASKS_BY_DOMAIN[domain]:
            raise self.error("[protocol] task", f"unknown task {task!r} of {domain}; available: "
                                                f"{', '.join(tasks.TASKS_BY_DOMAIN[domain])}")
        try:
            return runner.Protocol(**options, agent_configs=agent_configs)
        except (ValueError, TypeError) as error:
            raise self.error(where or "[protocol]", str(error)) from None

    def agents(self, protocol: runner.Protocol, where: str) -> None:
        """Build each learner of ``protocol`` on its task: catches what only the task's spaces
        reveal (e.g. input weights of the wrong length) before anything runs."""
        from rmac_mj.agents import make_agent
        from rmac_mj.experiments.episode import action_space_of, state_space_of

        key = json.dumps([protocol.domain, protocol.task, protocol.task_kwargs], sort_keys=True)
        if key not in self._spaces:
            env = runner.make_environment(protocol, task_seed=0)
            self._spaces[key] = (state_space_of(env), action_space_of(env))
        state_space, action_space = self._spaces[key]
        for algorithm in protocol.algorithms:
            try:
                make_agent(algorithm, state_space, action_space,
                           config=protocol.agent_configs.get(algorithm), seed=0)
            except (ValueError, TypeError) as error:
                raise self.error(where, f"{algorithm}: {error}") from None

    def hyperparameter(self, key: str, algorithms: Iterable[str], where: str) -> list:
        """The constraints of the hyperparameter ``key`` ("ALGO.FIELD[.FIELD]"), from its config's
        table (:mod:`rmac_mj.constraints`)."""
        algorithm, *path = key.split(".")
        if not path or not all(path):
            raise self.error(where, 'expected a hyperparameter "ALGO.FIELD", e.g. "rmac.alpha_r"')
        if algorithm not in ALGORITHMS:
            raise self.error(where, f"unknown algorithm {algorithm!r}; available: {', '.join(ALGORITHMS)}")
        if algorithm not in algorithms:
            raise self.error(where, f"sets {algorithm}, which the protocol does not run (algorithms = "
                                    f"{_toml(list(algorithms))})")
        try:
            return constraints.lookup(config_class(algorithm), path)
        except constraints.InvalidParameterError as error:
            raise self.error(where, str(error)) from None

    def value(self, value: Any, allowed: list, where: str, key: str | None = None,
              base: dict[str, Any] | None = None) -> None:
        """Check ``value`` against the constraints ``allowed``; with ``key``, also that the
        learner's config accepts it on top of the ``base`` hyperparameters (rules that tie values
        together)."""
        problem = constraints.unmet(value, allowed)
        if problem is not None:
            raise self.error(where, f"expected {problem}, got {_toml(value)}")
        if key is not None:
            algorithm = key.split(".")[0]
            overrides = nest({**(base or {}), key: value}).get(algorithm, {})
            try:
                config_from_dict(config_class(algorithm), overrides)
            except (ValueError, TypeError) as error:
                raise self.error(where, str(error)) from None

    def variants(self, document: dict, algorithms, fixed: dict, grid: dict
                 ) -> tuple[tuple[str, dict[str, Any]], ...]:
        variants, names = [], set()
        for number, table in enumerate(document.get("variant", []), start=1):
            name = table.get("name")
            label = f"[[variant]] #{number}"
            if not isinstance(name, str) or not name.strip():
                raise self.error(f"{label} name", f"each variant needs a name (a non-empty string), "
                                                  f"got {_toml(name) if name is not None else 'none'}")
            if name in names:
                raise self.error(f"{label} name", f"repeats the variant name {name!r}")
            names.add(name)
            values, hints = {}, {}
            for key, value in flatten({k: v for k, v in table.items() if k != "name"}).items():
                where = f'[[variant]] "{name}" "{key}"'
                hints[key] = self.hyperparameter(key, algorithms, where)
                self.value(value, hints[key], where)  # the type first, for every key
                if key in grid:
                    raise self.error(where, "is also swept in [grid]; set it in one place")
                values[key] = value
            # Then the ranges, each key with the variant's other values, which it may depend on
            # (rmac.exploration.where = "uncertain" needs its uncertainty_threshold).
            for key, value in values.items():
                where = f'[[variant]] "{name}" "{key}"'
                self.value(value, hints[key], where, key, {**fixed, **values})
            variants.append((name, values))
        return tuple(variants)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


# ----------------------------------------------------------------------------------------------------
# Configurations and their names.

def _label(value: Any) -> str:
    if isinstance(value, list):
        return ",".join(_label(v) for v in value)
    if isinstance(value, dict):
        return "+".join(f"{k}-{_label(v)}" for k, v in value.items())
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _short_names(keys: list[str]) -> dict[str, str]:
    """Each key's shortest dotted suffix that no other key shares (``rmac.exploration.sigma`` ->
    ``sigma``; with ``s-ac.exploration.sigma`` beside it, ``rmac.exploration.sigma`` stays whole)."""
    names = {}
    for key in keys:
        parts = key.split(".")
        for size in range(1, len(parts) + 1):
            suffix = ".".join(parts[-size:])
            if sum(other.split(".")[-size:] == parts[-size:] for other in keys) == 1:
                break
        names[key] = suffix
    return names


_UNSAFE = re.compile(r"[^A-Za-z0-9._,=+-]")


def configuration_name(variant: str | None, values: dict[str, Any], short: dict[str, str]) -> str:
    """A directory name from the swept values: ``[variant__]sigma=0.5__period=3``."""
    parts = ([variant] if variant is not None else []) + \
        [f"{short[key]}={_label(value)}" for key, value in values.items()]
    name = _UNSAFE.sub("_", "__".join(parts)) or "base"
    return name.lstrip(".") or "base"


def _configurations(check: _Checker, options: dict, fixed: dict, grid: dict,
                    variants: tuple) -> tuple[Configuration, ...]:
    short = _short_names(list(grid))
    configurations, seen = [], {}
    for variant, variant_values in (variants or ((None, {}),)):
        for point in itertools.product(*grid.values()):
            values = dict(zip(grid, point))
            agent_configs = nest({**fixed, **variant_values, **values})
            where = ", ".join([f"variant {variant!r}"] * (variant is not None) +
                              [f'"{k}" = {_toml(v)}' for k, v in values.items()]) or "[protocol]"
            protocol = check.protocol_object(options, agent_configs, f"configuration {where}")
            check.agents(protocol, f"configuration {where}")
            name = configuration_name(variant, values, short)
            if len(name) > 120 or name in seen:  # very long or (after sanitising) not unique
                digest = hashlib.sha256(json.dumps([variant, values], sort_keys=True).encode()).hexdigest()[:8]
                name = f"{name[:100]}-{digest}"
            seen[name] = True
            configurations.append(Configuration(name=name, variant=variant, values=values,
                                                protocol=protocol))
    return tuple(configurations)


# ----------------------------------------------------------------------------------------------------
# Running a sweep and summarising it.

#: sweep.csv's columns after the configuration, the swept parameters and the learner.
COLUMNS = ("experiments", "final_return_mean", "final_return_ci95_low", "final_return_ci95_high",
           "greedy_trial", "greedy_return_mean", "greedy_return_ci95_low", "greedy_return_ci95_high",
           "minutes_to_90pct", "mean_return_first_5min", "first_5min_ci95_low", "first_5min_ci95_high",
           "stuck_experiments", "optimal_return", "gap_to_optimal", "exploration_floor", "wall_time_s")

#: Metric -> (column, CI low column, CI high column, axis label) of the sweep_<metric>.png figures.
METRICS = {
    "final_return": ("final_return_mean", "final_return_ci95_low", "final_return_ci95_high",
                     "final return (mean of the last 50 trials)"),
    "greedy_return": ("greedy_return_mean", "greedy_return_ci95_low", "greedy_return_ci95_high",
                      "greedy return (last evaluation)"),
    "minutes_to_90pct": ("minutes_to_90pct", None, None,
                         "simulated minutes to within 10% of the final level"),
    "first_5min": ("mean_return_first_5min", "first_5min_ci95_low", "first_5min_ci95_high",
                   "mean return of the first 5 simulated minutes"),
    "stuck": ("stuck_experiments", None, None, "stuck experiments (final level < -1500)"),
    "gap_to_optimal": ("gap_to_optimal", None, None, "near-optimal return - final return"),
    "wall_time": ("wall_time_s", None, None, "wall time of its experiments, summed [s]"),
}


class SweepResumeRefused(runner.ResumeRefused):
    """The output directory holds another sweep (or an unfinished one without --resume)."""


def _prepare(out: pathlib.Path, sweep: Sweep, resume: bool) -> None:
    """Write (or, resuming, check) ``out/sweep.json``: the parsed file and the index of directories."""
    index = out / "sweep.json"
    document = {"sweep": sweep.as_dict(), "parameters": sweep.parameters,
                "configurations": [{"directory": c.name, "variant": c.variant,
                                    "values": results.as_jsonable(c.values)}
                                   for c in sweep.configurations]}
    if index.exists():
        if not resume:
            raise SweepResumeRefused(f"{out} already holds a sweep; pass --resume to finish it, or "
                                     "choose another --out")
        existing = json.loads(index.read_text())
        if {k: existing.get(k) for k in document} != document:
            raise SweepResumeRefused(f"{out} holds a sweep of a different file; refusing to mix "
                                     "results (use another --out)")
        return
    out.mkdir(parents=True, exist_ok=True)
    results.write_json(index, {**document, "source": str(sweep.path),
                               "provenance": results.provenance()})
    text = sweep.path.read_bytes()
    results.write_atomic(out / "sweep.toml", lambda handle: handle.write(text))


def run_sweep(sweep: Sweep, out: str | pathlib.Path, jobs: int | None = None,
              scheduler: str | None = None, resume: bool = False, progress: bool = True,
              optimal: Callable[[runner.Protocol], float | None] | None = None,
              floor: Callable[[runner.Protocol, str], float | None] | None = None,
              figures: bool = True, log: Callable[[str], None] | None = None,
              started: float | None = None) -> list[dict[str, Any]]:
    """Run (or finish, with ``resume``) every configuration of ``sweep`` into ``out``.

    Writes ``out/sweep.json`` (the index), one result directory per configuration, ``out/sweep.csv``
    and, with ``figures``, ``out/sweep_<metric>.png``. Returns the csv's rows. ``log`` and
    ``started`` mean what they mean for :func:`runner.run_protocol`.
    """
    out = pathlib.Path(out)
    _prepare(out, sweep, resume)
    runs = [(c.protocol, out / c.name) for c in sweep.configurations]
    summaries = runner.run_protocols(runs, jobs=jobs, resume=resume, scheduler=scheduler,
                                     progress=progress, optimal=optimal, floor=floor, figures=figures,
                                     log=log, started=started)
    rows = sweep_rows(sweep, out, summaries)
    write_csv(out / "sweep.csv", sweep, rows)
    if figures:
        plot_sweep(sweep, rows, out)
    return rows


def _ci(samples: np.ndarray) -> tuple[float, float, float]:
    mean, low, high = results.confidence_interval(np.asarray(samples, dtype=float))
    return float(mean), float(low), float(high)


def sweep_rows(sweep: Sweep, out: pathlib.Path, summaries: list[dict[str, Any]]) -> list[dict]:
    """One row per configuration and learner: the swept values and the metrics of :data:`COLUMNS`."""
    rows = []
    for configuration, summary in zip(sweep.configurations, summaries):
        protocol = configuration.protocol
        for algorithm in protocol.algorithms:
            returns, greedy, greedy_trials, wall = runner.load_curves(out / configuration.name,
                                                                      protocol, algorithm)
            learner = summary[algorithm]
            row: dict[str, Any] = {"configuration": configuration.name}
            if sweep.variants:
                row["variant"] = configuration.variant
            row.update(configuration.values)
            row["algorithm"] = algorithm
            row["experiments"] = learner["experiments"]
            row["final_return_mean"] = learner["final_return_mean"]
            row["final_return_ci95_low"], row["final_return_ci95_high"] = learner["final_return_ci95"]
            if greedy.size:
                row["greedy_trial"] = int(greedy_trials[-1])
                (row["greedy_return_mean"], row["greedy_return_ci95_low"],
                 row["greedy_return_ci95_high"]) = _ci(greedy[:, -1])
            row["minutes_to_90pct"] = learner["minutes_to_90pct"]
            (row["mean_return_first_5min"], row["first_5min_ci95_low"],
             row["first_5min_ci95_high"]) = _ci(returns[:, :results.trials_in(
                FIRST_MINUTES, summary["trial_seconds"])].mean(axis=1))
            row["stuck_experiments"] = learner["stuck_experiments"]
            row["optimal_return"] = summary.get("optimal_return")
            row["gap_to_optimal"] = learner.get("gap_to_optimal")
            row["exploration_floor"] = learner.get("exploration_floor")
            row["wall_time_s"] = float(wall.sum())
            rows.append({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                         for k, v in row.items()})
    return rows


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return value


def write_csv(path: pathlib.Path, sweep: Sweep, rows: list[dict]) -> pathlib.Path:
    """``sweep.csv``: configuration, [variant,] one column per grid key, algorithm, :data:`COLUMNS`.
    Lists (e.g. input weights) are written as JSON; a missing value (no greedy evaluation, no
    optimum, a CI of one experiment) as an empty cell."""
    header = ["configuration", *(["variant"] if sweep.variants else []), *sweep.grid, "algorithm",
              *COLUMNS]
    return results.write_csv(path, header,
                             ([_cell(row.get(column)) for column in header] for row in rows))


def format_table(sweep: Sweep, rows: list[dict]) -> str:
    """The end-of-sweep table for the terminal: one line per configuration and learner."""
    width = max([len(r["configuration"]) for r in rows] + [13])
    header = (f"{'configuration':<{width}} {'learner':>7} {'final return [95% CI]':>24} "
              f"{'greedy':>7} {'min to 90%':>10} {'first 5 min':>11} {'stuck':>5}")
    lines = [header, "-" * len(header)]
    for row in rows:
        low, high = row["final_return_ci95_low"], row["final_return_ci95_high"]
        ci = f" [{low:.0f}, {high:.0f}]" if low is not None else ""
        greedy = row.get("greedy_return_mean")
        stuck = row["stuck_experiments"]  # None without a reference return to judge "stuck" by
        lines.append(f"{row['configuration']:<{width}} {row['algorithm']:>7} "
                     f"{row['final_return_mean']:>9.1f}{ci:>15} "
                     f"{'' if greedy is None else f'{greedy:.1f}':>7} "
                     f"{row['minutes_to_90pct']:>10.1f} {row['mean_return_first_5min']:>11.1f} "
                     f"{'' if stuck is None else stuck:>5}")
    return "\n".join(lines)


def _axis_values(values: list) -> tuple[list[float], list[str] | None]:
    """Positions on the x axis: the values themselves when all are numbers, else 0, 1, 2, ... with
    the values as tick labels."""
    if all(_is_number(v) for v in values):
        return [float(v) for v in values], None
    return list(range(len(values))), [_label(v) if v is not None else "-" for v in values]


def plot_sweep(sweep: Sweep, rows: list[dict], out: pathlib.Path) -> list[pathlib.Path]:
    """``out/sweep_<metric>.png``: each metric against each swept parameter, one panel per parameter.

    In a parameter's panel each line joins the configurations that share every other swept value
    (and the learner), drawn slightly apart; error bars are 95% confidence intervals where the
    metric has one.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parameters = sweep.parameters or ["configuration"]
    paths = []
    for metric, (column, low_column, high_column, label) in METRICS.items():
        if all(row.get(column) is None for row in rows):
            continue  # e.g. no greedy evaluations, no optimum
        # a panel of many named values (variants) gets the width their tick labels need
        widths = [max(4.8, 0.9 * len({json.dumps(row.get(p)) for row in rows})) for p in parameters]
        fig, axes = plt.subplots(1, len(parameters), figsize=(max(sum(widths), 6.4), 3.8),
                                 squeeze=False, constrained_layout=True,
                                 gridspec_kw={"width_ratios": widths})
        for ax, parameter in zip(axes[0], parameters):
            choices = []
            for row in rows:
                if all(json.dumps(row.get(parameter)) != json.dumps(c) for c in choices):
                    choices.append(row.get(parameter))
            positions, ticks = _axis_values(choices)
            others = [p for p in parameters if p != parameter]
            series: dict[str, list] = {}
            for row in rows:
                key = ", ".join([f"{_short_names(others).get(p, p) if p != 'variant' else 'variant'}"
                                 f"={_label(row.get(p))}" for p in others] +
                                ([row["algorithm"]] if len({r["algorithm"] for r in rows}) > 1
                                 else []))
                x = positions[[json.dumps(c) for c in choices].index(json.dumps(row.get(parameter)))]
                series.setdefault(key, []).append((x, row))
            logarithmic = ticks is None and all(p > 0 for p in positions) and \
                max(positions) >= 10 * min(positions)
            span = (np.log10(max(positions) / min(positions)) if logarithmic
                    else max(positions) - min(positions)) or 1.0
            for number, (key, points) in enumerate(series.items()):
                points.sort(key=lambda p: p[0])
                # Lines side by side, a little apart, so that their error bars do not hide each other.
                dodge = 0.012 * span * (number - (len(series) - 1) / 2)
                xs = [x * 10 ** dodge if logarithmic else x + dodge for x, _ in points]
                ys = [np.nan if r.get(column) is None else r[column] for _, r in points]
                if low_column is not None:
                    low = [np.nan if r.get(low_column) is None else r[low_column] for _, r in points]
                    high = [np.nan if r.get(high_column) is None else r[high_column]
                            for _, r in points]
                    errors = np.abs(np.array([np.subtract(ys, low), np.subtract(high, ys)]))
                    ax.errorbar(xs, ys, yerr=errors, marker="o", capsize=3, linewidth=1.2,
                                label=key or None)
                else:
                    ax.plot(xs, ys, marker="o", linewidth=1.2, label=key or None)
            if ticks is not None:
                slanted = max(map(len, ticks)) > 6
                ax.set_xticks(positions, ticks, rotation=30 if slanted else 0,
                              ha="right" if slanted else "center")
            elif logarithmic:
                ax.set_xscale("log")
                ax.set_xticks(positions, [_label(c) for c in choices])
            ax.set_xlabel(parameter)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
            if any(series) and len(series) <= 12:
                ax.legend(fontsize="x-small")
        fig.suptitle(f"{sweep.path.name}: {label}", fontsize="medium")
        path = out / f"sweep_{metric}.png"
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
    return paths
