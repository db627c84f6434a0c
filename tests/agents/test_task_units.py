"""Settings in the task's own units: on the paper's pendulum every default resolves to the paper's
number (section 6, Table 2), elsewhere it follows the task's step, action range, reward scale and
dimensions, and a value set explicitly is kept."""

import math

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import ActionSpace, StateSpace, make_agent
from rmac_mj.agents.task_knowledge import PAPER_REWARD_SCALE
from rmac_mj.rollout import action_space_of, state_space_of


def _pendulum_spaces():
    env = tasks.load("dc_pendulum", "swingup")
    return state_space_of(env), action_space_of(env)


def _spaces(n=4, m=2, timestep=0.05, reward_scale=None, action_high=1.0):
    state = StateSpace(
        low=-np.ones(n),
        high=np.ones(n),
        periodic=np.zeros(n, bool),
        timestep=timestep,
        reward_scale=reward_scale,
    )
    return state, ActionSpace(low=-action_high * np.ones(m), high=action_high * np.ones(m))


def test_the_pendulum_declares_its_step_and_reward_scale():
    state, _ = _pendulum_spaces()
    assert state.timestep == 0.03
    assert state.reward_scale == PAPER_REWARD_SCALE == 5.0 * math.pi**2


def test_resolved_on_the_paper_pendulum_every_default_is_table_2():
    """Pinned: the exact floats of the paper's settings (section 6.1, 6.2, Table 2)."""
    state, action = _pendulum_spaces()
    rmac = make_agent("rmac", state, action, seed=0, config={"planning": {"steps": 1}}).config
    assert (rmac.gamma, rmac.lam, rmac.alpha_c, rmac.alpha_r) == (0.97, 0.65, 0.1, 0.005)
    assert (rmac.critic.capacity, rmac.critic.neighbours, rmac.critic.weights) == (
        2000,
        20,
        (1.0, 0.1),
    )
    assert (rmac.process.capacity, rmac.process.neighbours, rmac.process.weights) == (
        100,
        9,
        (1.0, 0.1, 1.0),
    )
    assert (rmac.reference.capacity, rmac.reference.neighbours, rmac.reference.weights) == (
        2000,
        20,
        (1.0, 0.1),
    )
    assert (rmac.planning.model_capacity, rmac.planning.model_neighbours) == (2000, 9)
    sac = make_agent("s-ac", state, action, seed=0)
    c = sac.config
    assert (c.gamma, c.lam, c.alpha_a, c.alpha_c) == (0.97, 0.65, 0.005, 0.1)
    assert sac.rate_a == 0.005 / 16 and "reward_scale" not in sac.state_dict()
    mlac = make_agent("mlac", state, action, seed=0).config
    assert (mlac.gamma, mlac.lam, mlac.alpha_a, mlac.alpha_c) == (0.97, 0.65, 0.05, 0.3)
    assert (
        mlac.actor.capacity,
        mlac.actor.neighbours,
        mlac.critic.capacity,
        mlac.critic.neighbours,
        mlac.process.capacity,
        mlac.process.neighbours,
    ) == (2000, 25, 2000, 15, 100, 10)
    for config in (rmac, c, mlac):
        assert (config.exploration.sigma, config.exploration.period) == (1.0, 3)


@pytest.mark.parametrize("name", ["rmac", "s-ac", "mlac"])
def test_elsewhere_the_settings_follow_the_task(name):
    """Horizon in seconds, noise as a fraction of the range, memories grown with the dimension."""
    state, action = _spaces(n=4, m=2, timestep=0.06, action_high=1.5)
    overrides = {"planning": {"steps": 1}, **({"action_cost": 0.0} if name == "mlac" else {})}
    config = make_agent(name, state, action, seed=0, config=overrides).config
    assert config.gamma == pytest.approx(0.97**2) and config.lam == pytest.approx(0.65**2)
    assert config.exploration.sigma == pytest.approx(1.0 * 3.0 / 6.0)
    assert (config.planning.model_capacity, config.planning.model_neighbours) == (4000, 18)
    if name == "rmac":
        assert (
            config.critic.capacity,
            config.critic.neighbours,
            config.process.capacity,
            config.process.neighbours,
        ) == (4000, 40, 200, 18)


def test_a_value_set_explicitly_wins():
    state, action = _spaces()
    config = make_agent(
        "rmac",
        state,
        action,
        seed=0,
        config={"gamma": 0.99, "critic": {"capacity": 300}, "exploration": {"sigma": 0.7}},
    ).config
    assert (config.gamma, config.critic.capacity, config.exploration.sigma) == (0.99, 300, 0.7)
    # the critic's other settings stay RMAC's: K from the task (20 n / 2 at n = 4), clipped
    assert (config.critic.neighbours, config.critic.clip, config.critic.weights) == (
        40,
        True,
        (1.0,) * 4,
    )


def test_s_ac_actor_rate_follows_a_declared_reward_scale_down_but_never_up():
    state, action = _spaces(m=1, reward_scale=PAPER_REWARD_SCALE * 10)
    assert make_agent("s-ac", state, action, seed=0).config.alpha_a == pytest.approx(0.0005)
    for smaller in (PAPER_REWARD_SCALE / 10, 1e-6):
        state, action = _spaces(m=1, reward_scale=smaller)
        assert make_agent("s-ac", state, action, seed=0).config.alpha_a == 0.005


def test_the_dyna_actor_rate_follows_a_declared_reward_scale_both_ways():
    state, action = _spaces(m=1, reward_scale=PAPER_REWARD_SCALE / 10)
    assert make_agent("s-ac-dyna", state, action, seed=0).config.alpha_a == pytest.approx(0.02)
    state, action = _spaces(m=1, reward_scale=1e-6)
    assert make_agent("s-ac-dyna", state, action, seed=0).config.alpha_a == 1.0  # capped


