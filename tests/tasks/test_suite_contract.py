"""Every task of the suite against one contract (dm_control's suite_test style): dm_env conformance,
specs and observations, the learner's state, the trial length, seeding, and bad actions.

The cases loop over ``rmac_mj.tasks.ALL_TASKS``, so a new task is held to the contract without a new
test; the test-only ``toy`` domain (tests/toy_domain.py) runs through the same checks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import toy_domain
from absl.testing import absltest
from dm_env import test_utils

from rmac_mj import tasks
from rmac_mj.rollout import state_of, steps_per_trial, trial_seconds
from rmac_mj.tasks import LearnerStateSpec

TOY = (toy_domain.DOMAIN, toy_domain.TASK)
CASES = [*tasks.ALL_TASKS, TOY]


def load(domain: str, task: str, **task_kwargs):
    if (domain, task) == TOY:
        return toy_domain.settle(**task_kwargs)
    return tasks.load(domain, task, task_kwargs=task_kwargs)


def random_actions(env, count: int, seed: int = 0, margin: float = 1.0) -> np.ndarray:
    """``count`` actions uniform over the action bounds widened by ``margin``; (count, m)."""
    spec = env.action_spec()
    low, high = np.broadcast_to(spec.minimum, spec.shape), np.broadcast_to(spec.maximum, spec.shape)
    centre, half = (low + high) / 2, (high - low) / 2 * margin
    return np.random.default_rng(seed).uniform(centre - half, centre + half, (count, *spec.shape))


def rollout(env, actions):
    timesteps = [env.reset()]
    for u in actions:
        timesteps.append(env.step(u))
        if timesteps[-1].last():
            break
    return timesteps


def test_the_toy_case_is_not_a_suite_task():
    assert TOY not in tasks.ALL_TASKS and ("dc_pendulum", "swingup") in tasks.ALL_TASKS


@pytest.mark.parametrize("domain, task", CASES)
def test_specs_observations_and_learner_state(domain, task):
    env = load(domain, task, random=0)
    spec = env.action_spec()
    assert np.all(np.isfinite(spec.minimum)) and np.all(np.asarray(spec.minimum) < spec.maximum)
    learner_state = env.task.learner_state
    assert isinstance(learner_state, LearnerStateSpec)
    n, m = len(learner_state.low), int(np.prod(spec.shape))
    assert len(learner_state.action_labels) == len(learner_state.action_input_weights) == m
    observation_spec = env.observation_spec()
    assert set(learner_state.keys) <= set(observation_spec)
    for timestep in rollout(env, random_actions(env, 5 * steps_per_trial(env), margin=1.2)):
        for key, value in timestep.observation.items():
            observation_spec[key].validate(value)
            assert np.all(np.isfinite(value)), key
        x = state_of(timestep.observation, learner_state)
        assert x.shape == (n,)
        periodic = np.array(learner_state.periodic)
        low, high = np.array(learner_state.low), np.array(learner_state.high)
        # Periodic dimensions are observed within their one period (wrapped).
        assert np.all((x[periodic] >= low[periodic]) & (x[periodic] < high[periodic]))


@pytest.mark.parametrize("domain, task", CASES)
def test_a_trial_is_the_declared_number_of_control_steps(domain, task):
    env = load(domain, task)
    timesteps = rollout(env, random_actions(env, 10_000))
    steps = len(timesteps) - 1
    assert timesteps[-1].last() and steps == steps_per_trial(env)
    assert env.physics.data.time == pytest.approx(trial_seconds(env), abs=1e-9)
    assert all(t.mid() for t in timesteps[1:-1]) and timesteps[0].first()
    assert all(math.isfinite(t.reward) for t in timesteps[1:])


@pytest.mark.slow
@pytest.mark.parametrize("domain, task", CASES)
def test_same_seed_same_trajectory_and_observations_share_no_memory(domain, task):
    def run(seed):
        env = load(domain, task, random=seed)
        actions = random_actions(env, 2 * steps_per_trial(env), seed=1)
        return rollout(env, actions) + rollout(
            env, actions
        )  # two episodes: the task's stream moves on

    first, second = run(3), run(3)
    for a, b in zip(first, second):
        assert a.reward == b.reward
        for key in a.observation:
            np.testing.assert_array_equal(a.observation[key], b.observation[key])
    for key in first[-1].observation:
        assert not np.shares_memory(first[-1].observation[key], first[-2].observation[key])


@pytest.mark.parametrize("domain, task", CASES)
def test_bad_actions_raise_before_anything_is_stepped(domain, task):
    env = load(domain, task)
    env.reset()
    good = random_actions(env, 1)[0]
    time = env.physics.data.time
    bad = [
        np.full_like(good, np.nan),
        np.full_like(good, np.inf),
        np.zeros(good.size + 1),
        np.zeros((2, good.size)),
        good + 1j,  # a complex action: refused, not cut to its real part
        np.array(["1"] * good.size),
    ]
    for action in bad:
        with pytest.raises(ValueError, match="action"):
            env.step(action)
        assert env.physics.data.time == time
    env.step(good)
    assert env.physics.data.time > time


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
@pytest.mark.parametrize(
    "kwargs, named",
    [
        ({"time_limit": "3"}, "time_limit must be a positive finite number, got '3'"),
        ({"control_timestep": True}, "control_timestep must be a positive finite number"),
        ({"random": "x"}, "random must be None, a seed"),
        ({"random": -1}, "random must be None, a seed"),
        ({"start_noise": "0.1"}, "start_noise must be a number in [0, 3.14159] rad"),
        ({"state_weights": "x"}, "state_weights must be a diagonal"),
        ({"start_state": "x"}, "start_state must be finite"),
    ],
)
def test_bad_task_kwargs_are_refused_at_load_naming_them(domain, task, kwargs, named):
    with pytest.raises(ValueError) as refusal:
        tasks.load(domain, task, task_kwargs=kwargs)
    assert named in str(refusal.value)


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
def test_a_start_beyond_mujocos_range_is_refused_at_load_not_at_reset(domain, task):
    start = np.zeros(len(tasks.load(domain, task).task.learner_state.low))
    start[0] = 1e300
    with pytest.raises(ValueError, match=r"start_state must lie within \+-1e\+10"):
        tasks.load(domain, task, task_kwargs={"start_state": start.tolist()})


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
def test_learner_state_names_observations_and_boxes_the_start(domain, task):
    env = tasks.load(domain, task)
    hints = env.task.learner_state
    assert isinstance(hints, LearnerStateSpec)
    observation = env.reset().observation
    x = np.concatenate([np.asarray(observation[key]).ravel() for key in hints.keys])
    assert x.shape == (len(hints.low),)
    assert np.all(np.asarray(hints.low) <= x) and np.all(x <= np.asarray(hints.high))
    assert len(hints.action_input_weights) == env.action_spec().shape[0]


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)  # the toy has no batched reward
def test_batched_reward_is_the_step_reward(domain, task):
    """``task.reward_of(physics.state_of(...), u)`` is what the step charges: what trajopt relies on."""
    env = tasks.load(domain, task, task_kwargs={"random": 0})
    env.reset()
    spec = env.action_spec()
    rng = np.random.default_rng(2)
    for action in [rng.uniform(spec.minimum, spec.maximum, size=spec.shape) for _ in range(10)]:
        x = env.physics.state_of(env.physics.data.qpos.copy(), env.physics.data.qvel.copy())
        reward = env.step(action).reward
        applied = np.clip(action, spec.minimum, spec.maximum)
        assert reward == pytest.approx(float(env.task.reward_of(x, applied)), abs=1e-12)


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)  # the toy has no batched reward
def test_the_declared_action_cost_is_what_the_reward_charges(domain, task):
    """learner_state.action_cost P is the reward's whole dependence on u: r(x, u) = r(x, 0) -
    sum_i P_i u_i^2, for the task's defaults and for a changed reward; what learners rely on."""
    for task_kwargs in (
        {},
        {"action_weights": 0.3} if domain == "dc_pendulum" else {"action_weights": (0.5, 2.0)},
    ):
        env = tasks.load(domain, task, task_kwargs=task_kwargs)
        cost = env.task.learner_state.action_cost
        assert cost is not None and len(cost) == env.action_spec().shape[0]
        rng = np.random.default_rng(0)
        x = rng.uniform(-1, 1, (20, len(env.task.learner_state.low)))
        u = rng.uniform(-2, 2, (20, len(cost)))
        charged = env.task.reward_of(x, np.zeros_like(u)) - env.task.reward_of(x, u)
        assert np.allclose(charged, (np.asarray(cost) * u * u).sum(axis=1), rtol=1e-12, atol=0)
        if task_kwargs:
            assert cost != load(domain, task).task.learner_state.action_cost


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
def test_the_declared_costs_are_the_whole_reward(domain, task):
    """learner_state.state_cost and action_cost together are the reward, r(x, u) = -sum_i q_i x_i^2
    - sum_j p_j u_j^2 (x as the learner sees it), for the defaults and a changed Q; what planning
    with the task's reward (Planning(reward='task')) computes. A full Q declares no state cost."""
    q = {"dc_pendulum": (2.0, 0.3), "two_link_arm": (0.5, 0.1, 2.0, 0.2)}[domain]
    for task_kwargs in ({}, {"state_weights": q}):
        env = tasks.load(domain, task, task_kwargs=task_kwargs)
        hints = env.task.learner_state
        assert hints.state_cost is not None and len(hints.state_cost) == len(hints.low)
        rng = np.random.default_rng(1)
        x = rng.uniform(hints.low, hints.high, (20, len(hints.low)))
        u = rng.uniform(-2, 2, (20, len(hints.action_cost)))
        declared = -(np.asarray(hints.state_cost) * x * x).sum(axis=1) - (
            np.asarray(hints.action_cost) * u * u
        ).sum(axis=1)
        assert np.allclose(env.task.reward_of(x, u), declared, rtol=1e-12, atol=1e-12)
    full = np.diag(q) + 0.1 * (np.ones((len(q), len(q))) - np.eye(len(q)))
    assert (
        tasks.load(domain, task, task_kwargs={"state_weights": full}).task.learner_state.state_cost
        is None
    )


