"""What is run: the paper's protocol (section 6, :class:`Protocol`) and one experiment of it.

Experiment i seeds its agent from ``SeedSequence(seed, spawn_key=(i,))``, its task from child ``(i,
0)``, its demonstration from ``(i, 1)``: results do not depend on workers or resuming.
:func:`build_experiment` assembles it, :func:`run_experiment` runs it.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import numbers
import pathlib
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from dm_control.rl import control

from rmac_mj import constraints, envs, tasks
from rmac_mj.agents import (
    ALGORITHMS,
    PRIOR_PARTS,
    ActionSpace,
    Agent,
    StateSpace,
    agent_class,
    config_class,
    config_from_dict,
    make_agent,
    unknown_algorithm,
)
from rmac_mj.errors import environment_failure_at
from rmac_mj.experiments import checkpoint as checkpoints
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.results import files, integrity
from rmac_mj.results.records import ExperimentResult
from rmac_mj.results.snapshots import snapshot_arrays, snapshot_state_problem
from rmac_mj.results.store import ResultStore
from rmac_mj.results.trial_log import TrialLog
from rmac_mj.rollout import action_space_of, run_counted_trial, run_trial, state_space_of


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
        "control_timestep": [constraints.Interval(numbers.Real, 0, None, closed="neither"), None],
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
        if given:
            raise ValueError(f"{', '.join(given)} describe an outside environment: give env too")
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
            return {"environment": _resolved(self.environment_spec).as_dict()}
        return {"domain": self.domain, "task": self.task, "task_kwargs": self.task_kwargs}

    def make_environment(self, task_seed: int | None = None) -> control.Environment:
        """The protocol's environment, its task's random state seeded with ``task_seed`` (None:
        unseeded). Every environment of a run is built here."""
        if self.env is not None:
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


def experiment_seeds(seed: int, index: int) -> tuple[np.random.SeedSequence, int]:
    """The agent's seed sequence and the task's integer seed of experiment ``index``."""
    agent_seq = np.random.SeedSequence(seed, spawn_key=(index,))
    task_seed = int(np.random.SeedSequence(seed, spawn_key=(index, 0)).generate_state(1)[0])
    return agent_seq, task_seed


def demonstration_for(protocol: Protocol, index: int) -> prior_data.Demonstration:
    """``prior_trials`` trials of demonstrator ``protocol.prior`` for experiment ``index``, recorded
    deterministically from the sequence ``(index, 1)``: its child 0 seeds the recording's task, the
    sequence itself the demonstrator's action noise."""
    demonstrator = protocol.knowledge.demonstrator(protocol.prior, protocol.environment_name)
    sequence = np.random.SeedSequence(protocol.seed, spawn_key=(index, 1))
    task_seed = int(
        np.random.SeedSequence(protocol.seed, spawn_key=(index, 1, 0)).generate_state(1)[0]
    )
    env = protocol.make_environment(task_seed)
    return prior_data.record(
        env,
        demonstrator.controller(env),
        protocol.prior_trials,
        seed=np.random.default_rng(sequence),
        action_noise=demonstrator.action_noise,
    )


@dataclasses.dataclass
class Experiment:
    """Experiment ``index`` of ``algorithm``, assembled and ready for its first trial.

    Attributes:
      env: its environment, the task's random state seeded with ``task_seed``.
      agent: the fresh agent, its generator from the experiment's seed sequence, already seeded with
        the prior knowledge of ``demonstration`` (if any).
      state_space, action_space: the task's, as the agent sees them.
      demonstration: the prior knowledge seeded, or None.
    """

    algorithm: str
    index: int
    env: control.Environment
    agent: Agent
    state_space: StateSpace
    action_space: ActionSpace
    task_seed: int
    demonstration: prior_data.Demonstration | None


def build_experiment(
    protocol: Protocol,
    algorithm: str,
    index: int,
    demonstration: prior_data.Demonstration | None = None,
) -> Experiment:
    """Assemble experiment ``index`` of ``algorithm`` exactly as the runner does: its environment and
    fresh agent from the experiment's seeds, then the prior knowledge (``demonstration`` when the
    protocol's prior is a file the caller read; else recorded here from the protocol's demonstrator)."""
    agent_seq, task_seed = experiment_seeds(protocol.seed, index)
    env = protocol.make_environment(task_seed)
    state_space, action_space = state_space_of(env), action_space_of(env)
    agent = make_agent(
        algorithm,
        state_space,
        action_space,
        config=protocol.agent_configs.get(algorithm),
        seed=np.random.default_rng(agent_seq),
    )
    if protocol.prior is not None:
        if demonstration is None:
            demonstration = demonstration_for(protocol, index)
        agent.seed_from(**demonstration.arrays(), parts=protocol.prior_parts or None)
    return Experiment(
        algorithm=algorithm,
        index=index,
        env=env,
        agent=agent,
        state_space=state_space,
        action_space=action_space,
        task_seed=task_seed,
        demonstration=demonstration if protocol.prior is not None else None,
    )


