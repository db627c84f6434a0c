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

Needs the ``[baselines]`` extra (torch, stable-baselines3); the configs (:mod:`rmac_mj.agents.sb3_config`)
import without it, the learners raise an ImportError naming the extra. The module runs past 400
lines because the three learners share one driver of SB3 (:class:`SB3Agent`: state dicts of torch
modules and optimisers, the swapped random streams), each a short subclass read against SB3's own
``learn()`` loop.
"""

from __future__ import annotations

import contextlib
import math
from typing import Any

import numpy as np

from rmac_mj.agents.base import Agent
from rmac_mj.agents.random_state import generator_state_array, set_generator_state
from rmac_mj.agents.sb3_config import (
    INSTALL_HINT,
    SB3PPOConfig,
    SB3SACConfig,
    SB3TD3Config,
    available,
)
from rmac_mj.agents.spaces import ActionSpace, StateSpace

# ----------------------------------------------------------------------------------------------------
# The learners.


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


def _arrays_of_optimizer(prefix: str, optimizer) -> dict[str, np.ndarray]:
    """Adam's moments and step count per parameter, as ``<prefix><index>.<name>``."""
    return {
        f"{prefix}{index}.{name}": value.detach().cpu().numpy().copy()
        for index, slots in optimizer.state_dict()["state"].items()
        for name, value in slots.items()
    }