def test_learner_state_rejects_inconsistent_hints():
    good = dict(
        keys=("a",),
        low=(-1.0,),
        high=(1.0,),
        periodic=(False,),
        labels=("a [m]",),
        input_weights=(1.0,),
        action_input_weights=(1.0,),
        action_labels=("u [V]",),
    )
    LearnerStateSpec(**good)
    for change, name in [
        ({"high": (1.0, 2.0)}, "high"),
        ({"low": (1.0,)}, "low"),
        ({"input_weights": (-1.0,)}, "input_weights"),
        ({"action_labels": ()}, "action_input_weights"),
        ({"action_cost": (1.0, 2.0)}, "action_cost"),
        ({"action_cost": (-1.0,)}, "action_cost"),
        ({"state_cost": (1.0, 2.0)}, "state_cost"),
        ({"state_cost": (-1.0,)}, "state_cost"),
        ({"keys": ()}, "keys"),
    ]:
        with pytest.raises(ValueError, match=name):
            LearnerStateSpec(**{**good, **change})


def _conformance_case(domain: str, task: str):
    class Case(test_utils.EnvironmentTestMixin, absltest.TestCase):
        def make_object_under_test(self):
            return load(domain, task, random=0)

        def make_action_sequence(self):  # long enough to cross an episode boundary
            env = self.make_object_under_test()
            yield from random_actions(env, 2 * steps_per_trial(env) + 50)

    Case.__name__ = Case.__qualname__ = f"TestDmEnvConformance_{domain}_{task}"
    return Case


for _domain, _task in CASES:
    globals()[f"TestDmEnvConformance_{_domain}_{_task}"] = _conformance_case(_domain, _task)
