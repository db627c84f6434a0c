"""SB3's on-policy baseline, PPO, driven one control step at a time in the order of SB3's
``OnPolicyAlgorithm.learn``."""

from __future__ import annotations

from typing import Any

import numpy as np

from rmac_mj.agents.sb3.config import SB3PPOConfig
from rmac_mj.agents.sb3.driver import SB3Agent, arrays_of_optimizer, load_optimizer, network_bytes
from rmac_mj.agents.spaces import ActionSpace, StateSpace


class SB3PPO(SB3Agent):
    """Stable-Baselines3's PPO (see :mod:`rmac_mj.agents.sb3.driver`): rollouts of ``n_steps`` control steps
    across trials, each followed by ``n_epochs`` of minibatch updates (SB3's ``OnPolicyAlgorithm.learn``).
    """

    name = "sb3-ppo"
    display_name = "PPO (SB3)"
    config_class = SB3PPOConfig
    sb3_class = "PPO"
    policy_fields = ("net_arch", "log_std_init")

    @classmethod
    def _memory_parts(
        cls, config: Any, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """An upper estimate (see :meth:`Agent.memory_estimate`): the policy and value networks
        with Adam's two moments, and a full rollout of float32 entries (observation, action,
        reward, return, advantage, value, log probability, episode start)."""
        n, m = state_space.dim, action_space.dim
        networks = 3 * (network_bytes(n, config.net_arch, m) + network_bytes(n, config.net_arch, 1))
        rollout = 4 * config.n_steps * (n + m + 6)
        return networks + rollout, networks + rollout

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.model._last_episode_starts = np.ones((1,), dtype=bool)
        self._pending: tuple[Any, Any, Any] | None = None  # the step's (action, value, log prob)

    def _policy_kwargs(self) -> dict[str, Any]:
        return {"net_arch": list(self.config.net_arch), "log_std_init": self.config.log_std_init}

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
        state.update(arrays_of_optimizer("optimizer.", self.model.policy.optimizer))
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
        load_optimizer("optimizer.", self.model.policy.optimizer, state)
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