def _load_optimizer(prefix: str, optimizer, state: dict[str, np.ndarray]) -> None:
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
    """An SB3 algorithm behind the online interface (see the module docstring); subclasses say which.

    Learned state besides SB3's model: ``timesteps_`` (control steps learned from, SB3's
    ``num_timesteps``).
    """

    #: The stable_baselines3 class name, e.g. ``"SAC"``.
    sb3_class = ""

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: Any = None,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        config = self.config_class() if config is None else config
        super().__init__(state_space, action_space, config, seed)
        if not available():
            raise ImportError(f"{self.name}: {INSTALL_HINT}")
        import stable_baselines3
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
            self.model = getattr(stable_baselines3, self.sb3_class)(
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

    def _sb3_kwargs(self) -> dict[str, Any]:
        """The SB3 constructor's arguments from the config."""
        raise NotImplementedError

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


def _network_bytes(inputs: int, net_arch: tuple[int, ...], outputs: int) -> int:
    """float32 parameters of a fully connected network (weights and biases)."""
    sizes = [inputs, *net_arch, outputs]
    return 4 * sum((a + 1) * b for a, b in zip(sizes[:-1], sizes[1:]))


class _OffPolicyAgent(SB3Agent):
    """SAC and TD3: act, store the transition, and update every ``train_freq`` steps (SB3's
    ``OffPolicyAlgorithm.learn``: ``collect_rollouts`` of ``train_freq`` steps, then ``train``)."""

    def _sb3_kwargs(self) -> dict[str, Any]:
        c = self.config
        return dict(
            learning_rate=c.learning_rate,
            buffer_size=c.buffer_size,
            learning_starts=c.learning_starts,
            batch_size=c.batch_size,
            tau=c.tau,
            gamma=c.gamma,
            train_freq=c.train_freq,
            gradient_steps=c.gradient_steps,
            policy_kwargs={"net_arch": list(c.net_arch)},
        )

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._buffer_action: np.ndarray | None = (
            None  # the scaled action of the step, for the buffer
        )
        self._steps_since_update = 0

    def _act(self) -> np.ndarray:
        """SB3's ``_sample_action``: random before ``learning_starts``, else the stochastic policy
        (SAC) or the actor plus exploration noise (TD3); keeps the scaled action for the buffer."""
        model = self.model
        with self._own_randomness():
            action, self._buffer_action = model._sample_action(
                model.learning_starts, model.action_noise, 1
            )
        return action[0].astype(float)

    def _record(self, reward: float, x: np.ndarray, last: bool, terminal: bool = False) -> None:
        """What ``collect_rollouts`` does after ``env.step``, then ``learn``'s update when due."""
        model = self.model
        observation = self._observation(x)
        # A trial that ends on its time limit is stored as a time-out, whose value is bootstrapped;
        # one that ends in a terminal state as a done, whose value is 0.
        infos = (
            [{"terminal_observation": observation[0], "TimeLimit.truncated": not terminal}]
            if last
            else [{}]
        )
        model.num_timesteps += 1
        model._store_transition(
            model.replay_buffer,
            self._buffer_action,
            observation,
            np.array([reward], dtype=np.float32),
            np.array([last]),
            infos,
        )
        model._on_step()
        if last:
            model._episode_num += 1
            if model.action_noise is not None:
                model.action_noise.reset()
        self._steps_since_update += 1
        if self._steps_since_update == model.train_freq.frequency:
            self._steps_since_update = 0
            if model.num_timesteps > model.learning_starts:
                steps = (
                    model.gradient_steps
                    if model.gradient_steps >= 0
                    else model.train_freq.frequency
                )
                if steps > 0:
                    with self._own_randomness():
                        model.train(batch_size=model.batch_size, gradient_steps=steps)
                    model.policy.set_training_mode(False)  # as collect_rollouts sets it

    def _value(self, x: np.ndarray) -> float:
        """The critics' estimate of the greedy action's value in x: their minimum, as the targets use."""
        torch = self._torch
        with torch.no_grad():
            observation = torch.as_tensor(self._observation(x))
            action = self._greedy_scaled_action(observation)
            return float(torch.cat(self.model.critic(observation, action), dim=1).min())

    def _greedy_scaled_action(self, observation):
        raise NotImplementedError

    @classmethod
    def _memory_parts(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """An upper estimate (see :meth:`Agent.memory_estimate`): the actor and two critics, each
        with a target copy and Adam's two moments, and a full replay buffer of float32 transitions
        (observation, next observation, action, reward, done, timeout)."""
        n, m = state_space.dim, action_space.dim
        networks = 4 * (
            _network_bytes(n, config.net_arch, 2 * m)
            + 2 * _network_bytes(n + m, config.net_arch, 1)
        )
        buffer = 4 * config.buffer_size * (2 * n + m + 3)
        return networks + buffer, networks + buffer

    def _optimizers(self) -> dict[str, Any]:
        return {
            "actor_optimizer.": self.model.actor.optimizer,
            "critic_optimizer.": self.model.critic.optimizer,
        }

    def _state(self) -> dict[str, np.ndarray]:
        state = super()._state()
        for prefix, optimizer in self._optimizers().items():
            state.update(_arrays_of_optimizer(prefix, optimizer))
        buffer = self.model.replay_buffer
        filled = buffer.buffer_size if buffer.full else buffer.pos
        for name in (
            "observations",
            "next_observations",
            "actions",
            "rewards",
            "dones",
            "timeouts",
        ):
            state[f"replay.{name}"] = getattr(buffer, name)[:filled].copy()
        state["replay.position"] = np.array([buffer.pos, buffer.full], dtype=np.int64)
        state["action_space_rng"] = generator_state_array(self.model.action_space.np_random)
        state["episodes"] = np.array(self.model._episode_num, dtype=np.int64)
        state["steps_since_update"] = np.array(self._steps_since_update, dtype=np.int64)
        if self._in_trial:
            state["buffer_action"] = np.array(self._buffer_action)
        return state

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        super()._load_state(state)
        for prefix, optimizer in self._optimizers().items():
            _load_optimizer(prefix, optimizer, state)
        buffer = self.model.replay_buffer
        buffer.reset()
        position, full = (int(v) for v in state["replay.position"])
        for name in (
            "observations",
            "next_observations",
            "actions",
            "rewards",
            "dones",
            "timeouts",
        ):
            saved = state[f"replay.{name}"]
            getattr(buffer, name)[: len(saved)] = saved
        buffer.pos, buffer.full = position, bool(full)
        set_generator_state(self.model.action_space.np_random, state["action_space_rng"])
        self.model._episode_num = int(state["episodes"])
        self._steps_since_update = int(state["steps_since_update"])
        self._buffer_action = (
            np.array(state["buffer_action"], dtype=np.float32) if "buffer_action" in state else None
        )


class SB3SAC(_OffPolicyAgent):
    """Stable-Baselines3's SAC (see the module docstring)."""

    name = "sb3-sac"
    display_name = "SAC (SB3)"
    config_class = SB3SACConfig
    sb3_class = "SAC"

    def _sb3_kwargs(self) -> dict[str, Any]:
        c = self.config
        return {
            **super()._sb3_kwargs(),
            "ent_coef": c.ent_coef,
            "target_entropy": c.target_entropy,
            "target_update_interval": c.target_update_interval,
        }

    def _greedy_scaled_action(self, observation):
        return self.model.actor(observation, deterministic=True)

    def _optimizers(self) -> dict[str, Any]:
        optimizers = super()._optimizers()
        if self.model.ent_coef_optimizer is not None:
            optimizers["ent_coef_optimizer."] = self.model.ent_coef_optimizer
        return optimizers

    def _state(self) -> dict[str, np.ndarray]:
        state = super()._state()
        if self.model.log_ent_coef is not None:
            state["log_ent_coef"] = self.model.log_ent_coef.detach().numpy().copy()
        return state

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        super()._load_state(state)
        if self.model.log_ent_coef is not None:
            with self._torch.no_grad():
                self.model.log_ent_coef.copy_(
                    self._torch.from_numpy(np.array(state["log_ent_coef"]))
                )


class SB3TD3(_OffPolicyAgent):
    """Stable-Baselines3's TD3 (see the module docstring), with Gaussian exploration noise."""

    name = "sb3-td3"
    display_name = "TD3 (SB3)"
    config_class = SB3TD3Config
    sb3_class = "TD3"

    def _sb3_kwargs(self) -> dict[str, Any]:
        from stable_baselines3.common.noise import NormalActionNoise

        c = self.config
        m = self.action_space.dim
        noise = (
            NormalActionNoise(mean=np.zeros(m), sigma=c.action_noise * np.ones(m))
            if c.action_noise > 0
            else None
        )
        return {
            **super()._sb3_kwargs(),
            "policy_delay": c.policy_delay,
            "target_policy_noise": c.target_policy_noise,
            "target_noise_clip": c.target_noise_clip,
            "action_noise": noise,
        }

    def _greedy_scaled_action(self, observation):
        return self.model.actor(observation)


class SB3PPO(SB3Agent):
    """Stable-Baselines3's PPO (see the module docstring): rollouts of ``n_steps`` control steps
    across trials, each followed by ``n_epochs`` of minibatch updates (SB3's ``OnPolicyAlgorithm.learn``).
    """

    name = "sb3-ppo"
    display_name = "PPO (SB3)"
    config_class = SB3PPOConfig
    sb3_class = "PPO"

    @classmethod
    def _memory_parts(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """An upper estimate (see :meth:`Agent.memory_estimate`): the policy and value networks
        with Adam's two moments, and a full rollout of float32 entries (observation, action,
        reward, return, advantage, value, log probability, episode start)."""
        n, m = state_space.dim, action_space.dim
        networks = 3 * (
            _network_bytes(n, config.net_arch, m) + _network_bytes(n, config.net_arch, 1)
        )
        rollout = 4 * config.n_steps * (n + m + 6)
        return networks + rollout, networks + rollout

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.model._last_episode_starts = np.ones((1,), dtype=bool)
        self._pending: tuple[Any, Any, Any] | None = None  # the step's (action, value, log prob)

    def _sb3_kwargs(self) -> dict[str, Any]:
        c = self.config
        return dict(
            learning_rate=c.learning_rate,
            n_steps=c.n_steps,
            batch_size=c.batch_size,
            n_epochs=c.n_epochs,
            gamma=c.gamma,
            gae_lambda=c.gae_lambda,
            clip_range=c.clip_range,
            clip_range_vf=c.clip_range_vf,
            normalize_advantage=c.normalize_advantage,
            ent_coef=c.ent_coef,
            vf_coef=c.vf_coef,
            max_grad_norm=c.max_grad_norm,
            target_kl=c.target_kl,
            policy_kwargs={"net_arch": list(c.net_arch), "log_std_init": c.log_std_init},
        )

    def _act(self) -> np.ndarray:
        """One step of SB3's ``collect_rollouts``: sample from the policy, clip to the bounds."""
        model, torch = self.model, self._torch
        from stable_baselines3.common.utils import obs_as_tensor

        with self._own_randomness(), torch.no_grad():
            actions, values, log_probs = model.policy(obs_as_tensor(model._last_obs, model.device))
        actions = actions.cpu().numpy()
        self._pending = (actions, values, log_probs)
        clipped = np.clip(actions, model.action_space.low, model.action_space.high)
        return clipped[0].astype(float)

    def _record(self, reward: float, x: np.ndarray, last: bool, terminal: bool = False) -> None:
        """The rest of that step (a time-out's reward bootstrapped with gamma V(x_K), a terminal
        state's not), then, with a full rollout, its advantages and the update."""
        model, torch = self.model, self._torch
        from stable_baselines3.common.utils import obs_as_tensor

        observation = self._observation(x)
        rewards = np.array([reward], dtype=np.float32)
        model.num_timesteps += 1
        if last and not terminal:
            final = model.policy.obs_to_tensor(observation[0])[0]
            with torch.no_grad():
                final_value = model.policy.predict_values(final)[0]
            rewards[0] += model.gamma * final_value
        actions, values, log_probs = self._pending
        model.rollout_buffer.add(
            model._last_obs, actions, rewards, model._last_episode_starts, values, log_probs
        )
        model._last_obs = observation
        model._last_episode_starts = np.array([last])
        if model.rollout_buffer.full:
            with torch.no_grad():
                # After a trial's end this is V(x_K), which the time-out masks: SB3 would use the next
                # trial's first state there, with the same (masked) result.
                last_values = model.policy.predict_values(obs_as_tensor(observation, model.device))
            model.rollout_buffer.compute_returns_and_advantage(
                last_values=last_values, dones=np.array([last])
            )
            with self._own_randomness():
                model.train()
            model.rollout_buffer.reset()
            model.policy.set_training_mode(False)

    def _value(self, x: np.ndarray) -> float:
        with self._torch.no_grad():
            return float(
                self.model.policy.predict_values(self._torch.as_tensor(self._observation(x)))[0, 0]
            )

    _ROLLOUT = ("observations", "actions", "rewards", "episode_starts", "values", "log_probs")

    def _state(self) -> dict[str, np.ndarray]:
        state = super()._state()
        state.update(_arrays_of_optimizer("optimizer.", self.model.policy.optimizer))
        buffer = self.model.rollout_buffer
        for name in self._ROLLOUT:
            state[f"rollout.{name}"] = getattr(buffer, name)[: buffer.pos].copy()
        state["last_episode_starts"] = np.array(self.model._last_episode_starts)
        if self._in_trial:
            actions, values, log_probs = self._pending
            state["pending_action"] = actions.copy()
            state["pending_value"] = values.numpy().copy()
            state["pending_log_prob"] = log_probs.numpy().copy()
        return state

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        super()._load_state(state)
        _load_optimizer("optimizer.", self.model.policy.optimizer, state)
        buffer = self.model.rollout_buffer
        buffer.reset()
        for name in self._ROLLOUT:
            saved = state[f"rollout.{name}"]
            getattr(buffer, name)[: len(saved)] = saved
        buffer.pos = len(state["rollout.observations"])
        self.model._last_episode_starts = np.array(state["last_episode_starts"], dtype=bool)
        if "pending_action" in state:
            torch = self._torch
            self._pending = (
                np.array(state["pending_action"], dtype=np.float32),
                torch.from_numpy(np.array(state["pending_value"])),
                torch.from_numpy(np.array(state["pending_log_prob"])),
            )
        else:
            self._pending = None
