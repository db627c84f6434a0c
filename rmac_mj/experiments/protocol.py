"""What is run: the paper's protocol (section 6, :class:`Protocol`), its checks and its environment.

An experiment of it is assembled by :mod:`~rmac_mj.experiments.experiment` and run by
:mod:`~rmac_mj.experiments.experiment_loop`.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import numbers
import pathlib
from typing import Any, ClassVar

from dm_control.rl import control

from rmac_mj import constraints, envs, tasks
from rmac_mj.agents import (
    ALGORITHMS,
    PRIOR_PARTS,
    agent_class,
    config_class,
    config_from_dict,
    unknown_algorithm,
)
from rmac_mj.envs import spec as env_spec
from rmac_mj.errors import MissingExtra, UserInputError
from rmac_mj.results import files


class _Empty(constraints.Constraint):
    """An empty list (of snapshot trials, or of prior parts: none)."""

    def satisfied(self, value: Any, context: Any = None) -> bool:
        return isinstance(value, (tuple, list)) and len(value) == 0

    def normalise(self, value: Any) -> tuple:
        return ()

    def describe(self, context: Any = None) -> str:
        return "an empty list"


_EMPTY = _Empty()


@dataclasses.dataclass(frozen=True)
class Protocol:
    """What is run: the paper's protocol by default (section 6: 40 experiments of 600 trials).

    Attributes:
      domain, task: the environment, loaded with ``rmac_mj.tasks.load`` (see :meth:`make_environment`,
        the one place an experiment's environment is built); None with ``env``.
      task_kwargs: task arguments (not ``random``, which comes from the seed); with ``env``, the outside
        environment's kwargs (``rmac_mj.envs.EnvSpec.kwargs``).
      algorithms: algorithm keys, from ``rmac_mj.agents.ALGORITHMS``.
      experiments: learning experiments per algorithm.
      trials: consecutive learning trials per experiment (with ``steps``: at most this many).
      steps: a budget of environment steps per experiment (learner steps times the action repeat;
        greedy evaluations do not count): trials run until the experiment has taken ``steps``, and
        the trial that reaches it runs to its end (a curve holds whole episodes), so an experiment
        takes at least ``steps`` and at most one trial more; or until ``trials``. None: ``trials``
        alone. Experiments whose episodes end early then hold different numbers of trials.
      seed: root of every experiment's random stream.
      evaluate_every: after every this many learning trials, one greedy trial (no exploration, no
        learning) is recorded; 0 disables it.
      snapshot_trials: after which trials the agent is saved; stored sorted, without trials beyond
        ``trials``, and with the final trial, which is always saved.
      agent_configs: per algorithm, overrides of its hyperparameters (e.g. for ablations).
      prior: prior knowledge seeded into every fresh agent before its first trial: None (none, the
        paper's protocol), the name of a demonstrator the task declares (``'demo'``, see
        ``tasks.knowledge``), or the path of a recorded ``.npz`` file
        (``experiments.prior``). Every learner must take prior knowledge.
      prior_trials: trials of the demonstrator recorded per experiment (demonstrators only).
      prior_parts: which kinds of knowledge to seed (``base.PRIOR_PARTS``, e.g. ``('process',)`` for
        the recorded dynamics alone); empty: everything each learner takes.
      evaluate_starts: what an evaluation is: 0, one greedy trial from the experiment's next start
        (the task's own stream; right for a task that always starts alike); N, the mean of N greedy
        trials from N starts drawn once per experiment by an environment of its own (seeded from
        ``(i, 2)``), the same N at every evaluation, so that the curve follows the policy and not the
        starts (Gymnasium's Pendulum-v1 starts anywhere).
      env: an outside environment by SPEC (``rmac_mj.envs``: ``dm_control:DOMAIN/TASK``,
        ``gymnasium:ID``, ``package.module:factory``, ``path/file.py:factory``) instead of
        ``domain``/``task``. With it, and only with it:
      learner_state: what x is where it cannot be inferred: some of LearnerStateSpec's fields, or
        ``bounds`` per dimension (a ``[learner_state]`` table; ``rmac_mj.envs.EnvSpec``).
      action_repeat: environment steps per learner step, the same action held (rewards summed).
      trial_steps: learner steps after which a trial is truncated; None: the environment's limit.
      control_timestep: seconds per environment step, for an environment that does not say.
    """

    domain: str = tasks.DEFAULT_TASK[0]
    task: str = tasks.DEFAULT_TASK[1]
    task_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    algorithms: tuple[str, ...] = ("rmac", "s-ac")
    experiments: int = 40
    trials: int = 600
    steps: int | None = None
    seed: int = 0
    evaluate_every: int = 0
    snapshot_trials: tuple[int, ...] = (1, 10, 50, 200)
    agent_configs: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)
    prior: str | None = None
    prior_trials: int = 5
    prior_parts: tuple[str, ...] = ()
    evaluate_starts: int = 0
    env: str | None = None
    learner_state: dict[str, Any] | None = None
    action_repeat: int = 1
    trial_steps: int | None = None
    control_timestep: float | None = None

    #: The type and range of every field (:mod:`rmac_mj.constraints`); the sweep file's [protocol]
    #: table is checked against the same rules.
    parameter_constraints: ClassVar[dict[str, list]] = {
        "domain": [constraints.InstanceOf(str), None],
        "task": [constraints.InstanceOf(str), None],
        "task_kwargs": [constraints.InstanceOf(dict)],
        "algorithms": [
            constraints.TupleOf(
                constraints.InstanceOf(str), what="a list of one or more algorithm names"
            )
        ],
        "experiments": [constraints.EXPERIMENTS.constraint()],
        "trials": [constraints.TRIALS.constraint()],
        "steps": [constraints.Interval(numbers.Integral, 1, None), None],
        "seed": [constraints.Interval(numbers.Integral, 0, None)],
        "evaluate_every": [constraints.Interval(numbers.Integral, 0, None)],
        "snapshot_trials": [
            constraints.TupleOf(constraints.Interval(numbers.Integral, 1, None)),
            _EMPTY,
        ],
        "agent_configs": [constraints.InstanceOf(dict)],
        "prior": [constraints.InstanceOf(str), None],
        "prior_trials": [constraints.PRIOR_TRIALS.constraint()],
        "prior_parts": [constraints.TupleOf(constraints.Options(*PRIOR_PARTS)), _EMPTY],
        "evaluate_starts": [constraints.EVALUATE_STARTS.constraint()],
        "env": [constraints.InstanceOf(str), None],
        "learner_state": [constraints.InstanceOf(dict), None],
        "action_repeat": [constraints.ACTION_REPEAT.constraint()],
        "trial_steps": [constraints.TRIAL_STEPS.constraint(), None],
        "control_timestep": [
            constraints.Interval(numbers.Real, constraints.MIN_CONTROL_TIMESTEP, None),
            None,
        ],
    }
    #: The fields that describe an outside environment (``env``); they mean nothing without it.
    ENV_FIELDS: ClassVar[tuple[str, ...]] = (
        "learner_state",
        "action_repeat",
        "trial_steps",
        "control_timestep",
    )

    def __post_init__(self) -> None:
        if isinstance(self.algorithms, (tuple, list)):
            for name in self.algorithms:
                if name not in ALGORITHMS:
                    raise unknown_algorithm(name)
                missing = agent_class(name).missing_requirement()
                if missing is not None:  # refused before anything runs, naming the extra
                    raise MissingExtra(missing)
        constraints.check_config(self)
        if len(set(self.algorithms)) != len(self.algorithms):
            raise ValueError(f"algorithms must not repeat, got {self.algorithms}")
        object.__setattr__(
            self,
            "snapshot_trials",
            tuple(sorted({t for t in self.snapshot_trials if t <= self.trials} | {self.trials})),
        )
        if self.env is not None:
            self._check_env()
        else:
            self._check_suite_task()
        for name, overrides in self.agent_configs.items():
            if name not in ALGORITHMS:
                raise unknown_algorithm(name, "agent_configs names unknown algorithm")
            config_from_dict(config_class(name), overrides)  # raises on unknown or bad values
        self._check_prior()

    def _check_suite_task(self) -> None:
        given = [name for name in self.ENV_FIELDS if getattr(self, name) != _FIELD_DEFAULTS[name]]
        if given:  # named as in a [protocol] table and as the command line's option
            named = ", ".join(f"{name} (--{name.replace('_', '-')})" for name in given)
            verb = "describes" if len(given) == 1 else "describe"
            raise ValueError(f"{named} {verb} an outside environment: give env (--env) too")
        if self.domain not in tasks.TASKS_BY_DOMAIN:
            raise ValueError(
                f"unknown domain {self.domain!r}; available: "
                f"{', '.join(sorted(tasks.TASKS_BY_DOMAIN))}{envs.hint_for(self.domain)}"
            )
        if self.task not in tasks.TASKS_BY_DOMAIN[self.domain]:
            raise ValueError(
                f"unknown task {self.task!r} of domain {self.domain!r}; available: "
                f"{', '.join(tasks.TASKS_BY_DOMAIN[self.domain])}"
            )
        if "random" in self.task_kwargs:
            raise ValueError("task_kwargs must not set 'random': the task's seed comes from `seed`")

    def _check_env(self) -> None:
        """An outside environment: domain/task give way (None); the spec is resolved now, so that a
        learner state that cannot be inferred is refused before anything runs."""
        if (self.domain, self.task) not in ((None, None), tasks.DEFAULT_TASK):
            raise ValueError(
                f"env {self.env!r} and domain/task {self.domain}/{self.task} name two "
                f"environments: give one"
            )
        object.__setattr__(self, "domain", None)
        object.__setattr__(self, "task", None)
        # Where the environment comes from, exactly: a file's path resolved and its bytes digested
        # before they run, so that every experiment, a resume and a snapshot's reader use that.
        object.__setattr__(self, "env", env_spec.canonical(self.env))
        object.__setattr__(self, "_origin", env_spec.origin(self.env))
        _resolved(self.environment_spec)

    def _check_prior(self) -> None:
        if self.prior is None:
            if self.prior_parts:
                raise ValueError("prior_parts needs prior knowledge: set prior too")
            return
        if not self.prior:
            raise ValueError(
                f"prior must be a demonstrator name or a .npz path, got {self.prior!r}"
            )
        if not self.prior.endswith(".npz"):
            self.knowledge.demonstrator(
                self.prior, self.environment_name
            )  # raises, naming what exists
        refusing = [a for a in self.algorithms if not agent_class(a).prior_parts]
        if refusing:
            taking = [a for a in ALGORITHMS if agent_class(a).prior_parts]
            verb = "does" if len(refusing) == 1 else "do"
            raise ValueError(
                f"{', '.join(refusing)} {verb} not take prior knowledge: run only "
                f"learners that do ({', '.join(taking)}), e.g. --algorithms "
                f"{','.join(taking)}"
            )
        for name in self.algorithms:
            lacking = sorted(set(self.prior_parts) - set(agent_class(name).prior_parts))
            if lacking:
                raise ValueError(
                    f"{name} takes no {', '.join(lacking)} prior (it takes "
                    f"{', '.join(agent_class(name).prior_parts)})"
                )

    @property
    def knowledge(self) -> tasks.common.TaskKnowledge:
        """What the protocol's task declares beyond its environment (reference, demonstrators, plot
        hints: ``rmac_mj.tasks.knowledge``); an outside environment declares none."""
        if self.env is not None:
            return tasks.common.NOTHING_KNOWN
        return tasks.knowledge(self.domain, self.task)

    @property
    def environment_name(self) -> str:
        """The environment, as people read it: ``domain/task``, or an outside one's SPEC."""
        return self.env if self.env is not None else f"{self.domain}/{self.task}"

    @property
    def environment_spec(self) -> envs.EnvSpec | None:
        """The outside environment as declared (``rmac_mj.envs.EnvSpec``), None for the suite's."""
        if self.env is None:
            return None
        return envs.EnvSpec(
            self.env,
            kwargs=self.task_kwargs,
            learner_state=self.learner_state,
            action_repeat=self.action_repeat,
            trial_steps=self.trial_steps,
            control_timestep=self.control_timestep,
        )

    @property
    def environment_origin(self) -> dict[str, Any] | None:
        """Where the outside environment came from when the protocol was made
        (``rmac_mj.envs.spec.origin``: a file's path and SHA-256, a registry's package and version);
        None for the suite's tasks, whose code is the package's."""
        return getattr(self, "_origin", None)

    @property
    def measured_bounds(self) -> dict[str, list[float]] | None:
        """The dimensions of x whose box the outside environment's specs do not give and nobody
        declared, as measured from random-action rollouts (``rmac_mj.envs.EnvSpec.resolve``): name
        -> [low, high]; None when there are none."""
        if self.env is None:
            return None
        found = _resolved(self.environment_spec).measured_bounds
        return {name: list(bound) for name, bound in found.items()} if found else None

    def environment_description(self) -> dict[str, Any]:
        """What a snapshot records to rebuild the environment: the suite's ``domain``, ``task`` and
        ``task_kwargs``, or an outside environment's resolved spec under ``environment``."""
        if self.env is not None:
            return {
                "environment": _resolved(self.environment_spec).as_dict(),
                "environment_origin": self.environment_origin,
            }
        return {"domain": self.domain, "task": self.task, "task_kwargs": self.task_kwargs}

    def make_environment(self, task_seed: int | None = None) -> control.Environment:
        """The protocol's environment, its task's random state seeded with ``task_seed`` (None:
        unseeded). Every environment of a run is built here."""
        if self.env is not None:
            if env_spec.user_code(self.env):  # a run is one environment, in every worker
                problem = env_spec.origin_problem(
                    self.environment_origin, env_spec.origin(self.env)
                )
                if problem is not None:
                    raise UserInputError(
                        f"env {self.env!r} changed during the run ({problem}): a run is one "
                        "environment; put it back and --resume, or start another run"
                    )
            return _resolved(self.environment_spec).make(task_seed)
        kwargs = dict(self.task_kwargs)
        if task_seed is not None:
            kwargs["random"] = task_seed
        return tasks.load(self.domain, self.task, task_kwargs=kwargs)

    @property
    def prior_file(self) -> pathlib.Path | None:
        """The recorded prior knowledge file, when ``prior`` names one."""
        return pathlib.Path(self.prior) if self.prior and self.prior.endswith(".npz") else None

    @property
    def is_paper_protocol(self) -> bool:
        """True when the paper's protocol is run unchanged (both learners, default settings)."""
        default = Protocol()
        return (
            self.env,
            self.domain,
            self.task,
            self.task_kwargs,
            set(self.algorithms),
            self.experiments,
            self.trials,
            self.agent_configs,
            self.prior,
        ) == (
            default.env,
            default.domain,
            default.task,
            default.task_kwargs,
            set(default.algorithms),
            default.experiments,
            default.trials,
            default.agent_configs,
            default.prior,
        )

    def as_dict(self) -> dict[str, Any]:
        """The protocol as JSON data (what ``config.json`` stores); :meth:`from_dict` reads it back."""
        return files.as_jsonable(self)

    @classmethod
    def from_dict(cls, document: dict[str, Any]) -> Protocol:
        """The protocol of :meth:`as_dict`'s document (lists back to tuples); ValueError or TypeError
        naming what is wrong with it."""
        if not isinstance(document, dict):
            raise TypeError(f"a protocol is a JSON object, got {type(document).__name__}")
        fields = {field.name for field in dataclasses.fields(cls)}
        unknown = sorted(set(document) - fields)
        if unknown:
            raise ValueError(f"unknown protocol fields {unknown}")
        values = dict(document)
        for name in ("algorithms", "snapshot_trials", "prior_parts"):
            if isinstance(values.get(name), list):
                values[name] = tuple(values[name])
        return cls(**values)


_FIELD_DEFAULTS = {field.name: field.default for field in dataclasses.fields(Protocol)}


@functools.lru_cache(maxsize=32)
def _resolved_from(document: str) -> envs.EnvSpec:
    return envs.EnvSpec(**json.loads(document)).resolve()


def _resolved(spec: envs.EnvSpec) -> envs.EnvSpec:
    """``spec`` with its full learner state, resolved once per process (inference probes an instance
    of the environment); ValueError naming what is missing or ambiguous."""
    return _resolved_from(json.dumps(spec.as_dict(), sort_keys=True))
