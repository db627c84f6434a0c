"""A scripted agent: a fixed policy behind the learners' checked interface."""

from __future__ import annotations

from typing import Any

import numpy as np

from rmac_mj.agents.base import Agent
from rmac_mj.agents.spaces import ActionSpace, StateSpace


class PolicyAgent(Agent):
    """An agent that acts with a fixed policy ``u = policy(x)`` and learns nothing.

    For scripted controllers (a demonstrator, a constant action in a benchmark) wherever the
    experiments take an :class:`Agent`: every call still goes through the checked boundary. The value
    is 0 everywhere; the state is empty apart from the generator.
    """

    name = display_name = "policy"
    config_class = type(None)

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        policy: Any,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        if not callable(policy):
            raise TypeError(f"policy must be a function x -> u, got {type(policy).__name__}")
        super().__init__(state_space, action_space, config=None, seed=seed)
        self.policy_function = policy

    @classmethod
    def _memory_parts(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        return 0, 0

    def _act(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.policy_function(x), dtype=float).reshape(self.action_space.dim)

    def _start(self, x0: np.ndarray) -> np.ndarray:
        return self._act(x0)

    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        return self._act(x)

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        pass

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        return self._act(x)

    def _value(self, x: np.ndarray) -> float:
        return 0.0

    def _state(self) -> dict[str, np.ndarray]:
        return {}

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        pass

    def config_dict(self) -> dict[str, Any]:
        return {}
