"""What every learner shares: construction, validation and the registry."""

import dataclasses
import re
import subprocess
import sys

import numpy as np
import pytest
from learners import quick_config

from rmac_mj.agents import (
    ALGORITHMS,
    ActionSpace,
    Exploration,
    LLRConfig,
    StateSpace,
    base,
    config_class,
    make_agent,
)

BACKENDS = ("numba", "numpy")

STATES = StateSpace(low=[-np.pi, -25.0], high=[np.pi, 25.0], periodic=[True, False])
ACTIONS = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])


@pytest.mark.slow
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
    explore = Exploration(sigma=1.0)
    draws = [explore.sample(k, 1, rng)[0] for k in range(9)]
    assert [d != 0 for d in draws] == [True, False, False] * 3  # every third step, from step 0


def test_the_boundary_checks_are_functions_of_a_value_its_space_and_its_name():
    x = base.check_state([0.5, 2], STATES, "x0", "rmac")
    assert x.dtype == float and x.tolist() == [0.5, 2.0]
    assert base.check_state([[0.5], [2.0]], STATES).shape == (2,)  # any (2,)-sized input
    with pytest.raises(ValueError, match=r"^rmac: x0 must be finite"):
        base.check_state([np.nan, 0.0], STATES, "x0", "rmac")
    with pytest.raises(ValueError, match=r"x_next must have shape \(2,\)"):
        base.check_state([0.0, 0.0, 0.0], STATES, "x_next")
    with pytest.raises(ValueError, match=r"x\[1\] = 1e\+09 is beyond what a learner accepts"):
        base.check_state([0.0, 1e9], STATES)
    assert base.check_action(2.5, ACTIONS).tolist() == [2.5]  # inside or outside the bounds
    with pytest.raises(ValueError, match=r"u must have shape \(1,\)"):
        base.check_action([1.0, 2.0], ACTIONS)
    with pytest.raises(ValueError, match="u must be finite"):
        base.check_action([np.inf], ACTIONS)
    assert base.check_reward(np.float32(-1.5)) == -1.5
    with pytest.raises(ValueError, match="v must be a finite number"):
        base.check_reward("a", "v")
    with pytest.raises(ValueError, match="reward must be finite"):
        base.check_reward(np.nan)


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


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_copy_restored_mid_trial_continues_exactly_like_the_original(algorithm):
    """state_dict holds everything that decides what the agent does next: memories, weights, traces,
    the trial's bookkeeping and the random generator."""
    from rmac_mj.rollout import action_space_of, run_trial, state_space_of

    env = _pendulum_env()
    S, U = state_space_of(env), action_space_of(env)
    original = make_agent(
        algorithm, S, U, config=quick_config(algorithm), seed=np.random.default_rng(4)
    )
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
    A, B, c = (
        np.eye(2) + 0.1 * rng.normal(size=(2, 2)),
        rng.normal(size=(2, 1)),
        0.1 * rng.normal(size=2),
    )
    S = StateSpace(low=-10 * np.ones(2), high=10 * np.ones(2), periodic=np.zeros(2, bool))
    U = ActionSpace(low=-3.0 * np.ones(1), high=3.0 * np.ones(1), cost=np.ones(1))
    small = (
        dict(
            critic=LLRConfig(capacity=30, neighbours=5),
            reference=LLRConfig(capacity=25, neighbours=4),
            process=LLRConfig(capacity=12, neighbours=4),
        )
        if learner == "rmac"
        else dict(
            critic=LLRConfig(capacity=30, neighbours=5),
            actor=LLRConfig(capacity=25, neighbours=4),
            process=LLRConfig(capacity=12, neighbours=4),
        )
    )
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
    memories = [
        key for key in before if key.split(".")[0] in ("process", "reference", "critic", "actor")
    ]
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


# -- issue 20: learner boundaries ---------------------------------------------------------------

