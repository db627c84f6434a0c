"""What every learner shares: construction, validation and the registry."""

import dataclasses

import numpy as np
import pytest
from learners import quick_config

from rmac_mj.agents import ALGORITHMS, ActionSpace, Exploration, StateSpace, config_class, make_agent

BACKENDS = ("numba", "numpy")

STATES = StateSpace(low=[-np.pi, -25.0], high=[np.pi, 25.0], periodic=[True, False])
ACTIONS = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])


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
    # gamma overridden, every other default (the paper's, or SB3's for the baselines) kept
    default = make_agent(algorithm, STATES, ACTIONS, seed=0)
    assert agent.config == dataclasses.replace(default.config, gamma=0.9) != default.config
    assert agent.name == algorithm
    with pytest.raises(ValueError, match=r"has no parameter 'gama' \(did you mean 'gamma'\?\)"):
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


# -- the shared boundary and a whole state, for every registered learner ---------------------------

def _pendulum_env():
    from rmac_mj import tasks
    return tasks.load("dc_pendulum", "swingup")


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("reward", [float("nan"), float("inf"), -float("inf"), "ten", None])
def test_bad_rewards_are_refused_by_name(algorithm, reward):
    agent = make_agent(algorithm, STATES, ACTIONS, seed=0)
    agent.start([np.pi, 0.0])
    before = {k: v.copy() for k, v in agent.state_dict().items()}
    for method in (agent.step, agent.stop):
        with pytest.raises(ValueError, match="reward"):
            method(reward, [np.pi, 0.0])
    after = agent.state_dict()
    for key in before:  # nothing was learned from the refused call
        np.testing.assert_array_equal(before[key], after[key], err_msg=key)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_bad_states_are_refused_by_name(algorithm):
    agent = make_agent(algorithm, STATES, ACTIONS, seed=0)
    with pytest.raises(ValueError, match="x0 must be finite"):
        agent.start([np.nan, 0.0])
    with pytest.raises(ValueError, match=r"x0 must have shape \(2,\)"):
        agent.start([0.0, 0.0, 0.0])
    agent.start([np.pi, 0.0])
    with pytest.raises(ValueError, match="x must be finite"):
        agent.step(-1.0, [0.0, np.inf])
    with pytest.raises(ValueError, match="x must be finite"):
        agent.greedy_action([np.nan, 0.0])
    with pytest.raises(ValueError, match="x must be finite"):
        agent.value([np.nan, 0.0])


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_step_or_stop_outside_a_trial_is_refused(algorithm):
    agent = make_agent(algorithm, STATES, ACTIONS, seed=0)
    for method in (agent.step, agent.stop):
        with pytest.raises(RuntimeError, match="start"):
            method(-1.0, [np.pi, 0.0])
    agent.start([np.pi, 0.0])
    agent.step(-1.0, [np.pi, 0.1])
    agent.stop(-1.0, [np.pi, 0.2])
    with pytest.raises(RuntimeError, match="start"):  # stop ended the trial
        agent.step(-1.0, [np.pi, 0.0])


def _state(timestep):
    return np.r_[timestep.observation["angle"], timestep.observation["velocity"]]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_copy_restored_mid_trial_continues_exactly_like_the_original(algorithm):
    """state_dict holds everything that decides what the agent does next: memories, weights, traces,
    the trial's bookkeeping and the random generator."""
    from rmac_mj.experiments.episode import action_space_of, run_trial, state_space_of

    env = _pendulum_env()
    S, U = state_space_of(env), action_space_of(env)
    original = make_agent(algorithm, S, U, config=quick_config(algorithm),
                          seed=np.random.default_rng(4))
    for _ in range(3):
        run_trial(env, original)
    # Stop in the middle of a trial (step 37 of 100), after exploring steps have drawn from the rng.
    timestep = env.reset()
    u = original.start(_state(timestep))
    for _ in range(37):
        timestep = env.step(u)
        u = original.step(timestep.reward, _state(timestep))
    # another seed: the rng must come from the state
    copy = make_agent(algorithm, S, U, config=quick_config(algorithm), seed=12345)
    copy.load_state_dict(original.state_dict())
    # The rest of the trial, fed the same observations, gives the same actions, bit for bit.
    for _ in range(62):
        timestep = env.step(u)
        u = original.step(timestep.reward, _state(timestep))
        assert np.array_equal(copy.step(timestep.reward, _state(timestep)), u)
    timestep = env.step(u)
    assert timestep.last()
    original.stop(timestep.reward, _state(timestep))
    copy.stop(timestep.reward, _state(timestep))
    # Whole learning trials afterwards are identical too, and so is everything learned.
    assert [run_trial(env, original) for _ in range(2)] == [run_trial(env, copy) for _ in range(2)]
    a, b = original.state_dict(), copy.state_dict()
    assert sorted(a) == sorted(b)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_state_dict_is_numeric_and_refuses_foreign_state(algorithm):
    agent = make_agent(algorithm, STATES, ACTIONS, seed=0)
    agent.start([np.pi, 0.0])
    state = agent.state_dict()
    assert all(isinstance(v, np.ndarray) and v.dtype.kind in "fiub" for v in state.values())
    assert state["rng"].dtype == np.uint64 and state["in_trial"]
    with pytest.raises(ValueError, match="rng"):
        agent.load_state_dict({k: v for k, v in state.items() if k != "rng"})


