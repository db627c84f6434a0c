"""Model-predictive action choice by sampling action sequences in a learned model.

Each control step, :class:`Planner` draws a population of action sequences over a horizon (in
seconds), rolls each out in the learned model, scores it by its predicted rewards plus the
discounted critic value where it ends, and moves its sampling distribution towards the best
(MPPI, Williams et al. 2017, with the elites of CEM as TD-MPC does, Hansen et al. 2022); after a few
iterations the first action of the mean is applied. The distribution is warm-started from the last
step's, shifted by one step; the actor's own closed-loop rollout is one of the population. A
rollout stops trusting the model where its query lies far from data and takes the critic's value
there (the model's uncertainty, :mod:`rmac_mj.approximators.local_fits`).
"""

from __future__ import annotations

import dataclasses
from numbers import Integral, Real
from typing import Any, ClassVar

import numpy as np

from rmac_mj.agents import _planner_kernels as _k
from rmac_mj.agents.spaces import ActionSpace
from rmac_mj.approximators.llr_numpy import wrap
from rmac_mj.approximators.local_fits import LocalFits
from rmac_mj.constraints import Field, Interval, Options, check_config

#: The visit counts passed to the scoring kernel without optimism (never read).
_NO_VISITS = np.zeros(0)


@dataclasses.dataclass(frozen=True)
class SamplingPlanner:
    """Settings of the sampling planner.

    Attributes:
      horizon: seconds of task time a sequence spans (rounded to control steps, at least one).
      population: sequences scored per iteration.
      iterations: rounds of sampling and refitting per control step.
      elites: the best sequences the distribution is refitted to.
      temperature: MPPI's, relative to the elites' spread of scores (small: the best dominates).
      method: 'mppi' (elites weighted by exp(score / temperature)) or 'cem' (elites alike).
      policy_rollouts: sequences that follow the actor pi(x_t) closed-loop in the model.
      init_std: the sampling std at each step's start, as a fraction of half the action range.
      min_std: the std's floor, as a fraction of half the action range.
      trust: a rollout stops at the first step whose query lies more than ``trust`` neighbourhood
        radii from the model's data and takes the critic's value there; 0: rollouts always run to
        the horizon.
      optimism: a reward bonus per unit of that ratio (capped at ``trust``), as a fraction of the
        reward's scale per step, in learning trials only: sequences into the unknown are tried.
      act: the action applied: the refined distribution's 'mean' first step, or the first step of
        the 'best' sequence scored in any iteration.
      search: how a rollout finds the sample whose local model answers each query: a k-d 'tree' or
        a 'scan' of the memory (the same sample; the scan is the slow reference).
    """

    horizon: float = 0.5
    population: int = 32
    iterations: int = 3
    elites: int = 6
    temperature: float = 0.5
    method: str = "mppi"
    policy_rollouts: int = 1
    init_std: float = 0.5
    min_std: float = 0.05
    trust: float = 3.0
    optimism: float = 0.0
    act: str = "mean"
    search: str = "tree"

    parameter_constraints: ClassVar[dict[str, list]] = {
        "horizon": [Interval(Real, 0, None, closed="neither")],
        "population": [Interval(Integral, 2, 100_000)],
        "iterations": [Interval(Integral, 1, 1000)],
        "elites": [Interval(Integral, 1, Field("population"))],
        "temperature": [Interval(Real, 0, None, closed="neither")],
        "method": [Options("mppi", "cem")],
        "policy_rollouts": [Interval(Integral, 0, Field("population"))],
        "init_std": [Interval(Real, 0, None, closed="neither")],
        "min_std": [Interval(Real, 0, None)],
        "trust": [Interval(Real, 0, None)],
        "optimism": [Interval(Real, 0, None)],
        "act": [Options("mean", "best")],
        "search": [Options("tree", "scan")],
    }

    def __post_init__(self) -> None:
        check_config(self)

    def steps(self, timestep: float) -> int:
        """The horizon in control steps of ``timestep`` seconds."""
        return max(1, int(round(self.horizon / timestep)))


