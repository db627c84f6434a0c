"""Deep-RL baselines: Stable-Baselines3's SAC, TD3 and PPO behind the project's online interface.

Each learner holds an SB3 model and drives SB3's own policy, buffers and ``train()`` one control step
at a time, in the order of SB3's ``learn()`` loop, so that ``rmac-mj reproduce`` runs them like the
paper's learners (seeds, curves, greedy trials, snapshots, resume, ``--jobs``, Dask, ``--set``,
sweeps, ``render`` and ``policy``). ``tests/agents/test_sb3.py`` checks the claim: for the same seed and
environment, the parameters after a short run equal those of SB3's own ``model.learn()``.

What the learner sees and does (the same for the three):

* **Network input.** The learner state ``x`` with every periodic dimension as (cos, sin) and the others
  unscaled, in order: ``[cos phi, sin phi, phi_dot]`` on the pendulum, as Gymnasium's Pendulum-v1;
  SB3's default, no observation normalisation, is kept. The suite's Gymnasium environments
  (``rmac_mj.tasks.to_gymnasium``) observe exactly this vector.
* **Trial end is a truncation.** ``stop(r, x_K)`` stores the last transition as a time-out, as SB3
  does for a Gymnasium ``truncated`` episode: SAC and TD3 bootstrap from x_K (SB3's
  ``handle_timeout_termination``), PPO adds gamma V(x_K) to the last reward.
* **Randomness.** SB3 draws from the process-wide numpy and torch generators (and the action space's
  own one for SAC's and TD3's first random steps). Each learner seeds them through SB3 from its
  ``rng`` at construction, keeps their states as its own and swaps them in around every call into
  SB3, so learners in one process never share a stream and a state dict restores them exactly.
* **One torch thread** (``torch_threads``): the networks are small, so more threads only contend
  with the other workers, and a fixed count keeps floating-point reductions, hence results, fixed.

Hyperparameters are SB3's defaults (``SB3SACConfig``, ``SB3TD3Config``, ``SB3PPOConfig``) with one
exception, TD3's exploration noise (see its config). Learning rates are constant: SB3's schedules
need the run's total length, which a learner here does not know.

Needs the ``[baselines]`` extra (torch, stable-baselines3, sb3-contrib); the configs
(:mod:`rmac_mj.agents.sb3.config`) import without it, the learners raise an ImportError naming the
extra. This module holds their driver (:class:`SB3Agent`: an SB3 model behind the online interface,
its own random streams swapped in around every call into SB3, its state as flat arrays of torch
modules and optimisers); SAC, TD3 and sb3-contrib's CrossQ are in
:mod:`rmac_mj.agents.sb3.off_policy`, PPO in :mod:`rmac_mj.agents.sb3.ppo`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from typing import Any

import numpy as np

from rmac_mj.agents.base import Agent
from rmac_mj.agents.sb3.config import INSTALL_HINT, available
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.errors import MissingExtra


def network_input(x: np.ndarray, periodic: np.ndarray) -> np.ndarray:
    """The networks' view of a state ``x`` (shape (n,)): each periodic entry as (cos, sin), the others
    as they are, in order; float32 of shape (n + number of periodic entries,)."""
    parts = []
    for value, wraps in zip(x.tolist(), periodic.tolist()):
        parts.extend((math.cos(value), math.sin(value)) if wraps else (value,))
    return np.array(parts, dtype=np.float32)


def _arrays_of_module(prefix: str, module) -> dict[str, np.ndarray]:
    return {
        f"{prefix}{name}": tensor.detach().cpu().numpy().copy()
        for name, tensor in module.state_dict().items()
    }


def _load_module(prefix: str, module, state: dict[str, np.ndarray]) -> None:
    import torch

    module.load_state_dict(
        {name: torch.from_numpy(np.array(state[prefix + name])) for name in module.state_dict()}
    )


def arrays_of_optimizer(prefix: str, optimizer) -> dict[str, np.ndarray]:
    """Adam's moments and step count per parameter, as ``<prefix><index>.<name>``."""
    return {
        f"{prefix}{index}.{name}": value.detach().cpu().numpy().copy()
        for index, slots in optimizer.state_dict()["state"].items()
        for name, value in slots.items()
    }