PAPER_LEARNERS = ("rmac", "s-ac", "mlac")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("algorithm", PAPER_LEARNERS)
def test_a_state_that_overflows_the_arithmetic_is_refused_before_anything_changes(
    algorithm, backend
):
    # Issue 20: agent.step(-1., [0.5, 1e300]) made RMAC's actions NaN and its memories hold NaN.
    agent = make_agent(algorithm, STATES, ACTIONS, config=dict(backend=backend), seed=0)
    agent.start(np.array([0.5, 0.0]))
    agent.step(-1.0, np.array([0.4, 1.0]))
    before = agent.state_dict()
    for x in ([0.5, 1e300], [1e300, 0.0], [0.5, -3e9]):
        with pytest.raises(ValueError, match=r"x\[\d\] = .* beyond what a learner accepts"):
            agent.step(-1.0, np.array(x))
        with pytest.raises(ValueError, match="beyond what a learner accepts"):
            agent.greedy_action(np.array(x))
    after = agent.state_dict()
    for key in before:
        np.testing.assert_array_equal(after[key], before[key], err_msg=key)
    # The limit is far beyond any state of a task: a million box widths.
    low, high = STATES.limit
    assert high[1] == pytest.approx(1e6 * 50.0) and low[0] == pytest.approx(-1e6 * 2 * np.pi)
    agent.step(-1.0, np.array([0.5, 1e6]))  # out of the box, within the limit: a state


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("algorithm", PAPER_LEARNERS)
def test_a_transition_that_overflows_is_refused_and_nothing_non_finite_is_stored(
    algorithm, backend
):
    # Finite rewards near the largest float drive the TD error past it: refused, never stored.
    agent = make_agent(algorithm, STATES, ACTIONS, config=dict(backend=backend), seed=0)
    agent.start(np.array([0.5, 0.0]))
    with (
        pytest.raises(ValueError, match="overflows the learner's arithmetic"),
        np.errstate(over="ignore", invalid="ignore"),
    ):  # the numpy version meets the overflow
        for k in range(1, 50):
            agent.step(1.7e308, np.array([0.5, 0.01 * k]))
    for key, value in agent.state_dict().items():
        assert value.dtype.kind != "f" or np.all(np.isfinite(value)), key


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_restore_names_what_is_wrong_before_anything_changes(algorithm):
    # Issue 20: NaN arrays were accepted by RMAC and MLAC; another learner's dict gave KeyError.
    agent = make_agent(algorithm, STATES, ACTIONS, config=quick_config(algorithm), seed=0)
    agent.start(np.array([0.5, 0.0]))
    for k in range(1, 6):
        agent.step(-1.0, np.array([0.5, 0.1 * k]))
    good = agent.state_dict()
    twin = make_agent(algorithm, STATES, ACTIONS, config=quick_config(algorithm), seed=1)
    fresh = twin.state_dict()
    key = next(k for k, v in good.items() if v.dtype.kind == "f" and v.size > 1)
    bad_cases = [
        ({**good, key: np.full_like(good[key], np.nan)}, f"{key!r} must be finite"),
        ({**good, key: good[key][..., :1]}, f"{key!r} must have shape"),
        ({**good, key: good[key].astype(object)}, f"{key!r} must hold"),
        ({k: v for k, v in good.items() if k != key}, f"lacks {key!r}"),
        ({**good, "bogus": np.zeros(1)}, "has 'bogus'"),
    ]
    other = "mlac" if algorithm == "rmac" else "rmac"
    foreign = make_agent(other, STATES, ACTIONS, seed=0).state_dict()
    bad_cases.append((foreign, "another learner"))
    for state, named in bad_cases:
        with pytest.raises((ValueError, TypeError), match=re.escape(named)):
            twin.load_state_dict(state)
        after = twin.state_dict()
        for k in fresh:  # a refused restore changed nothing
            np.testing.assert_array_equal(after[k], fresh[k], err_msg=k)
    twin.load_state_dict(good)


