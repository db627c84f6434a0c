"""S-AC (Algorithm 1) with Dyna planning, in the task's units: the learner recommended before MPC.

Every default is in the task's own units (:func:`rmac_mj.agents.task_knowledge.with_task_units`);
optionally it acts by a one-step lookahead in the learned model, u = argmax_u r(x, u) + gamma V(f(x,
u)), the critic as its terminal value (docs/new-task.md).
"""

from __future__ import annotations

import dataclasses
import itertools
from numbers import Integral
from typing import ClassVar

import numpy as np

from rmac_mj.agents.planning import Planning
from rmac_mj.agents.standard_ac import StandardACConfig, StandardActorCritic
from rmac_mj.constraints import Boolean, Interval


@dataclasses.dataclass(frozen=True)
class DynaACConfig(StandardACConfig):
    """S-AC's settings (:class:`StandardACConfig`) with planning on: ``planning.steps`` simulated
    transitions per real one, and an actor rate of 0.002 at the paper's reward scale (the smaller
    step planning wants on the pendulum, docs/planning.md), carried to the task's reward scale both
    ways: planning refreshes the critic 30 times per real step, so it keeps up with the faster actor
    on small rewards that S-AC's own rule refuses (docs/new-task.md).

    Attributes:
      lookahead: candidate actions per action dimension (evenly spaced over the bounds, both
        included; the actor's pi(x) is one more) of the one-step lookahead that chooses every action,
        real, simulated and greedy, once the planning model holds enough samples for a fit; the
        exploration noise is added to it. 0: the actor chooses (S-AC's line 8).
      lookahead_rollouts: whether the simulated rollouts act by the lookahead too (False: the actor
        chooses there, the lookahead only in real and greedy trials).
    """

    planning: Planning = Planning(steps=30)
    lookahead: int = 0
    lookahead_rollouts: bool = True

    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        **StandardACConfig.task_units,
        "alpha_a": ("reward", 0.002),
    }
    parameter_constraints: ClassVar[dict[str, list]] = {
        **StandardACConfig.parameter_constraints,
        "lookahead": [Interval(Integral, 0, None)],
        "lookahead_rollouts": [Boolean()],
    }


class DynaAC(StandardActorCritic):
    """S-AC with planning (:class:`DynaACConfig`); interface and state as
    :class:`StandardActorCritic`."""

    name = "s-ac-dyna"
    display_name = "S-AC + planning"
    config_class = DynaACConfig

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        c = self.config
        if c.lookahead and not c.planning.steps:
            raise ValueError(
                "s-ac-dyna: config.lookahead needs the planning model (planning.steps > 0)"
            )
        grids = (
            [
                np.linspace(lo, hi, c.lookahead)
                for lo, hi in zip(self.action_space.low, self.action_space.high)
            ]
            if c.lookahead
            else []
        )
        #: The lookahead's fixed candidates, shape (c, m).
        self.candidates = np.array(list(itertools.product(*grids)), dtype=float).reshape(
            -1, self.action_space.dim
        )
        self._rehearsing = False

    def _set_rehearsing(self, rehearsing: bool) -> None:
        super()._set_rehearsing(rehearsing)
        self._rehearsing = rehearsing

    def _looks_ahead(self) -> bool:
        model = self.rehearsal.model if self.rehearsal is not None else None
        if self._rehearsing and not self.config.lookahead_rollouts:
            return False
        return (
            self.config.lookahead > 0
            and model is not None
            and model.memory.n_samples_ >= model.memory.n_neighbours
        )

    def _best(self, x: np.ndarray) -> np.ndarray:
        """argmax over the candidates and pi(x) of r(x, u) + gamma V(f(x, u)) in the learned model."""
        model, gamma = self.rehearsal.model, self.config.gamma
        x = self.state_space.canonical(x)
        best, best_score = None, -np.inf
        for u in itertools.chain(self.candidates, [self._policy(self.coder.active_tiles(x))]):
            x_next, r = model.predict(x, u)
            score = r + gamma * self._value(x_next)
            if score > best_score:
                best, best_score = u, score
        return np.array(best, dtype=float)

    def _explore(self, x: np.ndarray, k: int) -> np.ndarray:
        noise = self.config.exploration.sample(k, self.action_space.dim, self.rng, self.trial)
        return self.action_space.clip(self._best(x) + noise)

    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        if u is None and self._looks_ahead():
            u = self._explore(x0, 0)
        return super()._start(x0, u)

    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        if u is None and self._looks_ahead():
            u = self._explore(x, self._k + 1)
        return super()._step(reward, x, u)

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        return self._best(x) if self._looks_ahead() else super()._greedy_action(x)
