"""The deep-RL baselines' hyperparameters (Stable-Baselines3's defaults); can they run.

Each config is checked by one constraint table (:mod:`rmac_mj.constraints`) and imports without
torch; the learners are in :mod:`rmac_mj.agents.sb3.driver`.
"""

from __future__ import annotations

import dataclasses
import importlib.util
from numbers import Integral, Real
from typing import ClassVar

from rmac_mj.constraints import Boolean, Interval, Options, TupleOf, check_config

#: The algorithm keys of the baselines.
BASELINES = ("sb3-sac", "sb3-td3", "sb3-ppo", "sb3-crossq")

INSTALL_HINT = (
    "the deep-RL baselines need the [baselines] extra (torch, stable-baselines3, sb3-contrib): "
    'pip install -c constraints.txt -e ".[baselines]" '
    "--extra-index-url https://download.pytorch.org/whl/cpu (torch's CPU build)"
)


def available(package: str = "stable_baselines3") -> bool:
    """Whether torch, gymnasium and ``package`` (the SB3 package a learner's class comes from:
    ``stable_baselines3`` or ``sb3_contrib``) are installed (the ``[baselines]`` extra)."""
    return all(
        importlib.util.find_spec(name) is not None for name in ("torch", "gymnasium", package)
    )


# ----------------------------------------------------------------------------------------------------
# Hyperparameters: SB3's defaults (stable-baselines3 2.9), checked by one table each (rmac_mj.constraints).

#: Hidden units per layer of a network.
_NET_ARCH = TupleOf(
    Interval(Integral, 1, None), what="a list of positive integers (units per layer)"
)
_POSITIVE = [Interval(Real, 0, None, closed="neither")]
_COUNT = [Interval(Integral, 1, None)]

#: What every baseline's config shares.
_COMMON = {
    "learning_rate": _POSITIVE,
    "gamma": [Interval(Real, 0, 1)],
    "batch_size": _COUNT,
    "net_arch": [_NET_ARCH],
    "torch_threads": _COUNT,
}


@dataclasses.dataclass(frozen=True)
class ReplayConfig:
    """What the off-policy learners share (SB3's ``OffPolicyAlgorithm``): SAC, TD3 and CrossQ.

    Attributes:
      learning_rate: Adam's step size of every network.
      buffer_size: capacity of the replay buffer, in transitions (10 simulated minutes of the
        pendulum are 20 000).
      learning_starts: steps of uniformly random actions before the first update.
      batch_size: transitions per gradient step.
      gamma: discount factor per control step.
      train_freq: update after every ``train_freq`` control steps (counted over trials).
      gradient_steps: gradient steps per update; -1: as many as ``train_freq``.
      net_arch: hidden units per layer, the same for the actor and each critic.
      torch_threads: torch's intra-op threads (see :mod:`rmac_mj.agents.sb3.driver`).
    """

    learning_rate: float = 3e-4
    buffer_size: int = 1_000_000
    learning_starts: int = 100
    batch_size: int = 256
    gamma: float = 0.99
    train_freq: int = 1
    gradient_steps: int = 1
    net_arch: tuple[int, ...] = (256, 256)
    torch_threads: int = 1

    parameter_constraints: ClassVar[dict[str, list]] = {
        **_COMMON,
        "buffer_size": _COUNT,
        "learning_starts": [Interval(Integral, 0, None)],
        "train_freq": _COUNT,
        "gradient_steps": [Interval(Integral, -1, None)],
    }

    def __post_init__(self) -> None:
        check_config(self)


@dataclasses.dataclass(frozen=True)
class OffPolicyConfig(ReplayConfig):
    """What SAC and TD3 add to :class:`ReplayConfig`: target networks.

    Attributes:
      tau: Polyak factor of the target networks' soft update.
    """

    tau: float = 0.005

    parameter_constraints: ClassVar[dict[str, list]] = {
        **ReplayConfig.parameter_constraints,
        "tau": [Interval(Real, 0, 1, closed="right")],
    }


@dataclasses.dataclass(frozen=True)
class SB3SACConfig(OffPolicyConfig):
    """Soft actor-critic (Haarnoja et al. 2018), SB3's defaults.

    Attributes (besides :class:`OffPolicyConfig`'s):
      ent_coef: the entropy coefficient alpha: a number >= 0, or ``"auto"``: learned, from 1.
      target_update_interval: gradient steps between soft updates of the target critics.
      target_entropy: the entropy ``"auto"`` tunes alpha towards: ``"auto"`` is -(action dimension).
    """

    ent_coef: str | float = "auto"
    target_update_interval: int = 1
    target_entropy: str | float = "auto"

    parameter_constraints: ClassVar[dict[str, list]] = {
        **OffPolicyConfig.parameter_constraints,
        "ent_coef": [Options("auto"), Interval(Real, 0, None)],
        "target_update_interval": _COUNT,
        "target_entropy": [Options("auto"), Interval(Real)],
    }


