"""MPC (rmac_mj.agents.mpc) and its sampling planner: a population scored in one compiled call is
the one-by-one reference; the critic is the terminal value; the model's uncertainty stops rollouts
and, in learning trials, draws them into the unknown."""

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.agents import _planner_kernels as kernels
from rmac_mj.agents import make_agent
from rmac_mj.agents.sampling_planner import SamplingPlanner, score_population_numpy
from rmac_mj.rollout import action_space_of, run_trial, state_space_of


@pytest.fixture(scope="module")
def learned():
    """MPC after 4 trials of the paper's pendulum: a model of 400 real transitions, a critic."""
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent("recommended", state_space_of(env), action_space_of(env), seed=5)
    for _ in range(4):
        run_trial(env, agent)
    return agent


def _score(
    agent,
    x0,
    sequences,
    policy_rows=0,
    trust=0.0,
    bonus=0.0,
    search="tree",
    critic=None,
    potential=0.0,
    visits=None,
):
    fits = agent.fits
    fits.refresh()
    scores = np.empty(len(sequences))
    kernels.score_population(
        fits.memory.kernel_state,
        fits.kernel_arrays,
        agent._box,
        agent.critic_ if critic is None else critic,
        agent.actor_,
        agent._coder,
        (agent.action_space.low, agent.action_space.high),
        x0,
        sequences,
        policy_rows,
        agent.config.gamma,
        trust,
        bonus,
        potential,
        np.zeros(0) if visits is None else visits,
        fits.tree if search == "tree" else (),
        scores,
    )
    return scores


def _reference(agent, x0, sequences, policy_rows=0, trust=0.0, bonus=0.0):
    from rmac_mj.approximators.local_fits import LocalFits

    return score_population_numpy(
        x0,
        sequences,
        LocalFits(agent.fits.memory, backend="numpy"),
        agent._box,
        agent.value,
        lambda x: agent._policy(agent.coder.active_tiles(x)),
        policy_rows,
        agent.config.gamma,
        trust,
        bonus,
    )


def _sequences(agent, count, horizon, seed=0):
    rng = np.random.default_rng(seed)
    low, high = agent.action_space.low, agent.action_space.high
    return rng.uniform(low, high, size=(count, horizon, low.shape[0]))


@pytest.mark.parametrize("trust, bonus", [(0.0, 0.0), (1.5, 0.0), (1.5, 2.0)])
def test_the_batched_scores_are_the_one_by_one_reference(learned, trust, bonus):
    x0 = np.array([np.pi - 0.3, 1.0])
    sequences = _sequences(learned, 12, 8)
    batched = sequences.copy()
    got = _score(learned, x0, batched, policy_rows=2, trust=trust, bonus=bonus)
    one_by_one = sequences.copy()
    want = _reference(learned, x0, one_by_one, policy_rows=2, trust=trust, bonus=bonus)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(batched, one_by_one)  # the actor's rows written back alike
    np.testing.assert_array_equal(
        got, _score(learned, x0, sequences.copy(), 2, trust, bonus, "scan")
    )


def test_the_critic_is_the_terminal_value(learned):
    """A constant critic c adds gamma^H c to every full-length rollout's score."""
    x0 = np.array([np.pi, 0.0])
    sequences = _sequences(learned, 6, 5)
    zero = _score(learned, x0, sequences.copy(), critic=np.zeros_like(learned.critic_))
    c, T = 7.0, learned.coder.num_tilings
    shifted = _score(learned, x0, sequences.copy(), critic=np.full_like(learned.critic_, c / T))
    np.testing.assert_allclose(shifted - zero, learned.config.gamma**5 * c, rtol=1e-9)


def test_an_untrusted_rollout_stops_and_takes_the_value_where_it_was_trusted(learned):
    """Actions far outside what was ever applied (the model's u never left [-3, 3], here it is
    asked at the bounds from a state never visited) end a trusting rollout after its first step."""
    x0 = np.array([0.0, 40.0])  # upright at 40 rad/s: far from every sample
    sequences = np.full((1, 6, 1), 3.0)
    trusted = _score(learned, x0, sequences.copy(), trust=1e-6)
    free = _score(learned, x0, sequences.copy(), trust=0.0)
    one_step = _score(learned, x0, sequences[:, :1].copy(), trust=0.0)
    assert trusted[0] == pytest.approx(one_step[0]) and trusted[0] != pytest.approx(free[0])


