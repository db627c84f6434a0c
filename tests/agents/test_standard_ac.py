"""S-AC (Algorithm 1): hand-worked TD and trace updates, actor direction, back ends, learning."""

import numpy as np
import pytest

from rmac_mj.agents import (
    ActionSpace,
    Exploration,
    StandardACConfig,
    StandardActorCritic,
    StateSpace,
)
from rmac_mj.agents.task_knowledge import PAPER_REWARD_SCALE
from rmac_mj.approximators import TileCodingConfig

#: The pendulum's box; its reward scale, as dc_pendulum declares it, keeps alpha_a at the paper's.
PENDULUM = StateSpace(
    low=[-np.pi, -60.0], high=[np.pi, 60.0], periodic=[True, False], reward_scale=PAPER_REWARD_SCALE
)
VOLTS = ActionSpace(low=[-3.0], high=[3.0])
LINE = StateSpace(low=[0.0], high=[1.0], periodic=[False])
NO_EXPLORATION = Exploration(sigma=0.0)


def line_agent(backend="numba", **kwargs):
    """1-D state in [0, 1], one tiling of 2 tiles: x = 0.25 is tile 0, x = 0.75 is tile 1."""
    config = dict(
        gamma=0.9,
        lam=0.5,
        alpha_c=0.5,
        alpha_a=0.1,
        rate_split="none",
        tile_coding=TileCodingConfig(num_tilings=1, tiles=2),
        exploration=NO_EXPLORATION,
        backend=backend,
    )
    config.update(kwargs)
    return StandardActorCritic(LINE, VOLTS, StandardACConfig(**config), seed=0)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_two_step_td_with_traces(backend):
    agent = line_agent(backend)
    agent.start([0.25])
    # delta_1 = -1 + 0.9 * V(0.75) - V(0.25) = -1; the trace of x_0 (tile 0) is 1, so only tile 0
    # moves. Setting the trace of x_1 instead (Algorithm 1 line 11 as printed) would move tile 1.
    agent.step(-1.0, [0.75])
    np.testing.assert_allclose(agent.critic_[:2], [-0.5, 0.0])
    # delta_2 = -2 + 0.9 * (-0.5) - 0 = -2.45; traces: tile 0 decayed to 0.9 * 0.5 = 0.45, tile 1 = 1.
    agent.step(-2.0, [0.25])
    np.testing.assert_allclose(agent.critic_[:2], [-0.5 - 0.5 * 2.45 * 0.45, -0.5 * 2.45])
    assert agent.last_delta_ == pytest.approx(-2.45)
    # stop bootstraps from V(x_K): delta_3 = -1 + 0.9 * V(0.75) - V(0.25); tile 0 replaced to 1.
    theta = agent.critic_[:2].copy()
    delta3 = -1.0 + 0.9 * theta[1] - theta[0]
    agent.stop(-1.0, [0.75])
    np.testing.assert_allclose(
        agent.critic_[:2], [theta[0] + 0.5 * delta3, theta[1] + 0.5 * delta3 * 0.45]
    )
    np.testing.assert_array_equal(agent.actor_, 0.0)  # no exploration, no actor update


def test_traces_reset_each_trial():
    agent = line_agent()
    agent.start([0.25])
    agent.step(-1.0, [0.75])
    agent.stop(-1.0, [0.75])
    before = agent.critic_[:2].copy()
    agent.start([0.75])  # a new trial: the old trace of tile 0 must be gone
    agent.step(-1.0, [0.75])
    assert agent.critic_[0] == before[0]


@pytest.mark.parametrize("rate_split, v_change", [("both", -0.1), ("actor", -1.6), ("none", -1.6)])
def test_rate_split(rate_split, v_change):
    config = StandardACConfig(rate_split=rate_split, exploration=NO_EXPLORATION)
    agent = StandardActorCritic(PENDULUM, VOLTS, config, seed=0)
    x0 = np.array([np.pi, 0.0])
    agent.start(x0)
    agent.step(-1.0, [0.0, 30.0])  # delta = -1; 16 active weights each move by alpha(_c / 16)
    assert agent.value(x0) == pytest.approx(v_change)
    assert agent.rate_a == pytest.approx(0.005 / 16 if rate_split != "none" else 0.005)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("reward, toward", [(10.0, True), (-10.0, False)])
