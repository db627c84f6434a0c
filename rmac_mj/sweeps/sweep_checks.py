"""The checks of a sweep or ``--config`` file's tables against the Protocol's and the learners'
constraints: every failure a :class:`SweepFileError` whose message names the file and the key."""

from __future__ import annotations

import dataclasses
import difflib
import pathlib
from collections.abc import Iterable
from typing import Any

from rmac_mj import constraints
from rmac_mj.agents import ALGORITHMS, config_class, config_from_dict
from rmac_mj.errors import UserInputError
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.sweeps.bounded_toml import as_toml, flatten, nest

#: The tables a sweep file may have. [learner_state] is the Protocol option of that name written as a
#: table of its own: what x is in an outside environment (``env``) where it cannot be inferred.
SECTIONS = ("protocol", "grid", "variant", "learner_state")
#: Protocol options a [protocol] table may set: the fields of Protocol but agent_configs.
PROTOCOL_KEYS = tuple(
    field.name for field in dataclasses.fields(Protocol) if field.name != "agent_configs"
)


class SweepFileError(UserInputError):
    """A sweep (or --config) file that cannot be run: the message names the file and the key."""


class SweepFileChecker:
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
            raise self.error(f"[{section}]", f"expected a table, got {as_toml(value)}")
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
            raise self.error(where, f"expected {problem}, got {as_toml(value)}")
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
        from rmac_mj.experiments import admission

        for algorithm in protocol.algorithms:
            try:
                admission.check_memory([protocol], 1, self._facts, algorithms=[algorithm])
                admission.configured_agent(protocol, algorithm, self._facts)
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
                f"{as_toml(list(algorithms))})",
            )
        try:
            return constraints.lookup(config_class(algorithm), path, f"{algorithm}.")
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
            raise self.error(where, f"expected {problem}, got {as_toml(value)}")
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
                    f"got {as_toml(name) if name is not None else 'none'}",
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
