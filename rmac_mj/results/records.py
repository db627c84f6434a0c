"""The records of a run's results: what one experiment produced (:class:`ExperimentResult`, before
it is saved), one learner's curves over the experiments (:class:`Curves`, as read back), and the
live log of a running experiment (:class:`TrialLog`)."""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np


@dataclasses.dataclass(frozen=True)
class ExperimentResult:
    """What one learning experiment produced (before it is saved).

    Attributes:
      algorithm, index: which experiment.
      returns: ndarray of shape (trials,): the sum of rewards of every learning trial.
      env_steps: int ndarray of shape (trials,): the environment steps taken by the end of every
        learning trial, counted from the experiment's start (greedy trials not counted).
      greedy_trials: ndarray of shape (evaluations,): after which learning trials a greedy trial ran.
      greedy_returns: ndarray of shape (evaluations,): their returns.
      snapshots: trial -> the snapshot arrays of the agent after it (``snapshots.snapshot_arrays``).
      wall_time_s: the experiment's wall time (s).
      cpu_time_s: the CPU time of the process that ran it, over the experiment (s): its cost on a
        loaded machine, where the wall time is not.
      task_seed: the seed of its task's random state.
      demonstration_returns: ndarray of shape (prior trials,): the returns of the demonstration it
        was seeded with (empty without one).
    """

    algorithm: str
    index: int
    returns: np.ndarray
    greedy_trials: np.ndarray
    greedy_returns: np.ndarray
    snapshots: dict[int, dict[str, np.ndarray]]
    wall_time_s: float
    cpu_time_s: float
    task_seed: int
    demonstration_returns: np.ndarray
    env_steps: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Curves:
    """One learner's curves over the experiments of a run.

    Attributes:
      returns: ndarray of shape (experiments, trials): sum of rewards per learning trial; NaN after
        the last trial of an experiment that ran fewer (a budget in environment steps).
      env_steps: ndarray of shape (experiments, trials): environment steps taken by the end of each
        trial (float; NaN where ``returns`` is, and for curves written before they were recorded).
      greedy_returns: ndarray of shape (experiments, evaluations): greedy trials' returns.
      greedy_trials: ndarray of shape (evaluations,): after which learning trials they ran.
      wall_times: ndarray of shape (experiments,): each experiment's wall time (s).
      cpu_times: ndarray of shape (experiments,): each experiment's CPU time (s); NaN for results
        written before it was recorded.
      demonstration_returns: ndarray of shape (experiments, prior trials): the demonstrations the
        experiments were seeded with (zero columns without prior knowledge).
    """

    returns: np.ndarray
    greedy_returns: np.ndarray
    greedy_trials: np.ndarray
    wall_times: np.ndarray
    cpu_times: np.ndarray
    demonstration_returns: np.ndarray
    env_steps: np.ndarray | None = None

    @property
    def trials_run(self) -> np.ndarray:
        """int ndarray of shape (experiments,): the learning trials each experiment ran."""
        return np.sum(np.isfinite(self.returns), axis=1).astype(int)


class TrialLog:
    """The live log of one experiment: a CSV (``trial,return,greedy_return,env_steps``; the last: the
    environment steps taken so far) flushed after every trial,
    so ``tail -f`` or pandas can follow a run. Not atomic and rewritten when a resumed run repeats the
    experiment: it is a view of a run in progress, not a result."""

    HEADER = "trial,return,greedy_return,env_steps\n"

    def __init__(self, path: pathlib.Path | None):
        self.path, self.handle = path, None

    def __enter__(self) -> TrialLog:
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.handle = open(self.path, "w", encoding="utf-8")
            self.handle.write(self.HEADER)
            self.handle.flush()
        return self

    def write(
        self, trial: int, value: float, greedy: float | None, env_steps: int | None = None
    ) -> None:
        if self.handle is not None:
            text = "" if greedy is None else repr(float(greedy))
            steps = "" if env_steps is None else str(int(env_steps))
            self.handle.write(f"{trial},{float(value)!r},{text},{steps}\n")
            self.handle.flush()

    def __exit__(self, *exc) -> None:
        if self.handle is not None:
            self.handle.close()