def test_actor_follows_rewarded_perturbation(backend, reward, toward):
    config = StandardACConfig(exploration=Exploration(sigma=1.0), backend=backend)
    agent = StandardActorCritic(PENDULUM, VOLTS, config, seed=3)
    x0 = np.array([np.pi, 0.0])
    u0 = agent.start(x0)  # step 0 explores; pi(x0) = 0, so u0 is the perturbation
    assert u0[0] != 0.0
    agent.step(reward, [np.pi - 0.1, 1.0])
    delta = agent.last_delta_
    assert (delta > 0) == (reward > 0)
    moved = agent.greedy_action(x0)[0]
    assert np.sign(moved) == (np.sign(u0[0]) if toward else -np.sign(u0[0]))
    # eq. 4 with the rate split over the 16 tilings: pi(x0) moves by alpha_a delta Delta u_0.
    assert moved == pytest.approx(0.005 * delta * u0[0])


def test_actor_output_stays_within_bounds():
    config = StandardACConfig(alpha_a=1.0, rate_split="none", exploration=Exploration(sigma=1.0))
    agent = StandardActorCritic(PENDULUM, VOLTS, config, seed=3)
    x0 = np.array([np.pi, 0.0])
    u0 = agent.start(x0)
    agent.step(1e3, [np.pi, 0.0])  # a huge positive delta pushes pi(x0) far past the bound
    raw = agent.actor_[agent.coder.active_tiles(x0)].sum()
    assert raw == pytest.approx(3.0 * np.sign(u0[0]))


def test_saturated_exploration_is_not_credited():
    """With pi(x0) on the upper bound, noise pointing up is cut off and must not move the actor."""
    x0 = np.array([np.pi, 0.0])
    for seed in range(6):
        draw = np.random.default_rng(seed).normal(0.0, 1.0, size=1)[0]  # the agent's first Delta u
        agent = StandardActorCritic(
            PENDULUM, VOLTS, StandardACConfig(exploration=Exploration(sigma=1.0)), seed=seed
        )
        state = agent.state_dict()
        state["actor"][agent.coder.active_tiles(x0)] = 3.0 / 16
        agent.load_state_dict(state)
        u0 = agent.start(x0)
        assert u0[0] == pytest.approx(min(3.0, 3.0 + draw))
        agent.step(10.0, [np.pi, 0.0])
        moved = agent.actor_[agent.coder.active_tiles(x0)].sum() - 3.0
        if draw > 0:
            assert moved == 0.0
        else:  # tried lower with a positive delta: pi(x0) moves down by alpha_a delta Delta u
            assert moved == pytest.approx(0.005 * agent.last_delta_ * draw)


def test_backends_agree_and_seed_reproduces():
    rng = np.random.default_rng(5)
    xs = rng.uniform([-4, -70], [4, 70], size=(300, 2))
    rs = rng.normal(-20, 10, size=300)

    def run(backend, seed):
        agent = StandardActorCritic(PENDULUM, VOLTS, StandardACConfig(backend=backend), seed=seed)
        us = [agent.start(xs[0])]
        for k in range(1, 300):
            if k % 100 == 0:
                agent.stop(rs[k], xs[k])
                us.append(agent.start(xs[k]))
            else:
                us.append(agent.step(rs[k], xs[k]))
        return np.array(us), agent

    u_fast, fast = run("numba", 7)
    u_ref, ref = run("numpy", 7)
    np.testing.assert_allclose(u_fast, u_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.critic_, ref.critic_, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.actor_, ref.actor_, rtol=1e-9, atol=1e-12)
    assert np.any(fast.actor_ != 0) and np.any(fast.critic_ != 0)
    u_again, _ = run("numba", 7)
    np.testing.assert_array_equal(u_again, u_fast)
    u_other, _ = run("numba", 8)
    assert not np.array_equal(u_other, u_fast)


def test_state_dict_round_trip():
    agent = StandardActorCritic(PENDULUM, VOLTS, seed=0)
    agent.start([np.pi, 0.0])
    for k in range(30):
        agent.step(-5.0, [np.pi - 0.05 * k, 0.5 * k])
    state = agent.state_dict()
    assert all(isinstance(v, np.ndarray) and v.dtype.kind in "fiub" for v in state.values())
    clone = StandardActorCritic(PENDULUM, VOLTS, seed=1)
    clone.load_state_dict(state)
    for x in ([np.pi, 0.0], [1.0, 5.0], [-0.5, -3.0]):
        assert clone.value(x) == agent.value(x)
        np.testing.assert_array_equal(clone.greedy_action(x), agent.greedy_action(x))
    with pytest.raises(ValueError, match="state 'actor' must have shape"):
        clone.load_state_dict({**state, "actor": state["actor"][:-1]})
    with pytest.raises(ValueError, match="lacks 'in_trial', 'k'"):
        clone.load_state_dict({"critic": state["critic"], "actor": state["actor"]})