def fresh_learners(protocol: Protocol) -> dict[str, Agent]:
    """A learner of each of the protocol's algorithms as its experiments begin (their config, on
    the protocol's environment; one environment built for all): what the files a run keeps are
    checked against (``Agent.check_state_dict``)."""
    env = protocol.make_environment(experiment_seeds(protocol.seed, 0)[1])
    state_space, action_space = state_space_of(env), action_space_of(env)
    return {
        algorithm: make_agent(
            algorithm,
            state_space,
            action_space,
            config=protocol.agent_configs.get(algorithm),
            seed=0,
        )
        for algorithm in protocol.algorithms
    }


def evaluation(protocol: Protocol, index: int) -> Callable[[control.Environment, Agent], float]:
    """How experiment ``index`` evaluates its agent (``Protocol.evaluate_starts``): a function
    ``(env, agent) -> greedy return``."""
    if protocol.evaluate_starts == 0:
        return lambda env, agent: run_trial(env, agent, learn=False)
    seed = int(np.random.SeedSequence(protocol.seed, spawn_key=(index, 2)).generate_state(1)[0])

    def evaluate(env: control.Environment, agent: Agent) -> float:
        starts = protocol.make_environment(seed)  # the same starts at every evaluation
        return float(
            np.mean(
                [run_trial(starts, agent, learn=False) for _ in range(protocol.evaluate_starts)]
            )
        )

    return evaluate


@dataclasses.dataclass(frozen=True)
class ExperimentSpec:
    """One learning experiment to run: ``algorithm`` number ``index`` of ``protocol``.

    ``stream_to``: the result directory whose live trial log (``ResultStore.progress_path``) receives
    every trial as it ends, and which keeps the experiment's checkpoint (``ResultStore.
    checkpoint_path``; :mod:`~rmac_mj.experiments.checkpoint`) every ``checkpoint_seconds`` of wall
    time, from which the experiment continues when run again; None streams and keeps nothing.
    ``demonstration``: the recorded prior knowledge when ``protocol.prior`` is a file (read once by
    the driver).
    """

    protocol: Protocol
    algorithm: str
    index: int
    stream_to: str | None = None
    demonstration: prior_data.Demonstration | None = None
    checkpoint_seconds: float = checkpoints.CHECKPOINT_SECONDS


def _kept_checkpoint(
    store: ResultStore,
    spec: ExperimentSpec,
    digest: str,
    agent: Agent,
    snapshot_trials: set[int],
) -> dict[str, Any] | None:
    """The experiment's checkpoint (:func:`checkpoints.read`) with ``snapshots``, the snapshots of
    the trials it has done as written, when all of them are what the run would have written: the
    learner state of the checkpoint and of every snapshot one ``agent`` (the experiment's fresh
    learner) can restore, every snapshot whole. Else None: the experiment starts from its first
    trial, as without a checkpoint, and gives the same result."""
    saved = checkpoints.read(store.checkpoint_path(spec.algorithm, spec.index), digest)
    if saved is None:
        return None
    try:
        agent.check_state_dict(saved["agent"])
    except (TypeError, ValueError):
        return None
    saved["snapshots"] = {}
    for trial in sorted(t for t in snapshot_trials if t <= len(saved["returns"])):
        path = store.snapshot_path(spec.algorithm, spec.index, trial)
        if integrity.snapshot_problem(path, spec.algorithm, trial) is not None:
            return None
        arrays = store.read_snapshot_arrays(spec.algorithm, spec.index, trial)
        if snapshot_state_problem(arrays, agent) is not None:
            return None
        saved["snapshots"][trial] = arrays
    return saved


