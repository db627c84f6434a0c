"""The contract every task of the suite keeps (like dm_control's suite_test), over ``tasks.ALL_TASKS``."""

import inspect

import numpy as np
import pytest
from absl.testing import absltest
from dm_env import test_utils

from rmac_mj import tasks
from rmac_mj.tasks import common


def _random_actions(env, rng, n):
    spec = env.action_spec()
    return [rng.uniform(spec.minimum, spec.maximum, size=spec.shape) for _ in range(n)]


def _default(domain, task, name):
    return inspect.signature(tasks.SUITE[domain][task]).parameters[name].default


@pytest.fixture(params=tasks.ALL_TASKS, ids=lambda t: f"{t[0]}-{t[1]}")
def domain_task(request):
    return request.param


def test_observations_match_their_specs_and_are_finite(domain_task):
    env = tasks.load(*domain_task, task_kwargs={"random": 0})
    spec = env.observation_spec()
    timestep = env.reset()
    for action in [None] + _random_actions(env, np.random.default_rng(0), 20):
        if action is not None:
            timestep = env.step(action)
        assert list(timestep.observation) == list(spec)
        for key, value in timestep.observation.items():
            spec[key].validate(value)
            assert np.all(np.isfinite(value)), key


def test_same_seed_same_trajectory_and_observations_share_no_memory(domain_task):
    def run():
        env = tasks.load(*domain_task, task_kwargs={"random": 3})
        observations, rewards = [env.reset().observation], []
        for action in _random_actions(env, np.random.default_rng(1), 15):
            timestep = env.step(action)
            observations.append(timestep.observation)
            rewards.append(timestep.reward)
        return observations, rewards
    (first, first_rewards), (second, second_rewards) = run(), run()
    assert first_rewards == second_rewards
    for a, b in zip(first, second):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
    for key in first[-1]:
        assert not np.shares_memory(first[-1][key], first[-2][key]), key


def test_episode_is_time_limit_over_control_timestep_steps_with_float_rewards(domain_task):
    env = tasks.load(*domain_task)
    expected = round(_default(*domain_task, "time_limit") / _default(*domain_task, "control_timestep"))
    timestep, steps = env.reset(), 0
    spec = env.action_spec()
    while not timestep.last():
        timestep = env.step((spec.minimum + spec.maximum) / 2)
        steps += 1
        assert isinstance(timestep.reward, float) and np.isfinite(timestep.reward)
    assert steps == expected
    assert env.control_timestep() == pytest.approx(_default(*domain_task, "control_timestep"))


@pytest.mark.parametrize("kind", ["nan", "inf", "too_long", "nested"])
def test_bad_actions_raise_before_stepping(domain_task, kind):
    env = tasks.load(*domain_task)
    env.reset()
    shape = env.action_spec().shape
    action = {"nan": np.full(shape, np.nan), "inf": np.full(shape, np.inf),
              "too_long": np.zeros(shape[0] + 1), "nested": np.zeros((1,) + shape)}[kind]
    with pytest.raises(ValueError):
        env.step(action)
    assert env.physics.data.time == 0.0


def test_learner_state_names_observations_and_boxes_the_start(domain_task):
    env = tasks.load(*domain_task)
    hints = env.task.learner_state
    assert isinstance(hints, common.LearnerState)
    observation = env.reset().observation
    x = np.concatenate([np.asarray(observation[key]).ravel() for key in hints.keys])
    assert x.shape == (len(hints.low),)
    assert np.all(np.asarray(hints.low) <= x) and np.all(x <= np.asarray(hints.high))
    assert len(hints.action_weights) == env.action_spec().shape[0]


def test_batched_reward_is_the_step_reward(domain_task):
    """``task.reward_of(physics.state_of(...), u)`` is what the step charges: what trajopt relies on."""
    env = tasks.load(*domain_task, task_kwargs={"random": 0})
    env.reset()
    spec = env.action_spec()
    for action in _random_actions(env, np.random.default_rng(2), 10):
        x = env.physics.state_of(env.physics.data.qpos.copy(), env.physics.data.qvel.copy())
        reward = env.step(action).reward
        applied = np.clip(action, spec.minimum, spec.maximum)
        assert reward == pytest.approx(float(env.task.reward_of(x, applied)), abs=1e-12)


def test_learner_state_rejects_inconsistent_hints():
    good = dict(keys=("a",), low=(-1.0,), high=(1.0,), periodic=(False,), labels=("a [m]",),
                weights=(1.0,), action_weights=(1.0,), action_labels=("u [V]",))
    common.LearnerState(**good)
    for change, name in [({"high": (1.0, 2.0)}, "high"), ({"low": (1.0,)}, "low"),
                         ({"weights": (-1.0,)}, "weights"), ({"action_labels": ()}, "action_weights"),
                         ({"keys": ()}, "keys")]:
        with pytest.raises(ValueError, match=name):
            common.LearnerState(**{**good, **change})


def _conformance_case(domain, task):
    class Case(test_utils.EnvironmentTestMixin, absltest.TestCase):
        def make_object_under_test(self):
            return tasks.load(domain, task, task_kwargs={"random": 0})

        def make_action_sequence(self):  # long enough to cross an episode boundary
            env = self.make_object_under_test()
            yield from _random_actions(env, np.random.default_rng(0), 150)

    Case.__name__ = Case.__qualname__ = f"TestDmEnvConformance_{domain}_{task}"
    return Case


for _domain, _task in tasks.ALL_TASKS:
    globals()[f"TestDmEnvConformance_{_domain}_{_task}"] = _conformance_case(_domain, _task)