class Planner:
    """The sampling planner at work: its distribution, warm-started from step to step.

    Args:
      settings: the :class:`SamplingPlanner`.
      action_space: the bounds sequences are sampled within.
      timestep: the task's control step [s].

    State: ``mean_`` (H, m), the last plan (None before a trial's first).
    """

    def __init__(self, settings: SamplingPlanner, action_space: ActionSpace, timestep: float):
        self.settings = settings
        self.H = settings.steps(timestep)
        self.low, self.high = action_space.low, action_space.high
        half = 0.5 * (action_space.high - action_space.low)
        self.init_std = settings.init_std * half
        self.min_std = settings.min_std * half
        self.mean_: np.ndarray | None = None
        self.scores_ = np.empty(settings.population)

    def reset(self) -> None:
        """A new trial: no warm start."""
        self.mean_ = None

    def sample(self, noise: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
        """Sequences (P, H, m) = clip(mean + std * noise) inside the action bounds."""
        return np.clip(mean + std * noise, self.low, self.high)

    def _warm_start(self, initial: np.ndarray | None) -> np.ndarray:
        """The mean this step refines: the last plan shifted by one step, or at a trial's first
        step ``initial`` (default: the middle of the bounds) at every step of the horizon."""
        if self.mean_ is None:
            self.mean_ = np.empty((self.H, self.low.shape[0]))
            self.mean_[:] = 0.5 * (self.low + self.high) if initial is None else initial
        else:
            self.mean_[:-1] = self.mean_[1:]
        return self.mean_

    def plan(
        self,
        x: np.ndarray,
        fits: LocalFits,
        box: tuple[np.ndarray, np.ndarray, np.ndarray],
        critic: np.ndarray,
        actor: np.ndarray,
        coder: tuple[np.ndarray, ...],
        gamma: float,
        rng: np.random.Generator,
        bonus: float = 0.0,
        initial: np.ndarray | None = None,
        potential: float = 0.0,
        visits: np.ndarray | None = None,
    ) -> np.ndarray:
        """The action (m,) for the canonical state x: the first step of the refined mean.

        ``fits``: the model's cached fits (refreshed here); ``box``: (low, high, period) of the
        state; ``critic``, ``actor``, ``coder``: the tile-coded V and pi and their coder's arrays;
        ``rng``: the draws; ``bonus``: the optimism per unit of uncertainty (0: none);
        ``initial``: the mean's first plan of a trial (default: the middle of the bounds);
        ``potential``, ``visits``: the optimism added to the terminal value, ``potential`` x the
        mean over the tilings of 1 / sqrt(1 + visits[tile]) (0: none).
        """
        s = self.settings
        m = self.low.shape[0]
        mean, std = self._warm_start(initial), np.broadcast_to(self.init_std, (self.H, m)).copy()
        fits.refresh()
        arrays = fits.kernel_arrays
        memory = fits.memory.kernel_state
        method = _k.CEM if s.method == "cem" else _k.MPPI
        best_score, best = -np.inf, None
        for _ in range(s.iterations):
            noise = rng.standard_normal((s.population, self.H, m))
            sequences = self.sample(noise, mean, std)
            _k.score_population(
                memory,
                arrays,
                box,
                critic,
                actor,
                coder,
                (self.low, self.high),
                x,
                sequences,
                s.policy_rollouts,
                gamma,
                s.trust,
                bonus,
                potential,
                _NO_VISITS if visits is None else visits,
                fits.tree if s.search == "tree" else (),
                self.scores_,
            )
            top = _k.update_distribution(
                sequences, self.scores_, s.elites, s.temperature, method, self.min_std, mean, std
            )
            if self.scores_[top] > best_score:
                best_score, best = self.scores_[top], sequences[top, 0].copy()
        return best if s.act == "best" else mean[0].copy()


def score_population_numpy(
    x0: np.ndarray,
    sequences: np.ndarray,
    fits: LocalFits,
    box: tuple[np.ndarray, np.ndarray, np.ndarray],
    value: Any,
    policy: Any,
    policy_rows: int,
    gamma: float,
    trust: float,
    bonus: float,
) -> np.ndarray:
    """The readable reference of ``_planner_kernels.score_population`` with an exact search: each
    sequence rolled out one query at a time through ``fits.query``; ``value(x)`` and ``policy(x)``
    are the critic and the saturated actor. Returns the scores (P,)."""
    low, high, period = box
    n = x0.shape[0]
    scores = np.empty(sequences.shape[0])
    for p, sequence in enumerate(sequences):
        x, total, discount = x0.copy(), 0.0, 1.0
        for t, u in enumerate(sequence):
            if p < policy_rows:
                u[:] = policy(x)
            out, ratio, _ = fits.query(np.r_[x, u])
            if trust > 0 and ratio > trust and t > 0:
                break
            reward = out[n] + (bonus * min(ratio, trust) if bonus > 0 else 0.0)
            total += discount * reward
            discount *= gamma
            x = np.where(period > 0, wrap(out[:n], period), np.clip(out[:n], low, high))
        scores[p] = total + discount * value(x)
    return scores
