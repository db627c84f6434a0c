"""What a learner's config takes from the task for the fields left None.

The default input weightings of its LLR memories, the reward's action cost, and every default set
for the paper's pendulum carried to the task's own units (:func:`with_task_units`). The resolved
config is the one the learner keeps, so results record the values used.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.constraints import InvalidParameterError


def with_task_weights(
    owner: str,
    config: Any,
    state_space: StateSpace,
    action_space: ActionSpace,
    state_memories: tuple[str, ...],
    process_memories: tuple[str, ...] = ("process",),
) -> Any:
    """``config`` with the ``weights`` of every memory it names (an ``LLRConfig`` field) left None
    taken from the task's hints: the StateSpace's ``input_weights`` for a memory over x, those then
    the ActionSpace's for one over [x, u]; every weighting checked against n or n + m (ValueError
    naming ``owner``)."""
    n, m = state_space.dim, action_space.dim
    hints = {name: state_space.input_weights for name in state_memories}
    hints.update(
        {
            name: np.r_[state_space.input_weights, action_space.input_weights]
            for name in process_memories
        }
    )
    config = dataclasses.replace(
        config,
        **{
            name: dataclasses.replace(
                getattr(config, name), weights=tuple(float(w) for w in weights)
            )
            for name, weights in hints.items()
            if getattr(config, name).weights is None
        },
    )
    for name in hints:
        size = n + m if name in process_memories else n
        weights = getattr(config, name).weights
        if len(weights) != size:
            raise ValueError(
                f"{owner}: config.{name}.weights has {len(weights)} "
                f"entries, this task needs {size} "
                f"({'[x, u]' if name in process_memories else 'x'})"
            )
    return config


def with_task_action_cost(
    owner: str, config: Any, action_space: ActionSpace, used_by: str | None
) -> Any:
    """``config`` with its ``action_cost`` resolved against the task, as a tuple of m numbers: None
    takes the task's (``ActionSpace.cost``), a number P stands for P in every action dimension.
    ``used_by`` says what reads it; None when nothing does, and then a cost the task does not
    declare stays None (ValueError naming ``owner`` when it is needed)."""
    m, cost = action_space.dim, config.action_cost
    if cost is None:
        cost = action_space.cost
        if cost is None and used_by is not None:
            raise ValueError(
                f"{owner}: {used_by} uses the reward's action cost, "
                f"which this task does not declare (learner_state.action_cost); "
                f"set config.action_cost (0: the reward does not depend on u)"
            )
    elif np.ndim(cost) == 0:
        cost = (cost,) * m
    if cost is not None and len(cost) != m:
        raise ValueError(
            f"{owner}: config.action_cost has {len(cost)} entries, "
            f"this task has {m} action dimensions"
        )
    return dataclasses.replace(
        config, action_cost=None if cost is None else tuple(float(c) for c in cost)
    )


# --------------------------------------------------------------------------------------------------
# Settings in the task's own units.

#: The paper's pendulum, for which the learners' numeric defaults were set (section 6, Table 2): its
#: control step [s], its state and action dimensions, and its reward's scale, |r| hanging still at
#: the start (r = -Q_11 pi^2 with Q_11 = 5).
PAPER_TIMESTEP = 0.03
PAPER_STATE_DIM = 2
PAPER_ACTION_DIM = 1
PAPER_REWARD_SCALE = 5.0 * math.pi**2
#: The width of the paper's action range [V]: u in [-3, 3] (section 6).
PAPER_ACTION_RANGE = 6.0

#: How a default given at the paper's pendulum is carried to another task (a config's
#: ``task_units`` names one rule per field):
#:
#: * 'horizon': a per-step factor (gamma, lambda) keeping its horizon in seconds,
#:   value ** (dt / 0.03) for the task's control step dt;
#: * 'reward': a rate applied to a TD error, value * PAPER_REWARD_SCALE / the task's reward scale
#:   (left None when the task declares none: the learner then scales by a running estimate);
#: * 'reward_capped': as 'reward', but never above the value at the paper's pendulum: a task whose
#:   rewards are larger slows the rate, one whose rewards are smaller keeps the paper's. For a rate
#:   that is only safe as slow as its critic learns (S-AC's actor, whose critic learns once per real
#:   step from V = 0): raised in proportion on small rewards it outruns the critic (docs/new-task.md);
#: * 'states', 'transitions': a memory size or neighbour count, grown in proportion to the dimension
#:   of what the memory holds, n (2 on the pendulum) or n + m (3);
#: * 'action': an exploration std, the same fraction of the action range as on the paper's +-3 V
#:   (the mean width over action dimensions);
#: * 'steps': a number of control steps keeping its length in seconds (at least 1).
TASK_UNIT_RULES = ("horizon", "reward", "reward_capped", "states", "transitions", "action", "steps")


def memory_units(memory: str, rule: str, capacity: int, neighbours: int) -> dict:
    """A config's ``task_units`` of its LLR memory ``memory`` (an ``LLRConfig`` field): its size and
    K at the paper's pendulum, grown by ``rule`` ('states' for a memory over x, 'transitions' for
    one over [x, u])."""
    return {f"{memory}.capacity": (rule, capacity), f"{memory}.neighbours": (rule, neighbours)}


def step_ratio(state_space: StateSpace) -> float:
    """dt / 0.03 s for the task's control step dt (1 when the task does not say), to 9 decimals, so
    that a step computed as sub-steps times the physics step counts as its nominal value."""
    dt = getattr(state_space, "timestep", None)
    return 1.0 if dt is None else round(dt / PAPER_TIMESTEP, 9)


def reward_rate(paper_rate: float, reward_scale: float, rule: str = "reward") -> float:
    """A rate applied to TD errors, ``paper_rate`` at the paper's reward scale, at ``reward_scale``
    by ``rule`` ('reward': at most 1; 'reward_capped': at most ``paper_rate``); the paper's rate
    while the scale is unknown (0)."""
    if not reward_scale > 0:
        return paper_rate
    return min(
        paper_rate if rule == "reward_capped" else 1.0,
        paper_rate * (PAPER_REWARD_SCALE / reward_scale),
    )


def task_value(
    rule: str, paper_value: float, state_space: StateSpace, action_space: ActionSpace
) -> float | int | None:
    """``paper_value`` (a default at the paper's pendulum) carried to this task by ``rule`` (one of
    :data:`TASK_UNIT_RULES`); None for 'reward' and 'reward_capped' when the task declares no reward
    scale."""
    n, m = state_space.dim, action_space.dim
    if rule == "horizon":
        return float(paper_value ** step_ratio(state_space))
    if rule in ("reward", "reward_capped"):
        scale = getattr(state_space, "reward_scale", None)
        return None if scale is None else reward_rate(paper_value, scale, rule)
    if rule == "states":
        return int(round(paper_value * n / PAPER_STATE_DIM))
    if rule == "transitions":
        return int(round(paper_value * (n + m) / (PAPER_STATE_DIM + PAPER_ACTION_DIM)))
    if rule == "action":
        return float(
            paper_value * np.mean(action_space.high - action_space.low) / PAPER_ACTION_RANGE
        )
    if rule == "steps":
        return max(1, int(round(paper_value / step_ratio(state_space))))
    raise ValueError(f"unknown task-unit rule {rule!r}; one of {', '.join(TASK_UNIT_RULES)}")


def with_task_units(config: Any, state_space: StateSpace, action_space: ActionSpace) -> Any:
    """``config`` with every field its class lists in ``task_units`` (field -> (rule, value at the
    paper's pendulum); a dotted name, e.g. ``"critic.capacity"``, is a field of a nested config) and
    leaves None set from the task (:func:`task_value`), nested configs with task units of their own
    (exploration, planning) likewise. A field set explicitly is kept; on the paper's pendulum every
    resolved value is the paper's. A learner without a config (a scripted policy) has none."""
    if config is None:
        return None
    changes: dict[str, Any] = {}
    for field in dataclasses.fields(config):
        value = getattr(config, field.name)
        if dataclasses.is_dataclass(value) and hasattr(type(value), "task_units"):
            resolved = with_task_units(value, state_space, action_space)
            if resolved != value:
                changes[field.name] = resolved
    nested: dict[str, dict[str, Any]] = {}
    for name, (rule, paper_value) in getattr(type(config), "task_units", {}).items():
        owner, _, leaf = name.rpartition(".")
        holder = changes.get(owner, getattr(config, owner)) if owner else config
        if getattr(holder, leaf) is None:
            resolved = task_value(rule, paper_value, state_space, action_space)
            if resolved is None:
                continue
            if owner:
                nested.setdefault(owner, {})[leaf] = resolved
            else:
                changes[name] = resolved
    for owner, values in nested.items():
        memory = changes.get(owner, getattr(config, owner))
        try:
            changes[owner] = dataclasses.replace(memory, **values)
        except InvalidParameterError as error:  # named by its path in the learner's config
            message = str(error).removeprefix(type(memory).__name__)
            raise InvalidParameterError(f"{type(config).__name__}.{owner}{message}") from None
    return dataclasses.replace(config, **changes) if changes else config
