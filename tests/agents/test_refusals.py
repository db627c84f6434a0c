"""A refused call changes nothing: every learner checks, then changes.

For every public entry point that can refuse (start, step, stop, learn, learn_from, greedy_action,
load_state_dict, and planning and replay after a trial) and every kind of bad input (non-finite or
malformed rewards, states and actions, wrong shapes, calls outside a trial, and finite inputs whose
update overflows the arithmetic), the bytes of every array of ``state_dict()``, the random
generator's state included, are the same after the refused call as before it.
"""

import numpy as np
import pytest
from learners import quick_config

from rmac_mj.agents import (
    ALGORITHMS,
    ActionSpace,
    Exploration,
    Planning,
    Replay,
    StateSpace,
    make_agent,
)

STATES = StateSpace(low=[-np.pi, -25.0], high=[np.pi, 25.0], periodic=[True, False])
ACTIONS = ActionSpace(low=[-3.0], high=[3.0], cost=[1.0])
PAPER_LEARNERS = ("rmac", "s-ac", "mlac", "s-ac-dyna", "recommended")
BACKENDS = ("numba", "numpy")
#: Finite rewards whose updates drive the arithmetic past the largest float within a few steps.
OVERFLOWING = (1.7e308, -1.7e308, 1e308, -1e308)


def _agent(algorithm, **config):
    config = {**quick_config(algorithm), **config}
    if algorithm in PAPER_LEARNERS:  # noise at every step: a refused step must not draw it
        config.setdefault("exploration", Exploration(sigma=0.5, period=1))
    agent = make_agent(algorithm, STATES, ACTIONS, config=config, seed=3)
    agent.start(np.array([0.5, 0.0]))
    for k in range(1, 8):
        agent.step(-1.0 + 0.1 * k, np.array([0.5 - 0.05 * k, 0.3 * k]))
    return agent


def assert_unchanged(agent, before):
    after = agent.state_dict()
    assert sorted(after) == sorted(before)
    for key, value in before.items():
        assert after[key].dtype == value.dtype and after[key].shape == value.shape, key
        assert after[key].tobytes() == value.tobytes(), f"{key} changed by a refused call"


def _refused(agent, call, *args, error=(ValueError, TypeError, RuntimeError), match=None):
    before = agent.state_dict()
    with pytest.raises(error, match=match), np.errstate(all="ignore"):
        call(*args)
    assert_unchanged(agent, before)


def _until_refused(agent, call, prepare=None):
    """``prepare(k)`` then ``call(k)`` for k = 1, 2, ... until ``call`` is refused; the state before
    the refused call and after it must be the same."""
    with np.errstate(all="ignore"):
        for k in range(1, 60):
            if prepare is not None:
                prepare(k)
            before = agent.state_dict()
            try:
                call(k)
            except ValueError as error:
                assert "overflows the learner's arithmetic" in str(error)
                break
        else:
            pytest.fail("no update overflowed")
    assert_unchanged(agent, before)
    return before


BAD_STEPS = [
    (float("nan"), [0.5, 0.1]),
    (float("inf"), [0.5, 0.1]),
    ("ten", [0.5, 0.1]),
    (None, [0.5, 0.1]),
    (-1.0, [np.nan, 0.1]),
    (-1.0, [0.5, np.inf]),
    (-1.0, [0.5, 1e300]),  # beyond what a learner accepts
    (-1.0, [0.5, 0.1, 0.2]),  # wrong shape
    (-1.0, [[0.5], [0.1], [0.0]]),
    (-1.0, "state"),
]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_bad_inputs_at_every_entry_point_change_nothing(algorithm):
    agent = _agent(algorithm)
    for reward, x in BAD_STEPS:
        _refused(agent, agent.step, reward, x)
        _refused(agent, agent.stop, reward, x)
        if reward == -1.0:
            _refused(agent, agent.greedy_action, x)
            _refused(agent, agent.value, x)
    _refused(agent, agent.start, [np.nan, 0.0])
    _refused(agent, agent.start, [0.5, 1e300])
    _refused(agent, agent.start, [0.5])
    _refused(agent, agent.learn_from, [[0.5, 0.0]], [[0.0]], [-1.0])  # states must be K + 1
    _refused(agent, agent.learn_from, [[0.5, 0.0], [0.4, 0.1]], [[9.0]], [-1.0])  # out of bounds
    _refused(agent, agent.learn_from, [[0.5, 0.0], [0.4, 0.1]], [[0.0]], [np.nan])
    for bad in (
        dict(x=[np.nan, 0.0]),
        dict(u=[0.0, 1.0]),
        dict(u=[np.inf]),
        dict(reward=np.inf),
        dict(x_next=[0.5]),
    ):
        args = dict(x=[0.5, 0.0], u=[0.5], reward=-1.0, x_next=[0.4, 0.1]) | bad
        _refused(agent, agent.learn, *args.values(), error=(ValueError, NotImplementedError))
    agent.stop(-1.0, [0.4, 0.2])
    _refused(agent, agent.step, -1.0, [0.5, 0.1], error=RuntimeError, match="outside a trial")
    _refused(agent, agent.stop, -1.0, [0.5, 0.1], error=RuntimeError, match="outside a trial")


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("reward", OVERFLOWING)
@pytest.mark.parametrize("algorithm", PAPER_LEARNERS)
def test_a_step_whose_update_overflows_changes_nothing(algorithm, reward, backend):
    # step(-1e308, x) was refused after RMAC's process memory, step count and generator had
    # moved (S-AC: its count and tiles; MLAC: its critic, process memory and traces).
    agent = _agent(algorithm, backend=backend)
    _until_refused(agent, lambda k: agent.step(reward, np.array([0.5, 0.01 * k])))