def test_generic_dimensions():
    """Three state dimensions (one periodic) and two actions: every dimension is coded and learned."""
    space = StateSpace(
        low=[-np.pi, -1.0, 0.0], high=[np.pi, 1.0, 2.0], periodic=[True, False, False]
    )
    actions = ActionSpace(low=[-1.0, 0.0], high=[1.0, 5.0])
    config = StandardACConfig(tile_coding=TileCodingConfig(num_tilings=8, tiles=4))
    agent = StandardActorCritic(space, actions, config, seed=0)
    rng = np.random.default_rng(0)  # one stream: every step sees a new state
    states = rng.uniform([-4, -1.5, -0.5], [4, 1.5, 2.5], size=(60, 3))
    u = agent.start(states[0])
    for x in states[1:]:
        u = agent.step(float(rng.normal(0.0, 5.0)), x)  # TD errors of both signs
        assert u.shape == (2,) and np.all(u >= actions.low) and np.all(u <= actions.high)
    assert agent.actor_.shape == (agent.coder.num_features, 2)
    assert np.any(agent.actor_[:, 0] != 0) and np.any(agent.actor_[:, 1] != 0)  # both actions learn
    tiles = {tuple(agent.coder.active_tiles(x)) for x in states}
    assert len(tiles) == len(states)  # distinct states, distinct features
    # Each dimension matters: moving one coordinate alone changes the active tiles.
    base = np.array([0.1, 0.1, 1.0])
    for d, delta in enumerate((1.0, 0.6, 0.6)):
        moved = base.copy()
        moved[d] += delta
        assert tuple(agent.coder.active_tiles(moved)) != tuple(agent.coder.active_tiles(base)), d


@pytest.mark.parametrize(
    "field, value",
    [
        ("gamma", 1.0),
        ("gamma", -0.1),
        ("lam", 1.5),
        ("alpha_a", -0.01),
        ("alpha_c", 2.0),
        ("alpha_c", float("nan")),
        ("rate_split", "half"),
        ("trace_cutoff", 1.0),
        ("backend", "cuda"),
        ("tile_low", [0.0, "1"]),
        ("tile_high", (0.0, float("inf"))),
        ("exploration", 1.0),
        ("tile_coding", 16),
    ],
)
def test_config_validation(field, value):
    with pytest.raises(ValueError, match=f"StandardACConfig.{field}"):
        StandardACConfig(**{field: value})


def test_boundary_errors_and_config_round_trip():
    with pytest.raises(ValueError, match="tile_high"):
        StandardActorCritic(PENDULUM, VOLTS, StandardACConfig(tile_high=(1.0,)))
    from rmac_mj.agents import config_from_dict

    config = StandardACConfig(
        alpha_c=0.2,
        rate_split="actor",
        tile_high=(None, 30.0),
        exploration=Exploration(sigma=0.5, period=2),
        tile_coding=TileCodingConfig(num_tilings=8, tiles=5),
    )
    agent = StandardActorCritic(PENDULUM, VOLTS, config, seed=0)
    # The JSON form of the config (what results and snapshots store) rebuilds the same config.
    assert config_from_dict(StandardACConfig, agent.config_dict()) == agent.config


@pytest.mark.slow
def test_improves_on_swingup():
    """A short run (150 trials, ~2 s): S-AC leaves the hanging-down return (about -4900) behind."""
    from rmac_mj import tasks
    from rmac_mj.rollout import action_space_of, run_trial, state_space_of

    env = tasks.load("dc_pendulum", "swingup", task_kwargs={"random": 0})
    agent = StandardActorCritic(
        state_space_of(env), action_space_of(env), seed=np.random.default_rng(11)
    )
    untrained = run_trial(env, agent, learn=False)
    returns = [run_trial(env, agent) for _ in range(150)]
    assert np.mean(returns[-20:]) > untrained + 1000.0, (untrained, np.mean(returns[-20:]))
