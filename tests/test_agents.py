"""What every learner shares: construction, validation and the registry."""

import numpy as np
import pytest

from rmac_mj.agents import ALGORITHMS, config_class, make_agent
from rmac_mj.agents.base import ActionSpace, Exploration, StateSpace

STATES = StateSpace(low=[-np.pi, -25.0], high=[np.pi, 25.0], periodic=[True, False])
ACTIONS = ActionSpace(low=[-3.0], high=[3.0])


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_constructor_checks_its_arguments_by_name(algorithm):
    agent_cls = type(make_agent(algorithm, STATES, ACTIONS, seed=0))
    with pytest.raises(TypeError, match="state_space must be a StateSpace"):
        agent_cls((-1, 1), ACTIONS)
    with pytest.raises(TypeError, match="action_space must be an ActionSpace"):
        agent_cls(STATES, [-3, 3])
    with pytest.raises(TypeError, match=f"config must be a {config_class(algorithm).__name__}"):
        agent_cls(STATES, ACTIONS, config={"gamma": 0.9})


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_make_agent_takes_overrides_of_the_paper_defaults(algorithm):
    agent = make_agent(algorithm, STATES, ACTIONS, config={"gamma": 0.9}, seed=0)
    assert agent.config.gamma == 0.9 and agent.config.lam == 0.65  # the paper's lambda kept
    assert agent.name == algorithm
    with pytest.raises(ValueError, match="unknown hyperparameters"):
        make_agent(algorithm, STATES, ACTIONS, config={"gama": 0.9})


def test_unknown_algorithm_lists_the_known_ones():
    with pytest.raises(ValueError, match="rmac, s-ac"):
        make_agent("ppo", STATES, ACTIONS)


def test_spaces_and_exploration_reject_bad_values():
    with pytest.raises(ValueError, match="low < high"):
        StateSpace(low=[1.0], high=[0.0], periodic=[False])
    with pytest.raises(ValueError, match="one shape"):
        StateSpace(low=[0.0, 0.0], high=[1.0], periodic=[False])
    with pytest.raises(ValueError, match="sigma"):
        Exploration(sigma=-1.0)
    with pytest.raises(ValueError, match="period"):
        Exploration(period=0)
    rng = np.random.default_rng(0)
    explore = Exploration()
    draws = [explore.sample(k, 1, rng)[0] for k in range(9)]
    assert [d != 0 for d in draws] == [True, False, False] * 3  # every third step, from step 0