def test_optimism_rewards_the_unknown_in_learning_trials_only(learned):
    x0 = np.array([np.pi, 0.0])
    sequences = _sequences(learned, 8, 6, seed=1)
    plain = _score(learned, x0, sequences.copy(), trust=5.0)
    hopeful = _score(learned, x0, sequences.copy(), trust=5.0, bonus=1.0)
    assert np.all(hopeful >= plain) and np.any(hopeful > plain)


def test_greedy_trials_neither_learn_nor_draw_from_the_learners_stream(learned):
    env = tasks.load("dc_pendulum", "swingup")
    before = {k: v.copy() for k, v in learned.state_dict().items()}
    first, second = run_trial(env, learned, learn=False), run_trial(env, learned, learn=False)
    assert first == second
    for key, value in learned.state_dict().items():
        np.testing.assert_array_equal(value, before[key], err_msg=key)


def test_the_planner_settings_refuse_what_cannot_run():
    with pytest.raises(ValueError, match="elites"):
        SamplingPlanner(population=8, elites=9)
    with pytest.raises(ValueError, match="horizon"):
        SamplingPlanner(horizon=0.0)
    assert SamplingPlanner(horizon=0.5).steps(0.03) == 17 and SamplingPlanner().steps(2.0) == 1


@pytest.mark.slow
def test_mpc_swings_the_pendulum_up_within_five_trials():
    """The paper's pendulum: greedy after 5 learning trials (500 real steps) swings up and holds,
    far above hanging still (-3600 .. -4500)."""
    env = tasks.load("dc_pendulum", "swingup")
    agent = make_agent("recommended", state_space_of(env), action_space_of(env), seed=1)
    for _ in range(5):
        run_trial(env, agent)
    assert run_trial(env, agent, learn=False) > -1100


def _optimistic_agents(trials):
    """The same MPC without and with ``unknown_value`` after ``trials`` trials of the paper's
    pendulum."""
    agents = []
    for value in (0.0, 1.0):
        env = tasks.load("dc_pendulum", "swingup")
        spaces = state_space_of(env), action_space_of(env)
        agent = make_agent("recommended", *spaces, config={"unknown_value": value}, seed=3)
        for _ in range(trials):
            run_trial(env, agent)
        agents.append(agent)
    return agents


def test_the_unknown_is_valued_optimistically_until_visited():
    """Phi is the full R-MAX value, unknown_value x scale / (1 - gamma), on a state no real step
    visited, less where the learner has been, and vanishes as 1 / sqrt(1 + visits); the planner
    adds it to the terminal value (gamma^H Phi(x_H))."""
    plain, hopeful = _optimistic_agents(trials=2)
    far = np.array([0.3, 25.0])  # near upright and fast: never visited
    full = hopeful.potential_scale()
    scale = hopeful.reward_scale_ or hopeful.state_space.reward_scale
    assert full == pytest.approx(scale / (1 - hopeful.config.gamma))
    assert hopeful.potential(far) == pytest.approx(full)
    assert hopeful.potential(np.array([np.pi, 0.0])) < 0.5 * full  # the start: visited each trial
    assert plain.potential(far) == 0.0
    sequences = _sequences(hopeful, 4, 3, seed=2)
    plain_scores = _score(hopeful, far, sequences.copy())
    for visits, novelty in ((0.0, 1.0), (3.0, 0.5)):  # every tile visited alike: Phi known
        counts = np.full_like(hopeful.visits_, visits)
        scores = _score(hopeful, far, sequences.copy(), potential=full, visits=counts)
        gain = hopeful.config.gamma**3 * full * novelty
        np.testing.assert_allclose(scores - plain_scores, gain, rtol=1e-9)
    tiles = hopeful.coder.active_tiles(far)
    hopeful.visits_[tiles] += 10_000
    assert hopeful.potential(far) == pytest.approx(full / np.sqrt(10_001))


