"""The deep-RL baselines: Stable-Baselines3's SAC, TD3 and PPO and sb3-contrib's CrossQ behind the
learner contract (:class:`~rmac_mj.agents.base.Agent`), built by their keys (:data:`BASELINES`)
with ``rmac_mj.agents.make_agent`` like every learner.

The driver they share (:class:`SB3Agent`, what the learners see and do) is in ``driver.py``, SAC,
TD3 and CrossQ in ``off_policy.py``, PPO in ``ppo.py``, their configs in ``config.py``. The configs
and this face import without the ``[baselines]`` extra (torch, stable-baselines3, sb3-contrib);
building a learner without it raises an ImportError naming the extra (:data:`INSTALL_HINT`).
"""

from __future__ import annotations

from rmac_mj.agents.sb3.config import (
    BASELINES,
    INSTALL_HINT,
    SB3CrossQConfig,
    SB3PPOConfig,
    SB3SACConfig,
    SB3TD3Config,
    available,
)
from rmac_mj.agents.sb3.driver import SB3Agent, network_input
from rmac_mj.agents.sb3.off_policy import SB3SAC, SB3TD3, SB3CrossQ
from rmac_mj.agents.sb3.ppo import SB3PPO

__all__ = [
    # The learners and their configs
    "SB3CrossQ",
    "SB3CrossQConfig",
    "SB3PPO",
    "SB3PPOConfig",
    "SB3SAC",
    "SB3SACConfig",
    "SB3TD3",
    "SB3TD3Config",
    # Their keys, whether they can run, and the driver they share
    "BASELINES",
    "INSTALL_HINT",
    "SB3Agent",
    "available",
    "network_input",
]