@pytest.mark.parametrize("terminal", [False, True])
@pytest.mark.parametrize("algorithm", PAPER_LEARNERS)
def test_a_last_transition_that_overflows_changes_nothing(algorithm, terminal):
    agent = _agent(algorithm)

    def next_trial(k):
        if k > 1:
            agent.start(np.array([0.5, 0.0]))

    _until_refused(
        agent,
        lambda k: agent.stop(
            (-1) ** k * 1.7e308 if terminal else 1.7e308,  # a terminal value is not bootstrapped
            np.array([0.5, 0.01 * k]),
            terminal=terminal,
        ),
        next_trial,
    )


@pytest.mark.parametrize("algorithm", ("rmac", "mlac"))
def test_learn_that_overflows_changes_nothing(algorithm):
    agent = _agent(algorithm)
    _until_refused(agent, lambda k: agent.learn([0.5, 0.0], [0.5], 1.7e308, [0.5, 0.01 * k]))


@pytest.mark.parametrize("algorithm", ("rmac", "s-ac", "mlac"))
def test_learn_from_that_overflows_changes_nothing(algorithm):
    # A recorded trial learned as a whole: refused in its last transition, none of it is kept.
    agent = _agent(algorithm)
    agent.stop(-1.0, [0.4, 0.2])
    states = np.array([[0.5, 0.01 * k] for k in range(6)])
    actions, rewards = np.zeros((5, 1)), np.full(5, 1.7e308)
    _refused(agent, agent.learn_from, states, actions, rewards, match="overflows")


@pytest.mark.parametrize(
    "rehearsal",
    [dict(planning=Planning(steps=3)), dict(replay=Replay(steps=3, order="forward"))],
    ids=["planning", "replay"],
)
@pytest.mark.parametrize("algorithm", ("rmac", "s-ac", "mlac"))
def test_planning_or_replay_that_overflows_leaves_the_trial_as_it_was(algorithm, rehearsal):
    # The real transitions were finite; the rehearsal after the trial overflows on the huge
    # rewards they taught the model (planning) or hold (replay): stop is refused as a whole.
    agent = _agent(algorithm, **rehearsal)

    def next_trial(k):
        if k > 1:
            agent.start(np.array([0.5, 0.0]))

    _until_refused(agent, lambda k: agent.stop(1.7e308, np.array([0.5, 0.01 * k])), next_trial)
    assert agent.state_dict()["in_trial"]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_refused_restore_changes_nothing(algorithm):
    agent = _agent(algorithm)
    good = agent.state_dict()
    twin = _agent(algorithm)
    twin.step(-2.0, np.array([0.1, 0.1]))
    key = next(k for k, v in good.items() if v.dtype.kind == "f" and v.size > 1)
    for state in (
        {**good, key: good[key].astype(np.float32 if good[key].dtype == float else float)},
        {**good, key: np.full_like(good[key], np.inf)},
        {**good, key: np.zeros(good[key].shape + (2,))},
        {**good, "rng": good["rng"].astype(np.int64)},
        {**good, "extra": np.zeros(1)},
        {k: v for k, v in good.items() if k != key},
    ):
        _refused(twin, twin.load_state_dict, state)
