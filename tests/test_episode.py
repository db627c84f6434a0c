"""The trial loop shared by experiments, plots and videos."""

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import ALGORITHMS, make_agent
from rmac_mj.experiments.episode import action_space_of, run_trial, state_of, state_space_of
from rmac_mj.experiments.plots import policy_actions, policy_grid


@pytest.fixture(scope="module", params=ALGORITHMS)
def learned(request):
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent(request.param, state_space_of(env), action_space_of(env), seed=3)
    for _ in range(15):
        run_trial(env, agent, learn=True)
    return env, agent


def test_greedy_trials_are_repeatable_and_learn_nothing(learned):
    env, agent = learned
    before = {k: v.copy() for k, v in agent.state_dict().items()}
    first, second = run_trial(env, agent, learn=False), run_trial(env, agent, learn=False)
    assert first == second  # nothing carried over from one greedy trial to the next
    after = agent.state_dict()
    for key, value in before.items():
        if key == "u_greedy":  # RMAC's last greedy action: what a greedy trial may change
            continue
        np.testing.assert_array_equal(value, after[key], err_msg=key)


def test_policy_map_does_not_depend_on_scan_order(learned):
    _, agent = learned
    _, _, actions, values = policy_grid(agent, n_angle=7, n_velocity=5)
    assert actions.shape == values.shape == (5, 7)
    assert np.all(np.abs(actions) <= 3.0)
    assert np.ptp(actions) > 0  # a learned map, not a constant one
    # The same states scanned in a shuffled order (and in reverse) give the same action per state.
    rng = np.random.default_rng(0)
    states = rng.uniform([-np.pi, -20.0], [np.pi, 20.0], size=(40, 2))
    forward = policy_actions(agent, states)
    order = rng.permutation(len(states))
    shuffled = np.empty_like(forward)
    shuffled[order] = policy_actions(agent, states[order])
    np.testing.assert_array_equal(forward, shuffled)
    np.testing.assert_array_equal(forward, policy_actions(agent, states[::-1])[::-1])


def test_state_is_angle_then_velocity():
    env = tasks.load("dc_pendulum", "swingup")
    x = state_of(env.reset().observation)
    np.testing.assert_allclose(x, [-np.pi, 0.0])
    space = state_space_of(env)
    assert list(space.periodic) == [True, False] and space.period[0] == pytest.approx(2 * np.pi)