def test_the_critic_learns_from_rewards_shaped_by_the_potential():
    """A simulated transition x -> x' is learned with r + gamma Phi(x') - Phi(x): its TD error is
    larger by that much than S-AC's on the same critic, and a real one counts the visit of x'
    (kept in the state; without optimism nothing is counted)."""
    plain, hopeful = _optimistic_agents(trials=2)
    assert plain.visits_ is None and "visits" not in plain.state_dict()
    x, x_next = np.array([np.pi, 0.0]), np.array([0.3, 25.0])
    shaping = hopeful.config.gamma * hopeful.potential(x_next) - hopeful.potential(x)
    deltas = []
    for agent in (plain, hopeful):
        agent.critic_[:] = 0.0  # a like-for-like TD error: V = 0 on both
        agent._set_rehearsing(True)
        agent._start(x)
        agent._step(-1.0, x_next)
        agent._set_rehearsing(False)
        deltas.append(agent.last_delta_)
    assert deltas[1] - deltas[0] == pytest.approx(shaping)
    tiles = hopeful.coder.active_tiles(x_next)
    before = hopeful.visits_[tiles].copy()
    hopeful._start(x)
    hopeful._step(-1.0, x_next)
    np.testing.assert_array_equal(hopeful.visits_[tiles], before + 1)
    np.testing.assert_array_equal(hopeful.state_dict()["visits"], hopeful.visits_)


# -- optimism decided by the learner's own data (sparse_unknown_value, on by default) ---------------
def _toy_agent(config=None, reward_scale=None, seed=4, cost=0.1):
    """MPC on a small task of its own: a car on a line (position, velocity), a push u in [-1, 1]
    whose declared cost is ``cost`` u^2 (MountainCar's protocol: 0.1; dm-control's: 0)."""
    from rmac_mj.agents import ActionSpace, StateSpace

    states = StateSpace(
        low=[-1.2, -0.07],
        high=[0.6, 0.07],
        periodic=[False, False],
        timestep=0.05,
        reward_scale=reward_scale,
    )
    actions = ActionSpace(low=[-1.0], high=[1.0], cost=[cost])
    return make_agent("recommended", states, actions, config=config, seed=seed)


def _drive(agent, steps, reward_of, trials=1):
    """``trials`` trials of ``steps`` real steps of the toy car; the reward of each step is
    ``reward_of(x_next, u)`` with u as the environment saw it (float32, as Gymnasium's)."""
    for _ in range(trials):
        x = np.array([-0.5, 0.0])
        u = agent.start(x)
        for k in range(steps):
            u32 = float(np.float32(u[0]))
            v = float(np.clip(x[1] + 0.0015 * u32 - 0.0025 * np.cos(3 * x[0]), -0.07, 0.07))
            x = np.array([float(np.clip(x[0] + v, -1.2, 0.6)), v])
            r = reward_of(x, u32)
            if k == steps - 1:
                agent.stop(r, x)
            else:
                u = agent.step(r, x)
    return agent


def _action_cost_only(x, u):
    return -(u**2) * 0.1


def test_the_unknown_is_optimistic_while_every_reward_is_the_action_cost():
    """Rewards that are only the declared action cost (MountainCar before its flag) tell nothing:
    from the second one the unknown is worth the largest push's cost plus sparse_unknown_value x
    one reward unit, per step, / (1 - gamma); 0 switches it off."""
    agent = _toy_agent()
    assert not agent.optimistic()
    agent.start(np.array([-0.5, 0.0]))
    agent.step(
        _action_cost_only(None, float(np.float32(agent._prev_u[0]))), np.array([-0.5, 0.001])
    )
    assert not agent.optimistic() and agent.sparse_rewards_ == 1  # one reward: nothing decided
    agent = _drive(_toy_agent(), 60, _action_cost_only)
    assert agent.optimistic() and agent.sparse_rewards_ == 60
    assert agent.sparse_reward_ == pytest.approx(0.0, abs=1e-9)  # u rounded to float32 by the env
    full = (0.1 + 0.1) / (1 - agent.config.gamma)
    assert agent.potential_scale() == pytest.approx(full)
    assert agent.potential(np.array([0.5, 0.06])) == pytest.approx(full)  # never visited
    assert agent.potential(np.array([-0.5, 0.0])) < 0.5 * full  # the start
    state = agent.state_dict()
    for key in ("visits", "sparse_reward", "sparse_rewards", "prev_u"):
        assert key in state
    off = _drive(_toy_agent({"sparse_unknown_value": 0.0}), 60, _action_cost_only)
    assert not off.optimistic() and off.visits_ is None and off.potential_scale() == 0.0


