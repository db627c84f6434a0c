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
import without it, the learners raise an ImportError naming the extra. The three share one driver
(:mod:`rmac_mj.agents.sb3_base`); SAC and TD3 are in :mod:`rmac_mj.agents.sb3_off_policy`, PPO in
:mod:`rmac_mj.agents.sb3_ppo`.
"""

from rmac_mj.agents.sb3_base import SB3Agent, network_input
from rmac_mj.agents.sb3_off_policy import SB3SAC, SB3TD3
from rmac_mj.agents.sb3_ppo import SB3PPO

__all__ = ["SB3PPO", "SB3SAC", "SB3TD3", "SB3Agent", "network_input"]
