"""Sweep and ``reproduce --config`` files: TOML read and validated before anything runs.

Tables ``[protocol]`` (:class:`~rmac_mj.experiments.protocol.Protocol` options, fixed
``ALGO.FIELD``), ``[grid]`` and ``[[variant]]`` (the format: :func:`load_sweep`); any bad section,
key or value raises :class:`SweepFileError` naming the file and the key. Each configuration is
named after its swept values (:func:`configuration_name`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import pathlib
import re
from collections.abc import Callable, Sequence
from typing import Any

from rmac_mj import constraints
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.results import files
from rmac_mj.sweeps import bounded_toml
from rmac_mj.sweeps.bounded_toml import as_toml, flatten, merge, nest
from rmac_mj.sweeps.sweep_checks import (
    PROTOCOL_KEYS,
    SECTIONS,
    SweepFileChecker,
    SweepFileError,
)

__all__ = [
    "PROTOCOL_KEYS",
    "SECTIONS",
    "Configuration",
    "SingleConfiguration",
    "Sweep",
    "SweepFileError",
    "configuration_name",
    "flatten",
    "is_number",
    "load_configuration",
    "load_sweep",
    "merge",
    "nest",
    "read_toml",
    "short_names",
    "value_label",
]


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
      sizes: the [protocol] sizes the command line gave over the file's (``experiments``,
        ``trials``, ``steps``); already in ``options``.
    """

    path: pathlib.Path
    options: dict[str, Any]
    fixed: dict[str, Any]
    grid: dict[str, list]
    variants: tuple[tuple[str, dict[str, Any]], ...]
    configurations: tuple[Configuration, ...]
    sizes: dict[str, int] = dataclasses.field(default_factory=dict)

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
    """The TOML document at ``path``, read within the declared limits
    (:func:`~rmac_mj.sweeps.bounded_toml.read_toml`); a missing, oversized, too deeply nested,
    malformed or empty file is a :class:`UserInputError` naming it."""
    document = bounded_toml.read_toml(path, SweepFileError)
    if not document:
        raise SweepFileError(
            f"{path}: holds nothing; a sweep or --config file sets [protocol] options, a [grid] "
            "or [[variant]] tables (docs/guide/sweeps.md)"
        )
    return document


def load_sweep(
    path: str | pathlib.Path,
    announce: Callable[[str], None] | None = None,
    sizes: dict[str, int] | None = None,
) -> Sweep:
    """Read and validate a sweep file; raise :class:`SweepFileError` naming the first bad key.

    A sweep file::

        [protocol]                  # any Protocol option, plus fixed hyperparameters "ALGO.FIELD"
        algorithms = ["rmac"] experiments = 10 evaluate_every = 10
        [grid]                      # every combination of these values
        "rmac.alpha_r" = [0.005, 0.01, 0.02] "rmac.critic.weights" = [[1, 0.1], [1, 0.3]]
        [[variant]]                 # optional: named sets of overrides, crossed with the grid
        name = "oldest" "rmac.critic.replacement" = "oldest"

    Hyperparameter keys name fields of the learner's config dataclass, nested fields allowed
    (``rmac.exploration.sigma``); ``agent_configs`` is made up from them. Each configuration
    (variant x grid point) is a Protocol named after its swept values
    (``alpha_r=0.01__weights=1,0.1``); a ``--config`` file is the same tables with single
    values.

    ``announce`` hears the sweep's size (configurations, experiments) as soon as it is known, before
    every configuration is built and checked (seconds for a large grid). ``sizes``: some of
    ``experiments``, ``trials`` and ``steps`` that replace the file's (the command line's)."""
    path = pathlib.Path(path)
    document = read_toml(path)
    check = SweepFileChecker(path, sizes)
    options, fixed = check.protocol(document)
    sizes = dict(sizes or {})
    options = {**options, **sizes}
    algorithms = options.get("algorithms", Protocol().algorithms)
    grid = _grid(check, document, algorithms, fixed)
    variants = check.variants(document, algorithms, fixed, grid)
    count = max(1, len(variants)) * math.prod(len(values) for values in grid.values())
    if count > constraints.SWEEP_CONFIGURATIONS.value:  # counted, never enumerated, before refusing
        raise check.error(
            "[grid]",
            constraints.SWEEP_CONFIGURATIONS.refusal("the number of configurations", count)
            + f" ({' x '.join(str(n) for n in _factors(variants, grid))}): sweep fewer values",
        )
    if announce is not None:
        announce(_size_said(path, options, sizes, count))
    configurations = _configurations(check, options, fixed, grid, variants)
    return Sweep(
        path=path,
        options=options,
        fixed=fixed,
        grid=grid,
        variants=variants,
        configurations=configurations,
        sizes=sizes,
    )


def _grid(
    check: SweepFileChecker, document: dict, algorithms: Sequence[str], fixed: dict
) -> dict[str, list]:
    """The file's [grid]: each hyperparameter's values to sweep, checked (a list of distinct
    values the field takes, the key not also fixed in [protocol])."""
    grid = {}
    for key, values in flatten(check.table(document, "grid")).items():
        where = f'[grid] "{key}"'
        hint = check.hyperparameter(key, algorithms, where)
        if not isinstance(values, list):
            raise check.error(
                where,
                f"expected a list of values to sweep, e.g. [{as_toml(values)}, ...]; "
                f"got {as_toml(values)}",
            )
        if not values:
            raise check.error(where, "the list of values is empty")
        for value in values:
            check.value(value, hint, f"{where} value {as_toml(value)}", key, fixed)
        if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
            raise check.error(where, f"repeats a value in {as_toml(values)}")
        if key in fixed:
            raise check.error(where, "is also set in [protocol]; set it in one place")
        grid[key] = values
    return grid


def _size_said(path: pathlib.Path, options: dict, sizes: dict[str, int], count: int) -> str:
    """The sweep's size in one line: configurations x experiments, each of how many trials."""
    algorithms = options.get("algorithms", Protocol().algorithms)
    per = options.get("experiments", Protocol().experiments) * len(algorithms)
    trials = options.get("trials", Protocol().trials)
    size = (
        f"{trials} trials"
        if options.get("steps") is None
        else f"{options['steps']} env steps (at most {trials} trials)"
    )
    given = "".join(f" --{key} {value}" for key, value in sizes.items())
    return (
        f"{path}{given and f' with{given}'}: {count} configuration{'s' * (count != 1)} x "
        f"{per} experiments = {count * per} experiments of {size}; checking every "
        "configuration"
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
    check = SweepFileChecker(path, completion)
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


def _configurations(
    check: SweepFileChecker, options: dict, fixed: dict, grid: dict, variants: tuple
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
                    + [f'"{k}" = {as_toml(v)}' for k, v in values.items()]
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


# -- a configuration's name from its swept values: each value's label, each key's shortest
# distinct suffix, a directory name that is safe on any file system


def is_number(value: Any) -> bool:
    """Whether ``value`` is a number (a bool is not): a swept axis of numbers is drawn to scale."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


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
