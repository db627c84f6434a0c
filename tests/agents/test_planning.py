"""Planning and replay (issue 23): off is today's learner, a true model speeds learning, replay is
the real update, and both back ends rehearse alike."""

import itertools

import numpy as np
import plain_pendulum
import pytest

from rmac_mj.agents import ActionSpace, LLRConfig, Planning, Replay, StateSpace, make_agent
from rmac_mj.agents.task_knowledge import PAPER_REWARD_SCALE
from rmac_mj.constraints import InvalidParameterError

LEARNERS = ("rmac", "s-ac", "mlac")

#: The pendulum's spaces as the dc_pendulum task gives them (Table 2's weights, the reward's costs).
PENDULUM = (
    StateSpace(
        low=[-np.pi, -8 * np.pi],
        high=[np.pi, 8 * np.pi],
        periodic=[True, False],
        input_weights=[1.0, 0.1],
        cost=[5.0, 0.1],
        reward_scale=PAPER_REWARD_SCALE,
    ),
    ActionSpace(low=[-3.0], high=[3.0], cost=[1.0]),
)
#: Memories small enough to fill (and replace) within the first trials of these tests.
SMALL = {
    "rmac": dict(
        critic=LLRConfig(capacity=60, neighbours=5),
        reference=LLRConfig(capacity=50, neighbours=4),
        process=LLRConfig(capacity=20, neighbours=4),
    ),
    "mlac": dict(
        actor=LLRConfig(capacity=60, neighbours=5),
        critic=LLRConfig(capacity=60, neighbours=5),
        process=LLRConfig(capacity=20, neighbours=4),
    ),
    "s-ac": {},
}


def _pendulum_trial(agent, steps=30, x0=(-np.pi, 0.0)):
    """One learning trial on the plain-float pendulum; returns its (states, actions, rewards)."""
    x = np.array(x0)
    states, actions, rewards = [x], [], []
    u = agent.start(x)
    for k in range(1, steps + 1):
        actions.append(u)
        reward, x = plain_pendulum.control_step(x, u)
        states.append(x)
        rewards.append(reward)
        if k == steps:
            agent.stop(reward, x)
        else:
            u = agent.step(reward, x)
    return np.array(states), np.array(actions), np.array(rewards)


@pytest.mark.parametrize("learner", LEARNERS)
def test_zero_steps_is_the_learner_without_planning_bit_for_bit(learner):
    # Every other planning and replay setting changed: with 0 steps none of them may matter.
    off = dict(
        planning=Planning(
            steps=0,
            horizon=7,
            start="memory",
            reward="task",
            model_capacity=50,
            model_neighbours=3,
            clip=False,
        ),
        replay=Replay(steps=0, order="forward", capacity=10),
    )
    plain = make_agent(learner, *PENDULUM, config=SMALL[learner], seed=5)
    switched_off = make_agent(learner, *PENDULUM, config=dict(SMALL[learner], **off), seed=5)
    assert switched_off.rehearsal is None
    for _ in range(3):
        a, b = _pendulum_trial(plain), _pendulum_trial(switched_off)
        assert all(np.array_equal(p, q) for p, q in zip(a, b))
    a, b = plain.state_dict(), switched_off.state_dict()
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


# -- a model that holds the true dynamics --------------------------------------------------------

DT = 0.1
INTEGRATOR = (
    StateSpace(
        low=[-2, -2], high=[2, 2], periodic=[False, False], input_weights=[1, 1], cost=[1, 0.1]
    ),
    ActionSpace(low=[-1], high=[1], cost=[0.1]),
)


def _integrator(x, u):
    """A double integrator: position and speed under a bounded force; reward -x^T Q x - 0.1 u^2."""
    p, v = x
    return np.array([p + DT * v, v + DT * u[0]]), -(p * p + 0.1 * v * v) - 0.1 * u[0] ** 2


def _integrator_trial(agent, learn=True, steps=30):
    x, total = np.array([1.0, 0.0]), 0.0
    if not learn:
        agent.begin_greedy_trial()
    u = agent.start(x) if learn else agent.greedy_action(x)
    for k in range(steps):
        x, r = _integrator(x, u)
        total += r
        if k == steps - 1:
            if learn:
                agent.stop(r, x)
        else:
            u = agent.step(r, x) if learn else agent.greedy_action(x)
    return total