@dataclasses.dataclass(frozen=True)
class SB3TD3Config(OffPolicyConfig):
    """Twin delayed DDPG (Fujimoto et al. 2018), SB3's defaults but for the exploration noise.

    Attributes (besides :class:`OffPolicyConfig`'s):
      policy_delay: critic updates per actor (and target) update.
      target_policy_noise, target_noise_clip: std and clip of the target policy smoothing noise.
      action_noise: std of the Gaussian exploration noise added to the actor's action, in SB3's
        scaled action units (the action range is [-1, 1]). SB3's constructor default is no noise, which
        leaves TD3 exploring only in its first ``learning_starts`` random steps; 0.1 is the TD3 paper's
        value and the one of SB3's own TD3 example. 0 is SB3's default.
    """

    learning_rate: float = 1e-3
    net_arch: tuple[int, ...] = (400, 300)
    policy_delay: int = 2
    target_policy_noise: float = 0.2
    target_noise_clip: float = 0.5
    action_noise: float = 0.1

    parameter_constraints: ClassVar[dict[str, list]] = {
        **OffPolicyConfig.parameter_constraints,
        "policy_delay": _COUNT,
        "target_policy_noise": [Interval(Real, 0, None)],
        "target_noise_clip": [Interval(Real, 0, None)],
        "action_noise": [Interval(Real, 0, None)],
    }


@dataclasses.dataclass(frozen=True)
class SB3CrossQConfig(ReplayConfig):
    """CrossQ (Bhatt et al. 2024): SAC without target networks, batch renormalisation in the actor
    and the critics, and one joint forward pass of a batch and its next states; sb3-contrib's
    defaults but for the critics' width.

    Attributes (besides :class:`ReplayConfig`'s, where ``net_arch`` is the actor's):
      critic_net_arch: hidden units per layer of each critic. sb3-contrib's default is (1024, 1024)
        (the paper's 2048 narrowed for speed); at 1024 a control step costs about 7x one of SAC on
        one torch thread, at 256 about what SAC's costs, so the panel can afford CrossQ beside SAC.
        sb3-contrib notes that CrossQ already works with a (256, 256) critic.
      policy_delay: critic updates per actor update.
      ent_coef, target_entropy: as :class:`SB3SACConfig`'s.
      batch_norm_momentum, batch_norm_eps: of the batch renormalisation layers.
      renorm_warmup_steps: steps before batch renormalisation's running statistics take over.
    """

    learning_rate: float = 1e-3
    critic_net_arch: tuple[int, ...] = (256, 256)
    policy_delay: int = 3
    ent_coef: str | float = "auto"
    target_entropy: str | float = "auto"
    batch_norm_momentum: float = 0.01
    batch_norm_eps: float = 0.001
    renorm_warmup_steps: int = 100_000

    parameter_constraints: ClassVar[dict[str, list]] = {
        **ReplayConfig.parameter_constraints,
        "critic_net_arch": [_NET_ARCH],
        "policy_delay": _COUNT,
        "ent_coef": [Options("auto"), Interval(Real, 0, None)],
        "target_entropy": [Options("auto"), Interval(Real)],
        "batch_norm_momentum": [Interval(Real, 0, 1)],
        "batch_norm_eps": _POSITIVE,
        "renorm_warmup_steps": [Interval(Integral, 0, None)],
    }


@dataclasses.dataclass(frozen=True)
class SB3PPOConfig:
    """Proximal policy optimisation (Schulman et al. 2017), SB3's defaults.

    Attributes:
      learning_rate: Adam's step size.
      n_steps: control steps per rollout (across trials: 2048 are 20.48 trials of the pendulum).
      batch_size: minibatch size of the updates.
      n_epochs: passes over each rollout.
      gamma: discount factor per control step.
      gae_lambda: the lambda of generalised advantage estimation.
      clip_range: the policy ratio's clipping.
      clip_range_vf: the value function's clipping; None: not clipped.
      normalize_advantage: normalise the advantages of each minibatch.
      ent_coef, vf_coef: weights of the entropy bonus and the value loss.
      max_grad_norm: gradient norm clipping.
      target_kl: stop an update early above this KL divergence; None: never.
      log_std_init: initial log standard deviation of the Gaussian policy.
      net_arch: hidden units per layer, the same for the policy and the value network (tanh).
      torch_threads: torch's intra-op threads (see :mod:`rmac_mj.agents.sb3.driver`).
    """

    learning_rate: float = 3e-4
    n_steps: int = 2048
    batch_size: int = 64
    n_epochs: int = 10
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    clip_range_vf: float | None = None
    normalize_advantage: bool = True
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_kl: float | None = None
    log_std_init: float = 0.0
    net_arch: tuple[int, ...] = (64, 64)
    torch_threads: int = 1

    parameter_constraints: ClassVar[dict[str, list]] = {
        **_COMMON,
        "n_steps": [Interval(Integral, 2, None)],
        "n_epochs": _COUNT,
        "gae_lambda": [Interval(Real, 0, 1)],
        "clip_range": _POSITIVE,
        "clip_range_vf": [_POSITIVE[0], None],
        "normalize_advantage": [Boolean()],
        "ent_coef": [Interval(Real, 0, None)],
        "vf_coef": [Interval(Real, 0, None)],
        "max_grad_norm": _POSITIVE,
        "target_kl": [_POSITIVE[0], None],
        "log_std_init": [Interval(Real)],
    }

    def __post_init__(self) -> None:
        check_config(self)