def _drive(agent, rewards, states):
    agent.start(states[0])
    for r, x in zip(rewards[:-1], states[1:-1]):
        agent.step(r, x)
    agent.stop(rewards[-1], states[-1])


def test_s_ac_without_a_declared_scale_learns_alike_at_any_larger_reward_scale():
    """With the running scale (the largest |r| so far) above the pendulum's, rewards 100 times
    larger give the same actions and actor and a critic 100 times larger."""
    rng = np.random.default_rng(3)
    states = rng.uniform(-1, 1, size=(41, 2))
    rewards = -rng.uniform(0, 1, size=40)
    agents = []
    for factor in (1e3, 1e5):
        state, action = _spaces(n=2, m=1)
        agent = make_agent("s-ac", state, action, seed=5)
        assert agent.config.alpha_a is None
        _drive(agent, factor * rewards, states)
        agents.append(agent)
    small, large = agents
    assert large.reward_scale_ == pytest.approx(100 * small.reward_scale_)
    np.testing.assert_allclose(large.actor_, small.actor_, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(large.critic_, 100 * small.critic_, rtol=1e-9, atol=1e-12)


def test_s_ac_on_smaller_rewards_keeps_the_papers_actor_rate():
    """Rewards of a few units (a point mass's -x^2 on a box of +-2 m): the running scale is what was
    seen, the actor's rate the paper's 0.005, not 0.005 * 5 pi^2 / 4.4 = 0.056."""
    state, action = _spaces(n=2, m=1)
    agent = make_agent("s-ac", state, action, seed=5)
    _drive(agent, [-0.2, -4.4, -1.0], np.zeros((4, 2)))
    assert agent.reward_scale_ == 4.4 and agent.rate_a == 0.005 / 16


def _point_mass_trial(agent, x0, learn=True):
    """One 5 s trial of a 1 kg point mass pushed by a force in [-1, 1] N towards x = 0 from rest at
    x0 (0.05 s steps, position and speed clipped to +-2, r = -x^2 - 0.1 v^2); its return."""
    x, total = np.array([x0, 0.0]), 0.0
    u = agent.start(x) if learn else agent.greedy_action(x)
    for k in range(100):
        speed = np.clip(x[1] + 0.05 * np.clip(u[0], -1, 1), -2, 2)
        x = np.array([np.clip(x[0] + 0.05 * speed, -2, 2), speed])
        reward = -(x[0] ** 2) - 0.1 * x[1] ** 2
        total += reward
        if k == 99:
            if learn:
                agent.stop(reward, x)
            return total
        u = agent.step(reward, x) if learn else agent.greedy_action(x)


def test_s_ac_learns_a_point_mass_with_rewards_smaller_than_the_pendulums():
    """A user's 1-D point mass, nothing declared but its box and step: after 50 trials from random
    starts the greedy policy does better than standing still from six starts (mean over four
    seeds). With the actor's rate raised to 0.005 * 5 pi^2 / max |r| (up to 1 on the first, small
    rewards, then about 0.056) the actor outran its critic: it pushed the mass away from the goal,
    worse than standing still on every seed."""
    starts = (-0.9, -0.6, -0.3, 0.3, 0.6, 0.9)
    standing_still = sum(-100 * x0**2 for x0 in starts)
    state = StateSpace(
        low=-2 * np.ones(2), high=2 * np.ones(2), periodic=np.zeros(2, bool), timestep=0.05
    )
    greedy = []
    for seed in range(4):
        agent = make_agent("s-ac", state, ActionSpace(low=-np.ones(1), high=np.ones(1)), seed=seed)
        rng = np.random.default_rng(seed)
        for _ in range(50):
            _point_mass_trial(agent, rng.uniform(-1, 1))
        greedy.append(sum(_point_mass_trial(agent, x0, learn=False) for x0 in starts))
    assert np.mean(greedy) > 0.85 * standing_still, (greedy, standing_still)


def test_s_ac_running_scale_survives_a_restore():
    state, action = _spaces(n=2, m=1)
    agent = make_agent("s-ac", state, action, seed=5)
    _drive(agent, [-2.0, -7.0, -1.0], np.zeros((4, 2)))
    saved = agent.state_dict()
    assert float(saved["reward_scale"]) == 7.0
    other = make_agent("s-ac", state, action, seed=5)
    other.load_state_dict(saved)
    assert other.reward_scale_ == 7.0 and other.rate_a == agent.rate_a


def test_s_ac_with_dyna_planning_on_the_pendulum():
    state, action = _pendulum_spaces()
    agent = make_agent("s-ac-dyna", state, action, seed=0)
    c = agent.config
    assert (c.planning.steps, c.alpha_a, c.gamma, c.exploration.sigma) == (30, 0.002, 0.97, 1.0)
    assert agent.rehearsal is not None and agent.display_name == "S-AC + planning"


@pytest.mark.parametrize("interpolate", [False, True])
def test_an_interpolating_model_never_predicts_a_reward_beyond_the_real_ones(interpolate):
    from rmac_mj.agents import Planning
    from rmac_mj.agents.planning import TransitionModel  # the model itself, not on the face

    state, action = _spaces(n=1, m=1)
    model = TransitionModel(
        Planning(steps=1, interpolate=interpolate, model_capacity=50, model_neighbours=5),
        state,
        action,
    )
    for x in np.linspace(-0.5, 0.5, 11):
        model.observe(np.array([x]), np.array([0.0]), -1.0 + x, np.array([x]))
    _, r = model.predict(np.array([0.9]), np.array([0.9]))
    assert (r <= -0.5 + 1e-9) == interpolate  # an affine fit extrapolates to about -0.1
