"""The learners behind one interface: RMAC (Algorithm 2), S-AC (Algorithm 1), MLAC, the learner
recommended for a new task (MPC in the learned models), S-AC with Dyna planning and the
Stable-Baselines3 baselines.

``make_agent(name, state_space, action_space, config, seed)`` builds one by its key (:data:`ALGORITHMS`);
every learner is an :class:`Agent` (``start``/``step``/``stop``, ``greedy_action``, ``state_dict``) on a
:class:`StateSpace` and an :class:`ActionSpace`, configured by a frozen dataclass of the paper's values
(``RMACConfig``, ``StandardACConfig``, ``MLACConfig``, ...; each LLR memory's by :class:`LLRConfig`),
exploring by :class:`Exploration`, planning or replaying by :class:`Planning` or :class:`Replay`,
seeded from prior knowledge by :func:`seed_memory`. Each learner is a module holding its config dataclass and its :class:`Agent`
subclass; the registry ``_REGISTRY`` (key -> module, agent class, config class) builds them by name,
and adding a learner is one line there.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

import numpy as np

from rmac_mj import constraints
from rmac_mj.agents.base import Agent, RefusedTransition
from rmac_mj.agents.exploration import Exploration, model_uncertainty
from rmac_mj.agents.planning import Planning, Replay
from rmac_mj.agents.scripted import PolicyAgent
from rmac_mj.agents.seeding import PRIOR_PARTS, check_transitions, discounted_returns, seed_memory
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.approximators.llr import LLRConfig

#: Algorithm key -> (module, agent class, config class). Imported lazily: numba kernels compile on use.
_REGISTRY = {
    "rmac": ("rmac_mj.agents.rmac", "RMAC", "RMACConfig"),
    "s-ac": ("rmac_mj.agents.standard_ac", "StandardActorCritic", "StandardACConfig"),
    "mlac": ("rmac_mj.agents.mlac", "MLAC", "MLACConfig"),
    # The learner to pick for a new task: MPC, acting by planning in its learned models with S-AC's
    # critic at the horizon (mpc.py).
    "recommended": ("rmac_mj.agents.mpc", "MPC", "MPCConfig"),
    # S-AC with Dyna planning in the task's units, the learner recommended before MPC (dyna.py).
    "s-ac-dyna": ("rmac_mj.agents.dyna", "DynaAC", "DynaACConfig"),
    # Deep-RL baselines (Stable-Baselines3; the [baselines] extra): the room rmac_mj.agents.sb3.
    "sb3-sac": ("rmac_mj.agents.sb3.off_policy", "SB3SAC", "SB3SACConfig"),
    "sb3-td3": ("rmac_mj.agents.sb3.off_policy", "SB3TD3", "SB3TD3Config"),
    "sb3-ppo": ("rmac_mj.agents.sb3.ppo", "SB3PPO", "SB3PPOConfig"),
    "sb3-crossq": ("rmac_mj.agents.sb3.off_policy", "SB3CrossQ", "SB3CrossQConfig"),
}

#: The algorithm keys, as used on the command line and in results.
ALGORITHMS = tuple(_REGISTRY)

#: Names users may type for a learner that has another key ("sac": in RL, Soft Actor-Critic).
_DID_YOU_MEAN = {
    "sac": "s-ac (the paper's standard actor-critic) or sb3-sac (Soft Actor-Critic)",
    "sb3": "sb3-sac, sb3-td3, sb3-ppo or sb3-crossq",
    "crossq": "sb3-crossq",
    "standard-ac": "s-ac",
    "mpc": "recommended (model-predictive control in the learned models)",
    "dyna": "s-ac-dyna",
}


def unknown_algorithm(name: str, what: str = "unknown algorithm") -> ValueError:
    """The error for an algorithm key that is not one of :data:`ALGORITHMS`, with a "did you mean"."""
    hint = _DID_YOU_MEAN.get(str(name).lower())
    mean = f"; did you mean {hint}?" if hint else ""
    return ValueError(f"{what} {name!r}{mean} (available: {', '.join(ALGORITHMS)})")


def _lookup(name: str):
    if name not in _REGISTRY:
        raise unknown_algorithm(name)
    module_name, agent_name, config_name = _REGISTRY[name]
    module = importlib.import_module(module_name)
    return getattr(module, agent_name), getattr(module, config_name)


def display_name(name: str) -> str:
    """The name of algorithm ``name`` in figures, tables and videos (the agent's ``display_name``);
    a key this version does not know (e.g. from an old result) is shown as it is."""
    return _lookup(name)[0].display_name if name in _REGISTRY else name


def config_class(name: str) -> type:
    """The hyperparameter dataclass of algorithm ``name``."""
    return _lookup(name)[1]


def agent_class(name: str) -> type:
    """The learner class of algorithm ``name`` (e.g. to read its ``prior_parts``)."""
    return _lookup(name)[0]


def config_from_dict(cls: type, values: dict[str, Any], base: Any = None):
    """Rebuild a (possibly nested) frozen config dataclass from ``dataclasses.asdict`` output (or
    any dict of some of its parameters, e.g. a TOML table); the config checks the values against its
    ``parameter_constraints`` (:mod:`rmac_mj.constraints`), and an unknown name is refused with the
    closest known one. A parameter not given keeps its value in ``base`` (default: ``cls()``), a
    nested config's too: ``{"planning": {"model_capacity": 500}}`` changes one setting of the
    learner's own planning defaults, not of ``Planning()``'s."""
    table = cls.parameter_constraints
    for name in values:
        if name not in table:
            raise constraints.unknown(cls.__name__, name, table)
    kwargs = {}
    for name, value in values.items():
        nested = constraints.nested_class(table[name])
        if nested is not None and isinstance(value, dict):
            try:
                value = config_from_dict(nested, value, getattr(base or _defaults(cls), name))
            except constraints.InvalidParameterError as error:  # named by its path from here
                message = str(error)
                if message.startswith(nested.__name__):
                    message = f"{cls.__name__}.{name}{message[len(nested.__name__) :]}"
                raise constraints.InvalidParameterError(message) from None
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[name] = value
    return dataclasses.replace(base, **kwargs) if base is not None else cls(**kwargs)


def _defaults(cls: type) -> Any:
    """``cls()``, the config of every default (built once per class)."""
    if cls not in _DEFAULTS:
        _DEFAULTS[cls] = cls()
    return _DEFAULTS[cls]


_DEFAULTS: dict[type, Any] = {}


def memory_estimate(
    name: str, state_space: StateSpace, action_space: ActionSpace, config: Any = None
) -> int:
    """Bytes of RAM the learner ``name`` needs with ``config`` on these spaces, computed without
    building it (:meth:`Agent.memory_estimate`)."""
    return _lookup(name)[0].memory_estimate(config, state_space, action_space)


def make_agent(
    name: str,
    state_space: StateSpace,
    action_space: ActionSpace,
    config: Any = None,
    seed: int | np.random.Generator | None = None,
) -> Agent:
    """Build the learner ``name`` (one of :data:`ALGORITHMS`: ``"rmac"``, ``"s-ac"``, ``"mlac"``).

    ``config`` is its config dataclass, a dict of overrides of the paper's defaults, or None.
    """
    agent_cls, config_cls = _lookup(name)
    if config is None:
        config = config_cls()
    elif isinstance(config, dict):
        config = config_from_dict(config_cls, config)
    elif not isinstance(config, config_cls):
        raise TypeError(
            f"config for {name!r} must be a {config_cls.__name__} or dict, "
            f"got {type(config).__name__}"
        )
    return agent_cls(state_space, action_space, config=config, seed=seed)


#: The learners and their configs by class name (``RMAC``, ``RMACConfig``, ``SB3SAC``, ...) -> the module
#: that holds them. They are read from it on first use (PEP 562 ``__getattr__``), as ``make_agent``
#: reads the registry: ``import rmac_mj.agents`` stays the interface and imports no learner module,
#: so a learner's own imports (the baselines' torch and Stable-Baselines3, a learner's compiled
#: kernels) are paid for by whoever uses that learner.
_LEARNERS = {
    class_name: module_name
    for module_name, agent_name, config_name in _REGISTRY.values()
    for class_name in (agent_name, config_name)
}
_LEARNERS["SamplingPlanner"] = "rmac_mj.agents.sampling_planner"


def __getattr__(name: str) -> Any:
    if name in _LEARNERS:
        value = getattr(importlib.import_module(_LEARNERS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LEARNERS))


__all__ = [
    # Building a learner by its key
    "ALGORITHMS",
    "agent_class",
    "config_class",
    "config_from_dict",
    "display_name",
    "make_agent",
    "memory_estimate",
    "unknown_algorithm",
    # The interface every learner shares
    "ActionSpace",
    "Agent",
    "PolicyAgent",
    "RefusedTransition",
    "StateSpace",
    # The learners and their configs (RMAC, RMACConfig, ...; read from their modules on first use)
    *_LEARNERS,
    # A memory's settings, exploration, planning and replay, prior knowledge
    "Exploration",
    "LLRConfig",
    "PRIOR_PARTS",
    "Planning",
    "Replay",
    "check_transitions",
    "discounted_returns",
    "model_uncertainty",
    "seed_memory",
]
