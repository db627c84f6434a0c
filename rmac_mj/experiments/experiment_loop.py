"""The learning loop of one experiment (:func:`run_experiment` of an :class:`ExperimentSpec`): its
trials, greedy evaluations and snapshots, the live trial log, and the checkpoint it continues from.
It writes nothing but the log and the checkpoint; the caller saves the result."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rmac_mj._physics_timers import untimed
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


@dataclasses.dataclass
class _Curve:
    """What an experiment has done so far: every trial's return and the environment steps taken by
    its end, the greedy evaluations, the snapshots, and the time of its earlier parts (a continued
    experiment's)."""

    returns: list[float] = dataclasses.field(default_factory=list)
    env_steps: list[int] = dataclasses.field(default_factory=list)
    greedy_trials: list[int] = dataclasses.field(default_factory=list)
    greedy_returns: list[float] = dataclasses.field(default_factory=list)
    snapshots: dict[int, dict[str, np.ndarray]] = dataclasses.field(default_factory=dict)
    earlier_wall: float = 0.0
    earlier_cpu: float = 0.0

    @classmethod
    def from_checkpoint(cls, saved: dict[str, Any]) -> _Curve:
        return cls(
            saved["returns"],
            saved["env_steps"],
            saved["greedy_trials"],
            saved["greedy_returns"],
            saved["snapshots"],
            saved["wall_time_s"],
            saved["cpu_time_s"],
        )

    def greedy_after(self, trial: int) -> float | None:
        """The greedy return evaluated after ``trial``, if one was."""
        if trial not in self.greedy_trials:
            return None
        return self.greedy_returns[self.greedy_trials.index(trial)]


def run_experiment(
    spec: ExperimentSpec, on_trial: Callable[[str, int, int, float, int], None] | None = None
) -> ExperimentResult:
    """Run one learning experiment; return its curve, greedy evaluations and snapshots.

    Nothing is written but the live trial log in ``spec.stream_to`` (if any), so it runs unchanged in
    a local worker process or on a remote Dask worker, and the caller decides where the results go.
    ``on_trial(algorithm, index, trial, return, env_steps)`` is called after every learning trial,
    ``env_steps`` the environment steps the experiment has taken so far. MuJoCo's profiling timers
    are off while it runs (:func:`rmac_mj._physics_timers.untimed`: the same numbers, cheaper steps).
    """
    with environment_failure_at(f"{spec.algorithm} experiment {spec.index}, building it"):
        experiment = build_experiment(spec.protocol, spec.algorithm, spec.index, spec.demonstration)
    with untimed():
        return _Learning(spec, experiment).run(on_trial)


class _Learning:
    """The loop of one experiment (:func:`run_experiment`): trials, greedy evaluations, snapshots,
    the live trial log and the checkpoint, continued from a kept checkpoint where there is one."""

    def __init__(self, spec: ExperimentSpec, experiment):
        protocol = self.protocol = spec.protocol
        self.spec, self.experiment = spec, experiment
        self.env, self.agent = experiment.env, experiment.agent
        self.name = f"{spec.algorithm} experiment {spec.index}"
        self.meta = {
            **protocol.environment_description(),
            "experiment": spec.index,
            "seed": protocol.seed,
        }
        self.evaluate = evaluation(protocol, spec.index)
        self.snapshot_trials = set(protocol.snapshot_trials) | {protocol.trials}
        self.store = ResultStore(spec.stream_to) if spec.stream_to is not None else None
        self.digest = checkpoints.protocol_digest(protocol.as_dict())
        self.curve = _Curve()
        saved = (
            _kept_checkpoint(self.store, spec, self.digest, self.agent, self.snapshot_trials)
            if self.store is not None
            else None
        )
        if saved is not None:  # continue where the checkpoint left off, exactly
            self.agent.load_state_dict(saved["agent"])
            checkpoints.restore_environment(self.env, saved["environment"])
            self.curve = _Curve.from_checkpoint(saved)

    def run(self, on_trial: Callable[[str, int, int, float, int], None] | None) -> ExperimentResult:
        spec, protocol, curve = self.spec, self.protocol, self.curve
        self.start, self.cpu_start = time.perf_counter(), time.process_time()
        last_checkpoint = self.start
        taken, trial = (curve.env_steps[-1] if curve.env_steps else 0), len(curve.returns)
        log_path = (
            self.store.progress_path(spec.algorithm, spec.index) if self.store is not None else None
        )
        with TrialLog(log_path) as log:
            for done, value in enumerate(curve.returns, start=1):  # a continued experiment's
                log.write(done, value, curve.greedy_after(done), curve.env_steps[done - 1])
            while trial < protocol.trials and (protocol.steps is None or taken < protocol.steps):
                trial += 1
                value, greedy, taken, last = self.trial(trial, taken)
                log.write(trial, value, greedy, taken)
                now = time.perf_counter()
                due = now - last_checkpoint >= spec.checkpoint_seconds
                if self.store is not None and not last and due:
                    self.checkpoint(now)
                    last_checkpoint = time.perf_counter()
                if on_trial is not None:
                    on_trial(spec.algorithm, spec.index, trial, float(value), int(taken))
        return self.result()

    def trial(self, trial: int, taken: int) -> tuple[float, float | None, int, bool]:
        """Learning trial ``trial``, then its greedy evaluation and snapshot where due: its return,
        the greedy return (None), the environment steps taken by its end, whether it is the last."""
        protocol, curve = self.protocol, self.curve
        with environment_failure_at(f"{self.name}, trial {trial}"):
            value, steps = run_counted_trial(self.env, self.agent, learn=True)
        taken += steps
        curve.returns.append(value)
        curve.env_steps.append(taken)
        greedy = None
        if protocol.evaluate_every and trial % protocol.evaluate_every == 0:
            with environment_failure_at(f"{self.name}, greedy evaluation after trial {trial}"):
                greedy = self.evaluate(self.env, self.agent)
            curve.greedy_trials.append(trial)
            curve.greedy_returns.append(greedy)
        last = trial == protocol.trials or (protocol.steps is not None and taken >= protocol.steps)
        if trial in self.snapshot_trials or last:
            curve.snapshots[trial] = snapshot_arrays(
                self.agent,
                self.experiment.state_space,
                self.experiment.action_space,
                trial=trial,
                **self.meta,
            )
        return value, greedy, taken, last

    def checkpoint(self, now: float) -> None:
        """Keep the experiment's checkpoint and the snapshots so far, to continue from (none where
        the environment's state cannot be saved)."""
        spec, curve = self.spec, self.curve
        environment = checkpoints.environment_state(self.env)
        if environment is None:
            return
        for done, arrays in curve.snapshots.items():  # written once; the curve's save rewrites
            self.store.write_snapshot_arrays(spec.algorithm, spec.index, done, arrays)
        checkpoints.write(
            self.store.checkpoint_path(spec.algorithm, spec.index),
            digest=self.digest,
            agent=self.agent,
            environment=environment,
            returns=curve.returns,
            env_steps=curve.env_steps,
            greedy_trials=curve.greedy_trials,
            greedy_returns=curve.greedy_returns,
            wall_time_s=curve.earlier_wall + now - self.start,
            cpu_time_s=curve.earlier_cpu + time.process_time() - self.cpu_start,
        )

    def result(self) -> ExperimentResult:
        curve, demonstration = self.curve, self.experiment.demonstration
        return ExperimentResult(
            algorithm=self.spec.algorithm,
            index=self.spec.index,
            returns=np.asarray(curve.returns, dtype=float),
            env_steps=np.asarray(curve.env_steps, dtype=np.int64),
            greedy_trials=np.asarray(curve.greedy_trials, dtype=int),
            greedy_returns=np.asarray(curve.greedy_returns, dtype=float),
            snapshots=curve.snapshots,
            wall_time_s=curve.earlier_wall + time.perf_counter() - self.start,
            cpu_time_s=curve.earlier_cpu + time.process_time() - self.cpu_start,
            task_seed=self.experiment.task_seed,
            demonstration_returns=(
                demonstration.trial_returns() if demonstration is not None else np.zeros(0)
            ),
        )
