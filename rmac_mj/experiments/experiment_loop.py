"""The learning loop of one experiment (:func:`run_experiment` of an :class:`ExperimentSpec`): its
trials, greedy evaluations and snapshots, the live trial log, and the checkpoint it continues from.
It writes nothing but the log and the checkpoint; the caller saves the result."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rmac_mj.agents import (
    Agent,
)
from rmac_mj.errors import environment_failure_at
from rmac_mj.experiments import checkpoint as checkpoints
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.experiments.experiment import build_experiment, evaluation
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.results import integrity
from rmac_mj.results.records import ExperimentResult, TrialLog
from rmac_mj.results.snapshots import snapshot_arrays, snapshot_state_problem
from rmac_mj.results.store import ResultStore
from rmac_mj.rollout import run_counted_trial


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
    spec: ExperimentSpec, on_trial: Callable[[str, int, int, float, int], None] | None = None
) -> ExperimentResult:
    """Run one learning experiment; return its curve, greedy evaluations and snapshots.

    Nothing is written but the live trial log in ``spec.stream_to`` (if any), so it runs unchanged in
    a local worker process or on a remote Dask worker, and the caller decides where the results go.
    ``on_trial(algorithm, index, trial, return, env_steps)`` is called after every learning trial,
    ``env_steps`` the environment steps the experiment has taken so far.
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
                on_trial(spec.algorithm, spec.index, trial, float(value), int(taken))
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
