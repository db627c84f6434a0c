"""What a learner's config takes from the task: the default input weightings of its LLR memories
and the reward's action cost, for the fields left None (the task's hints, carried by the spaces).
The resolved config is the one the learner keeps, so results record the values actually used."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from rmac_mj.agents.spaces import ActionSpace, StateSpace


def with_task_weights(owner: str, config: Any, state_space: StateSpace, action_space: ActionSpace,
                      state_memories: tuple[str, ...],
                      process_memories: tuple[str, ...] = ("process",)) -> Any:
    """``config`` with every ``<memory>_weights`` left None taken from the task's hints: the
    StateSpace's ``input_weights`` for a memory over x, those then the ActionSpace's for one over
    [x, u]; every weighting checked against n or n + m (ValueError naming ``owner``)."""
    n, m = state_space.dim, action_space.dim
    hints = {name: state_space.input_weights for name in state_memories}
    hints.update({name: np.r_[state_space.input_weights, action_space.input_weights]
                  for name in process_memories})
    config = dataclasses.replace(config, **{
        f"{name}_weights": tuple(float(w) for w in weights)
        for name, weights in hints.items() if getattr(config, f"{name}_weights") is None})
    for name in hints:
        size = n + m if name in process_memories else n
        weights = getattr(config, f"{name}_weights")
        if len(weights) != size:
            raise ValueError(f"{owner}: config.{name}_weights has {len(weights)} "
                             f"entries, this task needs {size} "
                             f"({'[x, u]' if name in process_memories else 'x'})")
    return config


def with_task_action_cost(owner: str, config: Any, action_space: ActionSpace,
                          used_by: str | None) -> Any:
    """``config`` with its ``action_cost`` resolved against the task, as a tuple of m numbers: None
    takes the task's (``ActionSpace.cost``), a number P stands for P in every action dimension.
    ``used_by`` says what reads it; None when nothing does, and then a cost the task does not
    declare stays None (ValueError naming ``owner`` when it is needed)."""
    m, cost = action_space.dim, config.action_cost
    if cost is None:
        cost = action_space.cost
        if cost is None and used_by is not None:
            raise ValueError(f"{owner}: {used_by} uses the reward's action cost, "
                             f"which this task does not declare (learner_state.action_cost); "
                             f"set config.action_cost (0: the reward does not depend on u)")
    elif np.ndim(cost) == 0:
        cost = (cost,) * m
    if cost is not None and len(cost) != m:
        raise ValueError(f"{owner}: config.action_cost has {len(cost)} entries, "
                         f"this task has {m} action dimensions")
    return dataclasses.replace(
        config, action_cost=None if cost is None else tuple(float(c) for c in cost))