def test_restore_checks_the_learners_own_rules():
    agent = make_agent("rmac", STATES, ACTIONS, seed=0)
    state = agent.state_dict()
    for change, named in (
        (("critic.meta", np.array([3000, 3000])), "'critic.meta'"),
        (("traces", np.full_like(state["traces"], 2.0)), "'traces'"),
        (("k", np.array(-1)), "'k'"),
    ):
        with pytest.raises(ValueError, match=named):
            agent.load_state_dict({**state, change[0]: change[1]})
    sac = make_agent("s-ac", STATES, ACTIONS, seed=0)
    state = sac.state_dict()
    with pytest.raises(ValueError, match="'tiles'"):
        sac.load_state_dict({**state, "tiles": state["tiles"] + 10**6})


@pytest.mark.parametrize("algorithm", PAPER_LEARNERS)
def test_memory_estimate_is_what_the_learner_allocates(algorithm):
    """The estimate from the config alone matches what building the learner and taking two copies
    of its state (a snapshot) allocate."""
    import tracemalloc

    from rmac_mj.agents import memory_estimate

    big = {
        "rmac": {
            "critic": {"capacity": 60000},
            "reference": {"capacity": 50000},
            "process": {"capacity": 20000},
        },
        "mlac": {
            "critic": {"capacity": 60000},
            "actor": {"capacity": 50000},
            "process": {"capacity": 20000},
        },
        "s-ac": dict(tile_coding={"num_tilings": 64, "tiles": 60}),
    }[algorithm]
    estimate = memory_estimate(algorithm, STATES, ACTIONS, big)
    tracemalloc.start()
    agent = make_agent(algorithm, STATES, ACTIONS, config=big, seed=0)
    copies = [agent.state_dict(), agent.state_dict()]
    allocated, _ = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(copies) == 2 and 0.9 * allocated <= estimate <= 1.15 * allocated
    small = memory_estimate(algorithm, STATES, ACTIONS)
    assert 0 < small < estimate


@pytest.mark.slow
def test_memory_estimate_needs_no_memory_for_what_cannot_fit(tmp_path):
    """Issue 20: critic.capacity=1e9 grew to 21 GB before the OOM killer stopped it. The estimate
    says so from the config, under an address-space limit of 2 GB, while building the learner
    there fails."""
    script = (
        "import resource, numpy as np\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))\n"
        "from rmac_mj.agents import ActionSpace, StateSpace, make_agent, memory_estimate\n"
        "S = StateSpace(low=[-3.2, -25.0], high=[3.2, 25.0], periodic=[True, False])\n"
        "U = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])\n"
        "big = {'critic': {'capacity': 10**9}}\n"
        "print(memory_estimate('rmac', S, U, big))\n"
        "try:\n"
        "    make_agent('rmac', S, U, config=big)\n"
        "except MemoryError:\n"
        "    print('MemoryError')\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    estimate, outcome = result.stdout.split()
    assert int(estimate) > 24 * 2**30 and outcome == "MemoryError", result.stderr


#: Per learner, the hyperparameter its memory grows with, at two sizes.
_SIZES = {
    "rmac": ("critic", {"capacity": 2000}, {"capacity": 20000}),
    "mlac": ("actor", {"capacity": 2000}, {"capacity": 20000}),
    "s-ac": ("tile_coding", {"tiles": 7}, {"tiles": 70}),
    "recommended": ("tile_coding", {"tiles": 7}, {"tiles": 70}),
    "s-ac-dyna": ("tile_coding", {"tiles": 7}, {"tiles": 70}),
    "sb3-sac": ("buffer_size", 10**4, 10**6),
    "sb3-td3": ("buffer_size", 10**4, 10**6),
    "sb3-ppo": ("n_steps", 256, 8192),
    "sb3-crossq": ("buffer_size", 10**4, 10**6),
}


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_every_learner_estimates_its_memory_from_its_config(algorithm):
    # What a runner asks before it starts workers: an answer for every registered learner.
    from rmac_mj.agents import memory_estimate

    name, small, large = _SIZES[algorithm]
    at_small = memory_estimate(algorithm, STATES, ACTIONS, {name: small})
    at_large = memory_estimate(algorithm, STATES, ACTIONS, {name: large})
    assert isinstance(at_small, int) and 0 < at_small < at_large