def test_planning_in_the_true_model_learns_in_fewer_real_trials():
    # The model's memory holds the exact dynamics on a grid (affine: LLR predicts them exactly) and
    # the reward is the task's. S-AC without planning stays near its first greedy return (about
    # -30) for 8 trials; with 10 simulated steps per real one it settles the integrator (about -13).
    grid, forces = np.linspace(-2, 2, 9), np.linspace(-1, 1, 5)
    Z = np.array(list(itertools.product(grid, grid, forces)))
    Y = np.array([_integrator(z[:2], z[2:])[0] for z in Z])
    trials_needed = {}
    for steps in (0, 10):
        needed = []
        for seed in range(3):
            # The paper's actor rate and noise, as this test was set for (not the task's units).
            paper = dict(alpha_a=0.005, exploration={"sigma": 1.0})
            agent = make_agent(
                "s-ac",
                *INTEGRATOR,
                seed=seed,
                config=dict(paper, planning=Planning(steps=steps, reward="task"))
                if steps
                else paper,
            )
            if steps:
                agent.rehearsal.model.memory.fit(Z, Y)
            needed.append(
                next(
                    (
                        t
                        for t in range(1, 9)
                        if _integrator_trial(agent) is not None
                        and _integrator_trial(agent, learn=False) > -16.0
                    ),
                    99,
                )
            )
        trials_needed[steps] = needed
    assert max(trials_needed[10]) <= 8 and min(trials_needed[0]) == 99, trials_needed


# -- replay --------------------------------------------------------------------------------------


@pytest.mark.parametrize("learner", LEARNERS)
def test_replaying_a_recorded_trial_makes_the_real_updates(learner):
    # Two identical learners; one runs a trial, the other learns the recorded trial: their critics
    # (and every memory or weight) end the same. The generator is all that differs: only the real
    # trial drew exploration noise.
    real = make_agent(learner, *PENDULUM, config=SMALL[learner], seed=11)
    replayed = make_agent(learner, *PENDULUM, config=SMALL[learner], seed=11)
    for _ in range(2):
        replayed.learn_from(*_pendulum_trial(real))
    a, b = real.state_dict(), replayed.state_dict()
    for key in set(a) - {"rng", "trials"}:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_forward_replay_after_a_trial_is_learning_it_twice():
    # Replay(order='forward', steps=1) replays the one stored trial once after it ran: the same as
    # learning it again from the record, without touching the process model.
    config = dict(SMALL["rmac"], replay=Replay(steps=1, order="forward"))
    agent = make_agent("rmac", *PENDULUM, config=config, seed=4)
    twin = make_agent("rmac", *PENDULUM, config=SMALL["rmac"], seed=4)
    record = _pendulum_trial(agent)
    assert _pendulum_trial(twin)[1].tolist() == record[1].tolist()
    process = twin.process.state_dict()
    twin._set_rehearsing(True)
    twin.learn_from(*record)
    twin._set_rehearsing(False)
    assert all(np.array_equal(v, twin.process.state_dict()[k]) for k, v in process.items())
    a, b = agent.state_dict(), twin.state_dict()
    for key in set(b) - {"rng"}:  # (the replay drew which stored trial to replay)
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_learn_from_checks_the_record():
    agent = make_agent("s-ac", *PENDULUM, seed=0)
    good = (np.zeros((4, 2)), np.zeros((3, 1)), np.zeros(3))
    agent.learn_from(*good)
    for bad, word in [
        ((np.zeros((3, 2)),) + good[1:], "states"),
        (good[:1] + (np.full((3, 1), 5.0),) + good[2:], "bounds"),
        (good[:2] + (np.array([0.0, np.nan, 0.0]),), "finite"),
    ]:
        with pytest.raises(ValueError, match=word):
            agent.learn_from(*bad)


# -- the two back ends ---------------------------------------------------------------------------

#: Every option of Planning and Replay, one entry per value (defaults elsewhere).
OPTIONS = {
    "planning": dict(planning=Planning(steps=1, horizon=6)),
    "planning, whole trials": dict(planning=Planning(steps=1)),
    "planning from the trajectory": dict(planning=Planning(steps=1, horizon=6, start="trajectory")),
    "planning from the memory": dict(planning=Planning(steps=1, horizon=6, start="memory")),
    "planning with the task's reward": dict(planning=Planning(steps=1, horizon=6, reward="task")),
    "planning unclipped, small model": dict(
        planning=Planning(steps=1, horizon=6, clip=False, model_capacity=25, model_neighbours=5)
    ),
    "replay backward": dict(replay=Replay(steps=1)),
    "replay forward, small store": dict(replay=Replay(steps=2, order="forward", capacity=40)),
    "planning and replay": dict(planning=Planning(steps=1, horizon=10), replay=Replay(steps=1)),
}


