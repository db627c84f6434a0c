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