def run_experiment(
    spec: ExperimentSpec, on_trial: Callable[[str, int, int, float], None] | None = None
) -> ExperimentResult:
    """Run one learning experiment; return its curve, greedy evaluations and snapshots.

    Nothing is written but the live trial log in ``spec.stream_to`` (if any), so it runs unchanged in
    a local worker process or on a remote Dask worker, and the caller decides where the results go.
    ``on_trial(algorithm, index, trial, return)`` is called after every learning trial.
    """
    protocol = spec.protocol
    name = f"{spec.algorithm} experiment {spec.index}"
    with environment_failure_at(f"{name}, building it"):
        experiment = build_experiment(protocol, spec.algorithm, spec.index, spec.demonstration)
    env, agent = experiment.env, experiment.agent
    meta = {**protocol.environment_description(), "experiment": spec.index, "seed": protocol.seed}
    evaluate = evaluation(protocol, spec.index)
    returns, env_steps = [], []
    greedy_trials, greedy_returns, snapshots = [], [], {}
    snapshot_trials = set(protocol.snapshot_trials) | {protocol.trials}
    store = ResultStore(spec.stream_to) if spec.stream_to is not None else None
    log_path = store.progress_path(spec.algorithm, spec.index) if store is not None else None
    digest = checkpoints.protocol_digest(protocol.as_dict())
    earlier_wall = earlier_cpu = 0.0
    saved = (
        _kept_checkpoint(store, spec, digest, agent, snapshot_trials) if store is not None else None
    )
    if saved is not None:  # continue where the checkpoint left off, exactly
        agent.load_state_dict(saved["agent"])
        checkpoints.restore_environment(env, saved["environment"])
        returns, env_steps = saved["returns"], saved["env_steps"]
        greedy_trials, greedy_returns = saved["greedy_trials"], saved["greedy_returns"]
        earlier_wall, earlier_cpu = saved["wall_time_s"], saved["cpu_time_s"]
        snapshots = saved["snapshots"]
    start, cpu_start = time.perf_counter(), time.process_time()
    last_checkpoint = start
    taken, trial = (env_steps[-1] if env_steps else 0), len(returns)
    with TrialLog(log_path) as log:
        for done, value in enumerate(returns, start=1):  # a continued experiment's earlier trials
            log.write(
                done,
                value,
                greedy_returns[greedy_trials.index(done)] if done in greedy_trials else None,
                env_steps[done - 1],
            )
        while trial < protocol.trials and (protocol.steps is None or taken < protocol.steps):
            trial += 1
            with environment_failure_at(f"{name}, trial {trial}"):
                value, steps = run_counted_trial(env, agent, learn=True)
            taken += steps
            returns.append(value)
            env_steps.append(taken)
            greedy = None
            if protocol.evaluate_every and trial % protocol.evaluate_every == 0:
                with environment_failure_at(f"{name}, greedy evaluation after trial {trial}"):
                    greedy = evaluate(env, agent)
                greedy_trials.append(trial)
                greedy_returns.append(greedy)
            last = trial == protocol.trials or (
                protocol.steps is not None and taken >= protocol.steps
            )
            if trial in snapshot_trials or last:
                snapshots[trial] = snapshot_arrays(
                    agent, experiment.state_space, experiment.action_space, trial=trial, **meta
                )
            log.write(trial, value, greedy, taken)
            now = time.perf_counter()
            if store is not None and not last and now - last_checkpoint >= spec.checkpoint_seconds:
                environment = checkpoints.environment_state(env)
                if environment is not None:
                    for (
                        done,
                        arrays,
                    ) in snapshots.items():  # written once; the curve's save rewrites
                        store.write_snapshot_arrays(spec.algorithm, spec.index, done, arrays)
                    checkpoints.write(
                        store.checkpoint_path(spec.algorithm, spec.index),
                        digest=digest,
                        agent=agent,
                        environment=environment,
                        returns=returns,
                        env_steps=env_steps,
                        greedy_trials=greedy_trials,
                        greedy_returns=greedy_returns,
                        wall_time_s=earlier_wall + now - start,
                        cpu_time_s=earlier_cpu + time.process_time() - cpu_start,
                    )
                last_checkpoint = time.perf_counter()
            if on_trial is not None:
                on_trial(spec.algorithm, spec.index, trial, float(value))
    demonstration = experiment.demonstration
    return ExperimentResult(
        algorithm=spec.algorithm,
        index=spec.index,
        returns=np.asarray(returns, dtype=float),
        env_steps=np.asarray(env_steps, dtype=np.int64),
        greedy_trials=np.asarray(greedy_trials, dtype=int),
        greedy_returns=np.asarray(greedy_returns, dtype=float),
        snapshots=snapshots,
        wall_time_s=earlier_wall + time.perf_counter() - start,
        cpu_time_s=earlier_cpu + time.process_time() - cpu_start,
        task_seed=experiment.task_seed,
        demonstration_returns=(
            demonstration.trial_returns() if demonstration is not None else np.zeros(0)
        ),
    )