def load_optimizer(prefix: str, optimizer, state: dict[str, np.ndarray]) -> None:
    import torch

    slots: dict[int, dict[str, Any]] = {}
    for key, value in state.items():
        if key.startswith(prefix):
            index, name = key[len(prefix) :].split(".", 1)
            slots.setdefault(int(index), {})[name] = torch.from_numpy(np.array(value))
    document = optimizer.state_dict()
    document["state"] = slots
    optimizer.load_state_dict(document)


def _spaces_only(observation_dim: int, action_space: ActionSpace):
    """What SB3 is given for an environment: a Gymnasium environment with the learner's spaces that
    cannot be stepped. The runner, not SB3, steps the task."""
    import gymnasium

    class SpacesOnly(gymnasium.Env):
        def __init__(self) -> None:
            self.observation_space = gymnasium.spaces.Box(
                -np.inf, np.inf, (observation_dim,), np.float32
            )
            self.action_space = gymnasium.spaces.Box(
                action_space.low.astype(np.float32),
                action_space.high.astype(np.float32),
                dtype=np.float32,
            )

        def reset(self, *, seed=None, options=None):
            raise RuntimeError("an rmac-mj learner is stepped by the runner, not by SB3")

        def step(self, action):
            raise RuntimeError("an rmac-mj learner is stepped by the runner, not by SB3")

    return SpacesOnly()


