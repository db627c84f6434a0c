"""SB3's off-policy baselines, SAC, TD3 and sb3-contrib's CrossQ, driven one control step at a time
in the order of SB3's ``OffPolicyAlgorithm.learn``."""

from __future__ import annotations

from typing import Any

import numpy as np

from rmac_mj.agents.base import generator_state_array, set_generator_state
from rmac_mj.agents.sb3.config import SB3CrossQConfig, SB3SACConfig, SB3TD3Config
from rmac_mj.agents.sb3.driver import SB3Agent, arrays_of_optimizer, load_optimizer, network_bytes
from rmac_mj.agents.spaces import ActionSpace, StateSpace

#: The arrays of SB3's replay buffer that a learner's state holds (``replay.<name>``, filled rows).
_REPLAY_ARRAYS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")


class _OffPolicyAgent(SB3Agent):
    """SAC, TD3 and CrossQ: act, store the transition, and update every ``train_freq`` steps (SB3's
    ``OffPolicyAlgorithm.learn``: ``collect_rollouts`` of ``train_freq`` steps, then ``train``)."""

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
        critic = getattr(config, "critic_net_arch", config.net_arch)
        networks = 4 * (
            network_bytes(n, config.net_arch, 2 * m) + 2 * network_bytes(n + m, critic, 1)
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
            state.update(arrays_of_optimizer(prefix, optimizer))
        buffer = self.model.replay_buffer
        filled = buffer.buffer_size if buffer.full else buffer.pos
        for name in _REPLAY_ARRAYS:
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
            load_optimizer(prefix, optimizer, state)
        buffer = self.model.replay_buffer
        buffer.reset()
        position, full = (int(v) for v in state["replay.position"])
        for name in _REPLAY_ARRAYS:
            saved = state[f"replay.{name}"]
            getattr(buffer, name)[: len(saved)] = saved
        buffer.pos, buffer.full = position, bool(full)
        set_generator_state(self.model.action_space.np_random, state["action_space_rng"])
        self.model._episode_num = int(state["episodes"])
        self._steps_since_update = int(state["steps_since_update"])
        self._buffer_action = (
            np.array(state["buffer_action"], dtype=np.float32) if "buffer_action" in state else None
        )


class _EntropyRegularised(_OffPolicyAgent):
    """SAC and CrossQ: a stochastic actor whose entropy coefficient may be learned."""

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


class SB3SAC(_EntropyRegularised):
    """Stable-Baselines3's SAC (see :mod:`rmac_mj.agents.sb3.driver`)."""

    name = "sb3-sac"
    display_name = "SAC (SB3)"
    config_class = SB3SACConfig
    sb3_class = "SAC"


class SB3CrossQ(_EntropyRegularised):
    """sb3-contrib's CrossQ (see :mod:`rmac_mj.agents.sb3.driver` and :class:`SB3CrossQConfig`): SAC's
    driver; the batch renormalisation statistics are part of the policy's state."""

    name = "sb3-crossq"
    display_name = "CrossQ (SB3-contrib)"
    config_class = SB3CrossQConfig
    sb3_class = "CrossQ"
    sb3_package = "sb3_contrib"
    policy_fields = (
        "net_arch",
        "critic_net_arch",
        "batch_norm_momentum",
        "batch_norm_eps",
        "renorm_warmup_steps",
    )

    def _policy_kwargs(self) -> dict[str, Any]:
        c = self.config
        return {
            "net_arch": {"pi": list(c.net_arch), "qf": list(c.critic_net_arch)},
            "batch_norm_momentum": c.batch_norm_momentum,
            "batch_norm_eps": c.batch_norm_eps,
            "renorm_warmup_steps": c.renorm_warmup_steps,
        }


class SB3TD3(_OffPolicyAgent):
    """Stable-Baselines3's TD3 (see :mod:`rmac_mj.agents.sb3.driver`), with Gaussian exploration noise."""

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
        return {**super()._sb3_kwargs(), "action_noise": noise}  # SB3 takes the noise as an object

    def _greedy_scaled_action(self, observation):
        return self.model.actor(observation)
