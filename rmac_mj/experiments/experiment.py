"""Experiment i of a protocol assembled from its seeds (:func:`build_experiment`), exactly as the
runner does: experiment i seeds its agent from ``SeedSequence(seed, spawn_key=(i,))``, its task
from child ``(i, 0)``, its demonstration from ``(i, 1)``, its greedy evaluation's starts from
``(i, 2)``, so results do not depend on workers or resuming."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from dm_control.rl import control

from rmac_mj.agents import (
    ActionSpace,
    Agent,
    StateSpace,
    make_agent,
)
from rmac_mj.experiments import prior_transitions as prior_data
from rmac_mj.experiments.protocol import Protocol
from rmac_mj.rollout import action_space_of, run_trial, state_space_of


def experiment_seeds(seed: int, index: int) -> tuple[np.random.SeedSequence, int]:
    """The agent's seed sequence and the task's integer seed of experiment ``index``."""
    agent_seq = np.random.SeedSequence(seed, spawn_key=(index,))
    task_seed = int(np.random.SeedSequence(seed, spawn_key=(index, 0)).generate_state(1)[0])
    return agent_seq, task_seed


def demonstration_for(protocol: Protocol, index: int) -> prior_data.Demonstration:
    """``prior_trials`` trials of demonstrator ``protocol.prior`` for experiment ``index``, recorded
    deterministically from the sequence ``(index, 1)``: its child 0 seeds the recording's task, the
    sequence itself the demonstrator's action noise."""
    demonstrator = protocol.knowledge.demonstrator(protocol.prior, protocol.environment_name)
    sequence = np.random.SeedSequence(protocol.seed, spawn_key=(index, 1))
    task_seed = int(
        np.random.SeedSequence(protocol.seed, spawn_key=(index, 1, 0)).generate_state(1)[0]
    )
    env = protocol.make_environment(task_seed)
    return prior_data.record(
        env,
        demonstrator.controller(env),
        protocol.prior_trials,
        seed=np.random.default_rng(sequence),
        action_noise=demonstrator.action_noise,
    )


@dataclasses.dataclass
class Experiment:
    """Experiment ``index`` of ``algorithm``, assembled and ready for its first trial.

    Attributes:
      env: its environment, the task's random state seeded with ``task_seed``.
      agent: the fresh agent, its generator from the experiment's seed sequence, already seeded with
        the prior knowledge of ``demonstration`` (if any).
      state_space, action_space: the task's, as the agent sees them.
      demonstration: the prior knowledge seeded, or None.
    """

    algorithm: str
    index: int
    env: control.Environment
    agent: Agent
    state_space: StateSpace
    action_space: ActionSpace
    task_seed: int
    demonstration: prior_data.Demonstration | None


def build_experiment(
    protocol: Protocol,
    algorithm: str,
    index: int,
    demonstration: prior_data.Demonstration | None = None,
) -> Experiment:
    """Assemble experiment ``index`` of ``algorithm`` exactly as the runner does: its environment and
    fresh agent from the experiment's seeds, then the prior knowledge (``demonstration`` when the
    protocol's prior is a file the caller read; else recorded here from the protocol's demonstrator)."""
    agent_seq, task_seed = experiment_seeds(protocol.seed, index)
    env = protocol.make_environment(task_seed)
    state_space, action_space = state_space_of(env), action_space_of(env)
    agent = make_agent(
        algorithm,
        state_space,
        action_space,
        config=protocol.agent_configs.get(algorithm),
        seed=np.random.default_rng(agent_seq),
    )
    if protocol.prior is not None:
        if demonstration is None:
            demonstration = demonstration_for(protocol, index)
        agent.seed_from(**demonstration.arrays(), parts=protocol.prior_parts or None)
    return Experiment(
        algorithm=algorithm,
        index=index,
        env=env,
        agent=agent,
        state_space=state_space,
        action_space=action_space,
        task_seed=task_seed,
        demonstration=demonstration if protocol.prior is not None else None,
    )


def fresh_learners(protocol: Protocol) -> dict[str, Agent]:
    """A learner of each of the protocol's algorithms as its experiments begin (their config, on
    the protocol's environment; one environment built for all): what the files a run keeps are
    checked against (``Agent.check_state_dict``)."""
    env = protocol.make_environment(experiment_seeds(protocol.seed, 0)[1])
    state_space, action_space = state_space_of(env), action_space_of(env)
    return {
        algorithm: make_agent(
            algorithm,
            state_space,
            action_space,
            config=protocol.agent_configs.get(algorithm),
            seed=0,
        )
        for algorithm in protocol.algorithms
    }


def evaluation(protocol: Protocol, index: int) -> Callable[[control.Environment, Agent], float]:
    """How experiment ``index`` evaluates its agent (``Protocol.evaluate_starts``): a function
    ``(env, agent) -> greedy return``."""
    if protocol.evaluate_starts == 0:
        return lambda env, agent: run_trial(env, agent, learn=False)
    seed = int(np.random.SeedSequence(protocol.seed, spawn_key=(index, 2)).generate_state(1)[0])

    def evaluate(env: control.Environment, agent: Agent) -> float:
        starts = protocol.make_environment(seed)  # the same starts at every evaluation
        return float(
            np.mean(
                [run_trial(starts, agent, learn=False) for _ in range(protocol.evaluate_starts)]
            )
        )

    return evaluate