def test_the_scale_of_a_sparse_reward_is_the_largest_push_plus_a_declared_scale_else_one_unit():
    """All rewards 0 (dm-control's pendulum/swingup before the top, no action cost) or only action
    costs (MountainCar) give one rule: Phi of the unknown is (the largest action's declared cost +
    sparse_unknown_value x the task's declared reward scale, else one reward unit) / (1 - gamma)."""
    zero = _drive(_toy_agent(cost=0.0), 30, lambda x, u: 0.0)
    costs = _drive(_toy_agent(), 30, _action_cost_only)
    declared = _drive(_toy_agent(reward_scale=4.0), 30, _action_cost_only)
    halved = _drive(_toy_agent({"sparse_unknown_value": 0.05}), 30, _action_cost_only)
    gamma = zero.config.gamma
    assert zero.potential_scale() == pytest.approx(0.1 / (1 - gamma))
    assert costs.potential_scale() == pytest.approx((0.1 + 0.1) / (1 - gamma))
    assert declared.potential_scale() == pytest.approx((0.1 + 0.4) / (1 - gamma))
    assert halved.potential_scale() == pytest.approx((0.1 + 0.05) / (1 - gamma))
    # Zero rewards where the task declares an action cost are a state-dependent residual: dense.
    assert not _drive(_toy_agent(), 30, lambda x, u: 0.0).optimistic()


def test_a_state_dependent_reward_after_a_sparse_start_keeps_the_potential_as_it_was():
    """The flag (a reward of 100) ends the watch; the potential stays on with the scale it had
    (not the new reward's), fading with visits as before."""
    agent = _drive(_toy_agent(), 40, _action_cost_only)
    scale = agent.potential_scale()
    _drive(agent, 20, lambda x, u: 100.0 if x[1] > 0.0 else _action_cost_only(x, u))
    assert agent.sparse_reward_ is None and agent.optimistic()
    assert agent.potential_scale() == scale and agent.reward_scale_ == 100.0
    assert "sparse_reward" not in agent.state_dict() and "visits" in agent.state_dict()


def test_a_dense_reward_leaves_mpc_bit_for_bit_as_without_the_option():
    """On the paper's pendulum the second reward already differs from the first: the optimism is
    never on, nothing is counted, and the learner (state, keys, greedy return) is bit for bit MPC
    with sparse_unknown_value=0."""
    runs = []
    for config in (None, {"sparse_unknown_value": 0.0}):
        env = tasks.load("dc_pendulum", "swingup")
        agent = make_agent("recommended", state_space_of(env), action_space_of(env), config, seed=6)
        for _ in range(3):
            run_trial(env, agent)
        runs.append((agent, run_trial(env, agent, learn=False)))
    (auto, auto_return), (plain, plain_return) = runs
    assert auto.sparse_reward_ is None and auto.visits_ is None and not auto.optimistic()
    assert auto_return == plain_return
    a, b = auto.state_dict(), plain.state_dict()
    assert a.keys() == b.keys()
    for key in a:
        assert a[key].tobytes() == b[key].tobytes(), key


def test_the_watch_of_a_sparse_reward_is_carried_by_the_state():
    """A learner restored mid-watch acts and decides as the original; a state without the watch
    (a dense learner's, or one written before it existed) restores a learner never optimistic."""
    agent = _drive(_toy_agent(), 30, _action_cost_only)
    twin = _toy_agent(seed=99)
    twin.load_state_dict(agent.state_dict())
    for learner in (agent, twin):
        _drive(learner, 10, lambda x, u: 1.0 if x[0] > -0.49 else _action_cost_only(x, u))
    a, b = agent.state_dict(), twin.state_dict()
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    dense = _toy_agent()
    state = {k: v for k, v in agent.state_dict().items() if k not in agent._OPTIMISM_KEYS}
    dense.load_state_dict(state)
    assert not dense.optimistic() and dense.visits_ is None and dense.sparse_reward_ is None
    broken = dict(agent.state_dict(), sparse_rewards=np.array(-1))
    with pytest.raises(ValueError, match="sparse_rewards"):
        _toy_agent().load_state_dict(broken)