@pytest.mark.parametrize("learner", LEARNERS)
@pytest.mark.parametrize("options", list(OPTIONS))
def test_back_ends_rehearse_alike(learner, options):
    """Lock step per real step and per rehearsal: the numpy agent is set to the numba agent's state
    before each, both run it, and the actions and the whole state (memories, model, stored trials,
    generator) must agree."""
    config = dict(SMALL[learner], **OPTIONS[options])
    fast = make_agent(learner, *PENDULUM, config=dict(config, backend="numba"), seed=3)
    slow = make_agent(learner, *PENDULUM, config=dict(config, backend="numpy"), seed=3)
    tol = 1e-7
    for trial in range(2):
        x = np.array([-np.pi + 0.3 * trial, 0.0])
        slow.load_state_dict(fast.state_dict())
        u = fast.start(x)
        np.testing.assert_allclose(u, slow.start(x), atol=tol)
        for k in range(1, 25):
            reward, x = plain_pendulum.control_step(x, u)
            slow.load_state_dict(fast.state_dict())
            if k < 24:
                u = fast.step(reward, x)
                np.testing.assert_allclose(
                    u, slow.step(reward, x), atol=tol, err_msg=f"trial {trial} step {k}"
                )
            else:  # the rehearsal runs here, after the trial's last transition
                fast.stop(reward, x)
                slow.stop(reward, x)
        a, b = fast.state_dict(), slow.state_dict()
        assert a.keys() == b.keys()
        if "trace_idx" in a:  # S-AC's live traces: the compiled list keeps them in another order
            n = int(a["n_traces"])
            a["trace_idx"], b["trace_idx"] = (np.sort(d["trace_idx"][:n]) for d in (a, b))
        for key in a:
            if a[key].dtype.kind == "f":
                np.testing.assert_allclose(
                    a[key], b[key], rtol=tol, atol=tol, err_msg=f"{key} after trial {trial}"
                )
            else:
                np.testing.assert_array_equal(a[key], b[key], err_msg=f"{key} after trial {trial}")


@pytest.mark.parametrize("learner", LEARNERS)
def test_a_restored_copy_rehearses_like_the_original(learner):
    config = dict(SMALL[learner], planning=Planning(steps=1, horizon=8), replay=Replay(steps=1))
    agent = make_agent(learner, *PENDULUM, config=config, seed=8)
    _pendulum_trial(agent)
    copy = make_agent(learner, *PENDULUM, config=config, seed=0)
    copy.load_state_dict(agent.state_dict())
    a, b = _pendulum_trial(agent), _pendulum_trial(copy)
    assert all(np.array_equal(p, q) for p, q in zip(a, b))


def test_settings_are_checked_by_name():
    for kwargs, name in [
        (dict(steps=-1), "steps"),
        (dict(steps=2.0), "steps"),
        (dict(start="anywhere"), "start"),
        (dict(reward="oracle"), "reward"),
        (dict(model_capacity=5, model_neighbours=9), "model_neighbours"),
    ]:
        with pytest.raises(InvalidParameterError, match=f"Planning.{name}"):
            Planning(**kwargs)
    with pytest.raises(InvalidParameterError, match="Replay.order"):
        Replay(order="sideways")
    undeclared = (StateSpace(low=[-1], high=[1], periodic=[False]), ActionSpace(low=[-1], high=[1]))
    with pytest.raises(ValueError, match="state and action costs"):
        make_agent("s-ac", *undeclared, config=dict(planning=Planning(steps=1, reward="task")))


@pytest.mark.slow
def test_the_bench_prices_planning_and_replay_for_every_learner():
    """``rmac-mj bench`` restores one warm state (planning and replay memories filled) into learners
    configured with either or neither; each keeps the parts it holds and is priced."""
    from rmac_mj.bench import planning as bench_planning

    report = bench_planning.rehearsal_costs(
        "dc_pendulum", "swingup", repeats=1, trials=1, steps=(0, 5)
    )
    assert set(report) == {"s-ac", "rmac", "mlac"}
    for figures in report.values():
        assert figures["planning_update_us"] > 0 and figures["replay_update_us"] > 0
        for kind in bench_planning.KINDS:
            per_minute = figures["cpu_per_simulated_minute"][kind]
            assert set(per_minute) == {0, 5} and all(
                np.isfinite(v) and v > 0 for v in per_minute.values()
            )