@pytest.mark.parametrize("learner", ["rmac", "mlac"])
@pytest.mark.parametrize("backend", BACKENDS)
def test_learn_is_the_update_of_a_control_step(learner, backend):
    """``learn(x, u, r, x')`` is what a control step learns (Algorithm 2 lines 13-28; MLAC's steps
    1-3): a step acts, then learns its transition with V_{k-1}. ``model=False`` (a simulated
    transition) leaves the process model as it was and learns the rest."""
    rng = np.random.default_rng(0)
    A, B, c = np.eye(2) + 0.1 * rng.normal(size=(2, 2)), rng.normal(size=(2, 1)), 0.1 * rng.normal(size=2)
    S = StateSpace(low=-10 * np.ones(2), high=10 * np.ones(2), periodic=np.zeros(2, bool))
    U = ActionSpace(low=-3.0 * np.ones(1), high=3.0 * np.ones(1), cost=np.ones(1))
    small = (dict(critic_capacity=30, reference_capacity=25, process_capacity=12,
                  critic_neighbours=5, reference_neighbours=4, process_neighbours=4)
             if learner == "rmac" else
             dict(critic_capacity=30, actor_capacity=25, process_capacity=12, critic_neighbours=5,
                  actor_neighbours=4, process_neighbours=4))
    agent = make_agent(learner, S, U, config=dict(backend=backend, **small), seed=1)
    rng = np.random.default_rng(2)
    for _ in range(3):  # fill (and overfill) the memories
        x = rng.uniform(-1, 1, 2)
        u = agent.start(x)
        for _ in range(15):
            x = A @ x + B @ u + c
            u = agent.step(-float(x @ x), x)
        agent.stop(-float(x @ x), A @ x + B @ u + c)
    x0 = rng.uniform(-1, 1, 2)
    u0 = agent.start(x0)
    before = agent.state_dict()
    x1 = A @ x0 + B @ u0 + c
    agent.step(-1.5, x1)  # acts in x1, learns (x0, u0, -1.5, x1) with V_0
    stepped = agent.state_dict()

    twin = make_agent(learner, S, U, config=dict(backend=backend, **small), seed=1)
    twin.load_state_dict(before)
    v1 = twin.learn(x0, u0, -1.5, x1, v=float(before["v_prev"]))
    assert v1 == float(stepped["v_prev"])  # V(x1), as the step's V_k
    learned = twin.state_dict()
    memories = [key for key in before if key.split(".")[0] in ("process", "reference", "critic",
                                                                 "actor")]
    for key in memories + ["traces"]:
        np.testing.assert_array_equal(learned[key], stepped[key], err_msg=key)
    assert not np.array_equal(learned["critic.Y"], before["critic.Y"])
    for key in ("k", "x_prev", "u_prev", "v_prev", "rng"):  # the step's bookkeeping left alone
        np.testing.assert_array_equal(learned[key], before[key], err_msg=key)

    twin.load_state_dict(before)
    twin.learn(x0, u0, -1.5, x1, model=False)  # V(x0): the critic's estimate now, V_0 itself
    simulated = twin.state_dict()
    for key in [k for k in memories if k.startswith("process.")]:
        np.testing.assert_array_equal(simulated[key], before[key], err_msg=key)
    assert not np.array_equal(simulated["critic.Y"], before["critic.Y"])
    for bad in (dict(x=[np.nan, 0.0]), dict(u=[0.0, 1.0]), dict(reward=np.inf)):
        args = dict(x=x0, u=u0, reward=-1.5, x_next=x1) | bad
        with pytest.raises(ValueError):
            twin.learn(**args)
