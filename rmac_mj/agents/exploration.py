"""Exploration Delta u (section 6.1): when a learner explores and with what noise."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from numbers import Integral, Real
from typing import Any, ClassVar

import numpy as np

from rmac_mj.constraints import Field, Interval, Options, check_config, invalid


@dataclasses.dataclass(frozen=True)
class Exploration:
    """Exploration of section 6.1: every ``period``-th step, zero-mean Gaussian noise of std ``sigma``.

    The other steps are greedy (``Delta u = 0``). Step ``k`` of a trial is *scheduled* to explore when
    ``k % period == phase``; with the defaults, steps 0, 3, 6, ... explore, each with N(0, 1), in
    every trial: the paper's setting. Two extensions (not in the paper; docs/studies/):

    * **A decaying noise level** (``decay``): the std for learning trial t (t = 0, 1, ... counts the
      learning trials the agent has begun; greedy trials do not count) is

      - 'none': ``sigma`` in every trial (the paper);
      - 'exponential': ``max(sigma_min, sigma * decay_rate**t)``;
      - 'linear': from ``sigma`` at t = 0 down to ``sigma_min`` at t = ``decay_trials``, then
        ``sigma_min``.

    * **Exploring only where the process model is uncertain** (``where``, for the learners that learn
      one: RMAC and MLAC): with 'uncertain', a *scheduled* step explores only when the learner's
      model uncertainty at the step (:func:`model_uncertainty`: the mean weighted distance from the
      process model's query point to its K nearest samples, infinite while the memory holds fewer
      than K) is at least ``uncertainty_threshold``; the other scheduled steps are greedy. The
      schedule (``period``, ``phase``) still says *when* exploration may happen, the uncertainty
      *whether* it does. 'always' (the paper) explores on every scheduled step.

    Noise is drawn from the learner's generator only on steps that explore, so with the defaults the
    random stream is the one of the paper's schedule, draw for draw.

    Attributes:
      sigma: standard deviation of the exploration noise, in action units. None (the default): the
        paper's fraction of the action range, N(0, 1) on +-3 V, i.e. 1/6 of the range's width
        (``task_knowledge.with_task_units``; dc_pendulum: 1). With a decay, the std of the first
        trial.
      period: explore once every ``period`` steps. Paper: 3.
      phase: which step of each period explores.
      decay: 'none' (paper), 'exponential' or 'linear': how the std falls from trial to trial.
      sigma_min: the std a decay ends at, in [0, sigma]. Unused with decay='none'.
      decay_rate: the factor per trial of decay='exponential', in (0, 1). E.g. 0.99 halves the std
        every 69 trials.
      decay_trials: the trials decay='linear' takes to reach sigma_min, a positive integer.
      where: 'always' (paper) or 'uncertain'.
      uncertainty_threshold: for where='uncertain', the model uncertainty (in the process memory's
        weighted input-distance units; dc_pendulum with Table 2's weighting: 1-norm over
        (phi [rad], 0.1 omega [rad/s], u [V])) at or above which a scheduled step explores. Required
        (a finite number >= 0) with where='uncertain', unused otherwise.
    """

    sigma: float | None = None
    period: int = 3
    phase: int = 0
    decay: str = "none"
    sigma_min: float = 0.0
    decay_rate: float = 0.99
    decay_trials: int = 300
    where: str = "always"
    uncertainty_threshold: float | None = None

    parameter_constraints: ClassVar[dict[str, list]] = {
        "sigma": [Interval(Real, 0, None), None],
        "period": [Interval(Integral, 1, None)],
        "phase": [Interval(Integral, 0, Field("period"), closed="left")],
        "decay": [Options("none", "exponential", "linear")],
        "sigma_min": [Interval(Real, 0, Field("sigma"))],
        "decay_rate": [Interval(Real, 0, 1, closed="right")],
        "decay_trials": [Interval(Integral, 1, None)],
        "where": [Options("always", "uncertain")],
        "uncertainty_threshold": [Interval(Real, 0, None), None],
    }

    #: The fields set from the task when left None: field -> (rule, value at the paper's pendulum)
    #: (``task_knowledge.with_task_units``).
    task_units: ClassVar[dict[str, tuple[str, float]]] = {"sigma": ("action", 1.0)}

    def __post_init__(self) -> None:
        check_config(self)
        if self.decay == "exponential" and self.decay_rate == 1:
            raise invalid(
                "Exploration",
                "decay_rate",
                self.decay_rate,
                "below 1 with decay='exponential' (1 never decays; use decay='none')",
            )
        if self.where == "uncertain" and self.uncertainty_threshold is None:
            raise invalid(
                "Exploration",
                "uncertainty_threshold",
                None,
                "a finite number >= 0 with where='uncertain'",
            )

    @property
    def uses_trial(self) -> bool:
        """Whether the noise depends on the trial index (a decay)."""
        return self.decay != "none" and self.sigma is not None and self.sigma_min != self.sigma

    def sigma_at(self, trial: int) -> float:
        """The noise std of learning trial ``trial`` (0 for the first), see ``decay``; ``sigma``
        must be resolved against the task (``with_task_units``)."""
        if self.sigma is None:
            raise ValueError(
                "Exploration.sigma is None (the task's): resolve it with "
                "rmac_mj.agents.task_knowledge.with_task_units before sampling"
            )
        if self.decay == "none" or trial <= 0:
            return self.sigma
        if self.decay == "exponential":
            return max(self.sigma_min, self.sigma * self.decay_rate**trial)
        return (
            self.sigma
            + (self.sigma_min - self.sigma) * min(trial, self.decay_trials) / self.decay_trials
        )

    def scheduled(self, k: int) -> bool:
        """Whether step ``k`` of a trial is one on which exploration may happen (period, phase)."""
        return k % self.period == self.phase

    def sample(
        self,
        k: int,
        dim: int,
        rng: np.random.Generator,
        trial: int = 0,
        uncertainty: Callable[[], float] | None = None,
    ) -> np.ndarray:
        """Delta u_k, ndarray of shape (dim,): noise on exploring steps, zeros otherwise.

        Args:
          k: the step within the trial (0 for the action of ``start``).
          dim: m, the action dimension.
          rng: the learner's generator; drawn from only on a step that explores.
          trial: the learning trial's index (for a decay).
          uncertainty: for where='uncertain', a function returning the model uncertainty at this
            step; called only on scheduled steps.
        """
        if not self.scheduled(k):
            return np.zeros(dim)
        sigma = self.sigma_at(trial)
        if not sigma > 0:
            return np.zeros(dim)
        if self.where == "uncertain":
            if uncertainty is None:
                raise ValueError(
                    "Exploration.sample: where='uncertain' needs the learner's uncertainty"
                )
            if not uncertainty() >= self.uncertainty_threshold:
                return np.zeros(dim)
        return rng.normal(0.0, sigma, size=dim)


def model_uncertainty(memory: Any, query: np.ndarray) -> float:
    """How uncertain an LLR process model is at ``query`` (shape (n + m,), [x, u]).

    The mean weighted input distance (the memory's own norm and weighting) from ``query`` to its K
    nearest samples; ``inf`` while the memory holds fewer than K samples (the fit there is
    under-determined or rests on far samples). Small where the model has dense data, large where it
    would extrapolate. Used by ``Exploration(where='uncertain')``.
    """
    distances = memory.neighbour_distances(query)
    if len(distances) < memory.n_neighbours:
        return math.inf
    return float(distances.mean())
