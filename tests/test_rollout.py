"""The trial loop shared by experiments, plots and videos."""

import numpy as np
import pytest
from learners import quick_config

from rmac_mj import tasks
from rmac_mj.agents import ALGORITHMS, make_agent
from rmac_mj.figures import policy_actions, policy_slice
from rmac_mj.rollout import (
    action_space_of,
    run_trial,
    state_of,
    state_space_of,
    steps_per_trial,
    trial_seconds,
)


@pytest.fixture(scope="module", params=ALGORITHMS)
def learned(request):
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent(
        request.param,
        state_space_of(env),
        action_space_of(env),
        config=quick_config(request.param),
        seed=3,
    )
    for _ in range(15):
        run_trial(env, agent, learn=True)
    return env, agent


@pytest.mark.slow
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


@pytest.mark.slow
def test_policy_map_does_not_depend_on_scan_order(learned):
    _, agent = learned
    xs, ys, actions, values = policy_slice(
        agent, [-np.pi, -25.0], [np.pi, 25.0], [0.0, 0.0], resolution=(7, 5)
    )
    assert actions.shape == (5, 7, 1) and values.shape == (5, 7)
    np.testing.assert_allclose(xs, np.linspace(-np.pi, np.pi, 7))
    np.testing.assert_allclose(ys, np.linspace(-25.0, 25.0, 5))
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
    x = state_of(env.reset().observation, env.task.learner_state)
    np.testing.assert_allclose(x, [-np.pi, 0.0])
    space = state_space_of(env)
    assert list(space.periodic) == [True, False] and space.period[0] == pytest.approx(2 * np.pi)
    np.testing.assert_array_equal(space.input_weights, [1.0, 0.1])  # Table 2's input weighting
    np.testing.assert_array_equal(action_space_of(env).input_weights, [1.0])
    assert steps_per_trial(env) == 100 and trial_seconds(env) == pytest.approx(3.0)


def test_rmac_weightings_default_to_table_2_from_the_task_and_explicit_ones_win():
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent("rmac", state_space_of(env), action_space_of(env), seed=0)
    assert agent.config.critic.weights == agent.config.reference.weights == (1.0, 0.1)
    assert agent.config.process.weights == (1.0, 0.1, 1.0)
    np.testing.assert_array_equal(agent.process.input_weights, [1.0, 0.1, 1.0])
    agent = make_agent(
        "rmac",
        state_space_of(env),
        action_space_of(env),
        seed=0,
        config={"critic": {"weights": (1.0, 0.3)}},
    )
    assert agent.config.critic.weights == (1.0, 0.3) and agent.config.reference.weights == (
        1.0,
        0.1,
    )
