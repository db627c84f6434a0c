"""Sweep and ``reproduce --config`` files: TOML read and validated before anything runs.

Tables ``[protocol]`` (:class:`~rmac_mj.experiments.protocol.Protocol` options, fixed
``ALGO.FIELD``), ``[grid]`` and ``[[variant]]`` (the format: :func:`load_sweep`); any bad section,
key or value raises :class:`SweepFileError` naming the file and the key.
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
from collections.abc import Callable, Iterable
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from rmac_mj import constraints
from rmac_mj.agents import ALGORITHMS, config_class, config_from_dict
from rmac_mj.errors import MissingInputError, UserInputError
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.results import files

#: The tables a sweep file may have. [learner_state] is the Protocol option of that name written as a
#: table of its own: what x is in an outside environment (``env``) where it cannot be inferred.
SECTIONS = ("protocol", "grid", "variant", "learner_state")
#: Protocol options a [protocol] table may set: the fields of Protocol but agent_configs.
PROTOCOL_KEYS = tuple(
    field.name for field in dataclasses.fields(Protocol) if field.name != "agent_configs"
)


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
    protocol: Protocol


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
        return {
            "protocol": files.as_jsonable(self.options),
            "fixed": files.as_jsonable(self.fixed),
            "grid": files.as_jsonable(self.grid),
            "variants": [
                {"name": name, **files.as_jsonable(values)} for name, values in self.variants
            ],
        }


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


def load_sweep(path: str | pathlib.Path, announce: Callable[[str], None] | None = None) -> Sweep:
    """Read and validate a sweep file; raise :class:`SweepFileError` naming the first bad key.

    A sweep file::

        [protocol]                  # any Protocol option, plus fixed hyperparameters "ALGO.FIELD"
        algorithms = ["rmac"] experiments = 10 evaluate_every = 10
        [grid]                      # every combination of these values
        "rmac.alpha_r" = [0.005, 0.01, 0.02] "rmac.critic_weights" = [[1, 0.1], [1, 0.3]]
        [[variant]]                 # optional: named sets of overrides, crossed with the grid
        name = "oldest" "rmac.critic_replacement" = "oldest"

    Hyperparameter keys name fields of the learner's config dataclass, nested fields allowed
    (``rmac.exploration.sigma``); ``agent_configs`` is made up from them. Each configuration
    (variant x grid point) is a Protocol named after its swept values
    (``alpha_r=0.01__critic_weights=1,0.1``); a ``--config`` file is the same tables with single
    values.

    ``announce`` hears the sweep's size (configurations, experiments) as soon as it is known, before
    every configuration is built and checked (seconds for a large grid)."""
    path = pathlib.Path(path)
    document = read_toml(path)
    check = _Checker(path)
    options, fixed = check.protocol(document)
    algorithms = options.get("algorithms", Protocol().algorithms)
    grid = {}
    for key, values in flatten(check.table(document, "grid")).items():
        where = f'[grid] "{key}"'
        hint = check.hyperparameter(key, algorithms, where)
        if not isinstance(values, list):
            raise check.error(
                where,
                f"expected a list of values to sweep, e.g. [{_toml(values)}, ...]; "
                f"got {_toml(values)}",
            )
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
    count = max(1, len(variants)) * math.prod(len(values) for values in grid.values())
    if count > constraints.SWEEP_CONFIGURATIONS.value:  # counted, never enumerated, before refusing
        raise check.error(
            "[grid]",
            constraints.SWEEP_CONFIGURATIONS.refusal("the number of configurations", count)
            + f" ({' x '.join(str(n) for n in _factors(variants, grid))}): sweep fewer values",
        )
    if announce is not None:
        per = options.get("experiments", Protocol().experiments) * len(algorithms)
        announce(
            f"{path}: {count} configuration{'s' * (count != 1)} x {per} experiments = "
            f"{count * per} experiments of {options.get('trials', Protocol().trials)} trials; "
            "checking every configuration"
        )
    configurations = _configurations(check, options, fixed, grid, variants)
    return Sweep(
        path=path,
        options=options,
        fixed=fixed,
        grid=grid,
        variants=variants,
        configurations=configurations,
    )


def _factors(variants: tuple, grid: dict) -> list[int]:
    """The sizes whose product is a sweep's number of configurations: variants, then each grid key's."""
    return ([len(variants)] if variants else []) + [len(values) for values in grid.values()]


def load_configuration(
    path: str | pathlib.Path, completion: dict[str, Any] | None = None
) -> SingleConfiguration:
    """Read a ``reproduce --config`` file: the sweep tables with single values.

    A [grid] entry gives one value (a one-element list is taken as that value); a list of several
    values, or more than one [[variant]], is refused: that is a sweep. ``completion``: Protocol
    options given beside the file (the command line's ``--env``), with which the file is checked
    (a file of ``trial_steps`` for the environment the command line names); the options returned
    are the file's own.
    """
    path = pathlib.Path(path)
    document = read_toml(path)
    check = _Checker(path, completion)
    options, fixed = check.protocol(document)
    algorithms = options.get("algorithms", Protocol().algorithms)
    overrides = dict(fixed)
    for key, value in flatten(check.table(document, "grid")).items():
        where = f'[grid] "{key}"'
        hint = check.hyperparameter(key, algorithms, where)
        if constraints.unmet(value, hint) is not None and isinstance(value, list):
            if len(value) != 1:
                raise check.error(
                    where,
                    f"lists {len(value)} values; --config runs one configuration "
                    "(give one value, or run the file with `rmac-mj sweep`)",
                )
            value = value[0]
        check.value(value, hint, where, key, fixed)
        if key in fixed:
            raise check.error(where, "is also set in [protocol]; set it in one place")
        overrides[key] = value
    variants = check.variants(
        document, algorithms, fixed, {k: [v] for k, v in overrides.items() if k not in fixed}
    )
    if len(variants) > 1:
        raise check.error(
            "[[variant]]",
            f"{len(variants)} variants; --config runs one configuration "
            "(keep one, or run the file with `rmac-mj sweep`)",
        )
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

    def __init__(self, path: pathlib.Path, completion: dict[str, Any] | None = None):
        from rmac_mj.experiments import admission

        self.path = path
        #: Protocol options given beside the file (a command line's --env) that complete it.
        self.completion = dict(completion or {})
        self._facts = admission.TaskFacts()  # each distinct task's spaces, asked once

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
                raise self.error(
                    f"[{section}]",
                    f"unknown section{hint}; a sweep file has "
                    "[protocol], [grid], [[variant]] and "
                    "[learner_state]",
                )
        if "variant" in document and not (
            isinstance(document["variant"], list)
            and all(isinstance(v, dict) for v in document["variant"])
        ):
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
                raise self.error(
                    f"[protocol] {key}",
                    f"unknown key{hint}; known: "
                    f'{", ".join(PROTOCOL_KEYS)}, or a hyperparameter "ALGO.FIELD"',
                )
        if "learner_state" in document:
            if "learner_state" in options:
                raise self.error(
                    "[learner_state]", "is also set in [protocol]; set it in one place"
                )
            options["learner_state"] = self.option(
                "learner_state", self.table(document, "learner_state")
            )
        algorithms = options.get("algorithms", Protocol().algorithms)
        for key, value in hyper.items():
            where = f'[protocol] "{key}"'
            self.value(value, self.hyperparameter(key, algorithms, where), where, key)
        self.protocol_object(options, nest(hyper), "[protocol]")
        return options, hyper

    def option(self, key: str, value: Any) -> Any:
        """A [protocol] option checked against its Protocol field's constraints; lists become the
        tuples Protocol holds."""
        where = f"[protocol] {key}"
        if key == "algorithms" and isinstance(value, str):
            value = [a.strip() for a in value.split(",") if a.strip()]
        problem = constraints.unmet(value, constraints.lookup(Protocol, [key]))
        if problem is not None:
            raise self.error(where, f"expected {problem}, got {_toml(value)}")
        if key == "algorithms":
            for name in value:
                if name not in ALGORITHMS:
                    raise self.error(
                        where, f"unknown algorithm {name!r}; available: {', '.join(ALGORITHMS)}"
                    )
        return tuple(value) if isinstance(value, list) else value

    def protocol_object(self, options: dict, agent_configs: dict, where: str) -> Protocol:
        """Build the Protocol (with the options that complete the file); a value its validation
        rejects is reported against ``where``."""
        from rmac_mj import tasks

        options = {**options, **self.completion}
        domain = options.get("domain", Protocol().domain)
        task = options.get("task", Protocol().task)
        # An outside environment (env) is checked by Protocol, with no domain/task beside it.
        if options.get("env") is None:
            if domain not in tasks.TASKS_BY_DOMAIN:
                raise self.error(
                    "[protocol] domain",
                    f"unknown domain {domain!r}; available: {', '.join(tasks.TASKS_BY_DOMAIN)}",
                )
            if task not in tasks.TASKS_BY_DOMAIN[domain]:
                raise self.error(
                    "[protocol] task",
                    f"unknown task {task!r} of {domain}; "
                    f"available: {', '.join(tasks.TASKS_BY_DOMAIN[domain])}",
                )
        try:
            return Protocol(**options, agent_configs=agent_configs)
        except (ValueError, TypeError) as error:
            raise self.error(where or "[protocol]", str(error)) from None

    def agents(self, protocol: Protocol, where: str) -> None:
        """Build each learner of ``protocol`` on its task: catches what only the task's spaces
        reveal (e.g. input weights of the wrong length) before anything runs; a learner whose
        estimated memory cannot fit the machine is refused before it is built."""
        from rmac_mj.agents import make_agent
        from rmac_mj.experiments import admission

        state_space, action_space = self._facts.of(protocol)
        for algorithm in protocol.algorithms:
            try:
                admission.check_memory([protocol], 1, self._facts, algorithms=[algorithm])
                make_agent(
                    algorithm,
                    state_space,
                    action_space,
                    config=protocol.agent_configs.get(algorithm),
                    seed=0,
                )
            except (ValueError, TypeError) as error:
                raise self.error(where, f"{algorithm}: {error}") from None

    def hyperparameter(self, key: str, algorithms: Iterable[str], where: str) -> list:
        """The constraints of the hyperparameter ``key`` ("ALGO.FIELD[.FIELD]"), from its config's
        table (:mod:`rmac_mj.constraints`)."""
        algorithm, *path = key.split(".")
        if not path or not all(path):
            raise self.error(where, 'expected a hyperparameter "ALGO.FIELD", e.g. "rmac.alpha_r"')
        if algorithm not in ALGORITHMS:
            raise self.error(
                where, f"unknown algorithm {algorithm!r}; available: {', '.join(ALGORITHMS)}"
            )
        if algorithm not in algorithms:
            raise self.error(
                where,
                f"sets {algorithm}, which the protocol does not run (algorithms = "
                f"{_toml(list(algorithms))})",
            )
        try:
            return constraints.lookup(config_class(algorithm), path)
        except constraints.InvalidParameterError as error:
            raise self.error(where, str(error)) from None

    def value(
        self,
        value: Any,
        allowed: list,
        where: str,
        key: str | None = None,
        base: dict[str, Any] | None = None,
    ) -> None:
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

    def variants(
        self, document: dict, algorithms, fixed: dict, grid: dict
    ) -> tuple[tuple[str, dict[str, Any]], ...]:
        variants, names = [], set()
        for number, table in enumerate(document.get("variant", []), start=1):
            name = table.get("name")
            label = f"[[variant]] #{number}"
            if not isinstance(name, str) or not name.strip():
                raise self.error(
                    f"{label} name",
                    f"each variant needs a name (a non-empty string), "
                    f"got {_toml(name) if name is not None else 'none'}",
                )
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


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


# ----------------------------------------------------------------------------------------------------
# Configurations and their names.


def value_label(value: Any) -> str:
    if isinstance(value, list):
        return ",".join(value_label(v) for v in value)
    if isinstance(value, dict):
        return "+".join(f"{k}-{value_label(v)}" for k, v in value.items())
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def short_names(keys: list[str]) -> dict[str, str]:
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
    parts = ([variant] if variant is not None else []) + [
        f"{short[key]}={value_label(value)}" for key, value in values.items()
    ]
    name = _UNSAFE.sub("_", "__".join(parts)) or "base"
    return name.lstrip(".") or "base"


def _configurations(
    check: _Checker, options: dict, fixed: dict, grid: dict, variants: tuple
) -> tuple[Configuration, ...]:
    short = short_names(list(grid))
    configurations, seen = [], {}
    for variant, variant_values in variants or ((None, {}),):
        for point in itertools.product(*grid.values()):
            values = dict(zip(grid, point))
            agent_configs = nest({**fixed, **variant_values, **values})
            where = (
                ", ".join(
                    [f"variant {variant!r}"] * (variant is not None)
                    + [f'"{k}" = {_toml(v)}' for k, v in values.items()]
                )
                or "[protocol]"
            )
            protocol = check.protocol_object(options, agent_configs, f"configuration {where}")
            check.agents(protocol, f"configuration {where}")
            name = configuration_name(variant, values, short)
            if len(name) > 120 or name in seen:  # very long or (after sanitising) not unique
                digest = hashlib.sha256(
                    json.dumps([variant, values], sort_keys=True).encode()
                ).hexdigest()[:8]
                name = f"{name[:100]}-{digest}"
            seen[name] = True
            configurations.append(
                Configuration(name=name, variant=variant, values=values, protocol=protocol)
            )
    return tuple(configurations)