class SB3Agent(Agent):
    """An SB3 algorithm behind the online interface (see this module's docstring); subclasses
    say which.

    Learned state besides SB3's model: ``timesteps_`` (control steps learned from, SB3's
    ``num_timesteps``).
    """

    #: The SB3 class name, e.g. ``"SAC"``, and the package that holds it.
    sb3_class = ""
    sb3_package = "stable_baselines3"

    @classmethod
    def missing_requirement(cls) -> str | None:
        """The ``[baselines]`` extra, when torch, gymnasium or the SB3 package is not installed."""
        return None if available(cls.sb3_package) else f"{cls.name}: {INSTALL_HINT}"

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: Any = None,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        config = self.config_class() if config is None else config
        super().__init__(state_space, action_space, config, seed)
        problem = self.missing_requirement()
        if problem is not None:
            raise MissingExtra(problem)
        import importlib

        import torch
        from stable_baselines3.common.logger import Logger

        torch.set_num_threads(config.torch_threads)
        self._torch = torch
        self._periodic = state_space.periodic.copy()
        observation_dim = state_space.dim + int(self._periodic.sum())
        #: The seed SB3 is built with (drawn from ``rng``): SB3's ``learn()`` with this seed is what
        #: this learner reproduces.
        self.sb3_seed_ = int(self.rng.integers(2**31 - 1))
        outer = self._global_random_states()
        try:
            self.model = getattr(importlib.import_module(self.sb3_package), self.sb3_class)(
                "MlpPolicy",
                _spaces_only(observation_dim, action_space),
                seed=self.sb3_seed_,
                device="cpu",
                **self._sb3_kwargs(),
            )
            self._random_states = self._global_random_states()
        finally:
            self._set_global_random_states(outer)
        self.model.set_logger(Logger(folder=None, output_formats=[]))  # record, never write

    #: The config's fields that SB3 takes inside ``policy_kwargs`` (:meth:`_policy_kwargs`).
    policy_fields: tuple[str, ...] = ("net_arch",)

    def _sb3_kwargs(self) -> dict[str, Any]:
        """The SB3 constructor's arguments: every config field under its own name (the configs use
        SB3's names) but ``torch_threads`` and the :attr:`policy_fields`, which make
        ``policy_kwargs``."""
        c = self.config
        skip = ("torch_threads", *self.policy_fields)
        kwargs = {f.name: getattr(c, f.name) for f in dataclasses.fields(c) if f.name not in skip}
        return {**kwargs, "policy_kwargs": self._policy_kwargs()}

    def _policy_kwargs(self) -> dict[str, Any]:
        """SB3's ``policy_kwargs`` from the config's :attr:`policy_fields`."""
        return {"net_arch": list(self.config.net_arch)}

    # -- randomness: the learner's own streams, swapped in around every call into SB3 -------------------
    def _global_random_states(self) -> tuple[Any, Any]:
        return self._torch.get_rng_state(), np.random.get_state()

    def _set_global_random_states(self, states: tuple[Any, Any]) -> None:
        self._torch.set_rng_state(states[0])
        np.random.set_state(states[1])

    @contextlib.contextmanager
    def _own_randomness(self):
        outer = self._global_random_states()
        self._set_global_random_states(self._random_states)
        try:
            yield
        finally:
            self._random_states = self._global_random_states()
            self._set_global_random_states(outer)

    def _observation(self, x: np.ndarray) -> np.ndarray:
        """x as SB3's one-environment observation batch, shape (1, d)."""
        return network_input(x, self._periodic)[None, :]

    # -- one control step: act, then record its transition (and update when SB3's loop would) -------
    def _act(self) -> np.ndarray:
        """The action in the observation SB3 holds as its last (``_last_obs``)."""
        raise NotImplementedError

    def _record(self, reward: float, x: np.ndarray, last: bool, terminal: bool = False) -> None:
        """Store the step's transition to x (``last``: the trial ends, a time-out unless
        ``terminal``: x is a terminal state, not bootstrapped) and learn."""
        raise NotImplementedError

    def _start(self, x0: np.ndarray) -> np.ndarray:
        self.model._last_obs = self._observation(x0)
        self.model.policy.set_training_mode(False)
        return self._act()

    def _step(self, reward: float, x: np.ndarray) -> np.ndarray:
        self._record(reward, x, last=False)
        return self._act()

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        self._record(reward, x, last=True, terminal=terminal)

    @property
    def timesteps_(self) -> int:
        return int(self.model.num_timesteps)

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        action, _ = self.model.predict(self._observation(x), deterministic=True)
        return action[0].astype(float)

    # -- state: SB3's model as flat numeric arrays --------------------------------------------------------
    def _state(self) -> dict[str, np.ndarray]:
        torch_state, (_, keys, position, has_gauss, gauss) = self._random_states
        state = _arrays_of_module("policy.", self.model.policy)
        state.update(
            {
                "torch_rng": torch_state.numpy().copy(),
                "numpy_rng_keys": np.asarray(keys, dtype=np.uint32).copy(),
                "numpy_rng_position": np.array([position, has_gauss], dtype=np.int64),
                "numpy_rng_gauss": np.array(gauss, dtype=np.float64),
                "timesteps": np.array(self.model.num_timesteps, dtype=np.int64),
                "updates": np.array(self.model._n_updates, dtype=np.int64),
            }
        )
        if self._in_trial:
            state["last_observation"] = np.array(self.model._last_obs)
        return state

    def _may_lack(self, key: str) -> bool:
        """Entries SB3 holds only at some moments: in a trial, with a pending action, after an
        optimizer's first update."""
        return (
            super()._may_lack(key)
            or "optimizer." in key
            or key
            in (
                "last_observation",
                "buffer_action",
                "pending_action",
                "pending_value",
                "pending_log_prob",
            )
        )

    def _shape_varies(self, key: str) -> bool:
        return key.startswith(("replay.", "rollout."))  # buffers that fill

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        _load_module("policy.", self.model.policy, state)
        position, has_gauss = (int(v) for v in state["numpy_rng_position"])
        self._random_states = (
            self._torch.from_numpy(np.array(state["torch_rng"], dtype=np.uint8)),
            (
                "MT19937",
                np.array(state["numpy_rng_keys"], dtype=np.uint32),
                position,
                has_gauss,
                float(state["numpy_rng_gauss"]),
            ),
        )
        self.model.num_timesteps = int(state["timesteps"])
        self.model._n_updates = int(state["updates"])
        if "last_observation" in state:
            self.model._last_obs = np.array(state["last_observation"], dtype=np.float32)


def network_bytes(inputs: int, net_arch: tuple[int, ...], outputs: int) -> int:
    """float32 parameters of a fully connected network (weights and biases)."""
    sizes = [inputs, *net_arch, outputs]
    return 4 * sum((a + 1) * b for a, b in zip(sizes[:-1], sizes[1:]))
