"""An outside environment that fails (raises, exits, hands back non-finite, absurd or malformed
observations and rewards) is refused as one EnvironmentFailure naming the SPEC, the phase and its own
message, never a bare traceback of the package nor a learner that silently took the value."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from rmac_mj import envs
from rmac_mj.agents import PolicyAgent
from rmac_mj.envs.failures import checked_reward
from rmac_mj.errors import EnvironmentFailure, UserInputError
from rmac_mj.rollout import action_space_of, run_trial, state_space_of

FACTORIES = textwrap.dedent(
    """
    import sys
    import dm_env
    import numpy as np
    from dm_env import specs

    class Base(dm_env.Environment):
        fail = None
        def __init__(self):
            self.t = 0
        def control_timestep(self):
            return 0.05
        def observation_spec(self):
            return {"x": specs.BoundedArray((2,), float, [-1, -1], [1, 1])}
        def action_spec(self):
            return specs.BoundedArray((1,), float, -1, 1)
        def observation(self):
            return {"x": np.zeros(2)}
        def reward(self):
            return 0.0
        def reset(self):
            self.t = 0
            if self.fail == "reset":
                raise RuntimeError("the simulator is down")
            return dm_env.restart(self.observation())
        def step(self, action):
            self.t += 1
            if self.fail == "step" and self.t > 2:
                raise RuntimeError("lost power at t=3")
            return dm_env.transition(self.reward(), self.observation())

    def raises():
        raise RuntimeError("cannot open /dev/robot0")
    def exits():
        sys.exit(0)
    def reset_raises():
        env = Base(); env.fail = "reset"; return env
    def step_raises():
        env = Base(); env.fail = "step"; return env
    def late(value):
        class Late(Base):
            def observation(self):
                return {"x": np.full(2, value if self.t > 1 else 0.0)}
        return Late()
    def reward(value):
        class Bad(Base):
            def reward(self):
                return value
        return Bad()
    def dict_observation():
        class Nested(Base):
            def observation(self):
                return {"x": {"a": 1.0, "b": 2.0}}
        return Nested()
    def wrong_size():
        class Wrong(Base):
            def observation(self):
                return {"x": np.zeros(5 if self.t > 1 else 2)}
        return Wrong()
    def huge_reward():
        return reward(1e308)
    def string_reward():
        return reward("1.0")
    def keyword_seed(*, seed, **kw):
        env = Base()
        env.seed = seed
        return env
    def tiny_step():
        class Tiny(Base):
            def control_timestep(self):
                return 1e-300
        return Tiny()
    def wide():
        class Wide(Base):
            def observation_spec(self):
                return {"x": specs.BoundedArray((1000,), float, -np.ones(1000), np.ones(1000))}
            def observation(self):
                return {"x": np.zeros(1000)}
        return Wide()
    def time_limited(limit):
        import gymnasium
        from gymnasium import spaces
        from gymnasium.wrappers import TimeLimit

        class OneStep(gymnasium.Env):  # made without gymnasium.make: no spec
            observation_space = spaces.Box(-1.0, 1.0, (2,))
            action_space = spaces.Box(-1.0, 1.0, (1,))
            dt = 0.05
            def reset(self, seed=None, options=None):
                super().reset(seed=seed)
                return np.zeros(2, dtype=np.float32), {}
            def step(self, action):
                return np.zeros(2, dtype=np.float32), 1.0, True, False, {}
        return TimeLimit(OneStep(), limit)
    def gymnasium_reward(value):
        from gymnasium.wrappers import TimeLimit

        class Rewarding(type(time_limited(1).unwrapped)):
            def step(self, action):
                return np.zeros(2, dtype=np.float32), value, False, False, {}
        return TimeLimit(Rewarding(), 10)
    """
)


@pytest.fixture
def factories(tmp_path):
    path = tmp_path / "user_envs.py"
    path.write_text(FACTORIES)
    return path


def _steps(env, n=5):
    env.reset()
    for _ in range(n):
        env.step(np.zeros(1))


#: Declared x and trial length: no probing, so reset and step themselves are checked.
DECLARED = dict(learner_state={"keys": ["x"]}, trial_steps=10)


@pytest.mark.parametrize(
    "factory, kwargs, message",
    [
        ("raises", {}, r"its factory raised RuntimeError: cannot open /dev/robot0 \(at user_envs"),
        ("exits", {}, r"its factory called sys.exit\(0\)"),
        ("reset_raises", {}, r"its reset raised RuntimeError: the simulator is down"),
        ("step_raises", {}, r"its step raised RuntimeError: lost power at t=3"),
        ("late", {"value": float("nan")}, "its step gave a non-finite observation"),
        ("late", {"value": float("inf")}, "its step gave a non-finite observation"),
        ("late", {"value": 1e30}, r"its step gave x\[0\] = 1e\+30, beyond what a learner accepts"),
        ("reward", {"value": float("nan")}, "its step gave a non-finite reward, nan"),
        ("reward", {"value": None}, "its step gave the reward None, not a number"),
        ("reward", {"value": "1.0"}, r"its step gave the reward '1.0', not a number \(a str\)"),
        ("reward", {"value": [1.0]}, r"gave the reward \[1.0\], not a number \(a list\)"),
        ("huge_reward", {}, "its rewards over a trial of 10 steps sum to inf"),
        ("dict_observation", {}, "its reset gave an observation that is not numbers"),
        (
            "wrong_size",
            {},
            "its step gave an observation of 5 numbers, its observation_spec says 2",
        ),
    ],
)
def test_a_failing_environment_is_one_failure_naming_it(factories, factory, kwargs, message):
    spec = f"{factories}:{factory}"
    with pytest.raises(EnvironmentFailure, match=message) as failure:
        env = envs.load(spec, kwargs, **DECLARED)
        still = PolicyAgent(state_space_of(env), action_space_of(env), lambda x: np.zeros(1))
        run_trial(env, still)  # a trial's return too
    assert f"env '{spec}'" in str(failure.value) and "\n" not in str(failure.value)


def test_rewards_summed_over_an_action_repeat_stay_finite(factories):
    env = envs.load(f"{factories}:huge_reward", **{**DECLARED, "action_repeat": 2})
    with pytest.raises(EnvironmentFailure, match="over an action repeat of 2 sum to inf"):
        _steps(env, 1)


@pytest.mark.parametrize(
    "value, message",
    [("1.0", r"gave the reward '1.0', not a number \(a str\)"), (float("inf"), "non-finite")],
)
def test_a_gymnasium_reward_is_checked_before_it_is_converted(factories, value, message):
    pytest.importorskip("gymnasium")
    with pytest.raises(EnvironmentFailure, match=message):  # by the probes, before a run
        envs.load(f"{factories}:gymnasium_reward", {"value": value}, trial_steps=10)


def test_a_reward_of_numpy_numbers_is_taken():
    for reward in (np.float32(0.5), np.int64(2), np.array(0.25), np.array([1.5]), True):
        assert checked_reward("e", "step", reward) == float(np.asarray(reward).reshape(()))


def test_a_factory_that_requires_its_seed_gets_one(factories):
    spec = f"{factories}:keyword_seed"
    assert envs.load(spec, **DECLARED).base.seed is not None  # unseeded: fresh entropy
    assert envs.load(spec, seed=7, **DECLARED).base.seed == 7
    inferred = envs.load(spec, trial_steps=10).base  # the probes build it too
    assert inferred.seed is not None


@pytest.mark.parametrize("limit, steps", [(20, 20), (7, 7)])
def test_a_time_limit_wrapped_by_a_factory_is_its_time_limit(factories, limit, steps):
    pytest.importorskip("gymnasium")
    env = envs.load(f"{factories}:time_limited", {"limit": limit})
    assert env.steps_per_trial == steps


def test_a_time_limit_beyond_the_longest_trial_asks_for_trial_steps(factories):
    pytest.importorskip("gymnasium")
    with pytest.raises(ValueError, match=r"its time limit in learner steps must be at most"):
        envs.load(f"{factories}:time_limited", {"limit": 10**9})
    env = envs.load(f"{factories}:time_limited", {"limit": 10**9}, trial_steps=50)
    assert env.steps_per_trial == 50


def test_a_control_step_too_short_is_named(factories):
    with pytest.raises(ValueError, match="says its time step is 1e-300 s, less than 1e-06 s"):
        envs.load(f"{factories}:tiny_step", **DECLARED)
    with pytest.raises(ValueError, match=r"control_timestep must be a number of seconds >= 1e-06"):
        envs.load(f"{factories}:tiny_step", control_timestep=1e-300, **DECLARED)
    assert envs.load(f"{factories}:tiny_step", control_timestep=0.01, **DECLARED)


@pytest.mark.parametrize(
    "factory, kwargs, message",
    [
        ("reset_raises", {}, r"its reset \(probed with random actions before the run\) raised"),
        ("step_raises", {}, r"its step \(probed with random actions before the run\) raised"),
        ("late", {"value": float("nan")}, r"\(probed .*\) gave a non-finite observation"),
        ("dict_observation", {}, r"\(probed .*\) gave an observation that is not numbers"),
        ("wrong_size", {}, r"\(probed .*\) gave an observation of 5 numbers"),
    ],
)
def test_the_probes_before_a_run_refuse_the_same_way(factories, factory, kwargs, message):
    with pytest.raises(EnvironmentFailure, match=message):
        envs.load(f"{factories}:{factory}", kwargs, trial_steps=10)  # x inferred: probed


@pytest.mark.parametrize(
    "source, message",
    [
        ("def f(:\n    pass\n", r"its module broken.py raised SyntaxError: .*\(at broken.py:1\)"),
        ("raise RuntimeError('no config')\n", r"raised RuntimeError: no config \(at broken.py:1\)"),
        ("import sys\nsys.exit(0)\n", r"its module broken.py called sys.exit\(0\)"),
    ],
)
def test_a_module_that_fails_on_import_is_one_failure(tmp_path, source, message):
    (tmp_path / "broken.py").write_text(source)
    with pytest.raises(EnvironmentFailure, match=message):
        envs.load(f"{tmp_path / 'broken.py'}:f")
    with pytest.raises(EnvironmentFailure, match=message):  # the same again: not half imported
        envs.load(f"{tmp_path / 'broken.py'}:f")


def test_our_own_refusals_stay_bad_input(factories):
    with pytest.raises(UserInputError, match="cannot import 'no_such_module'"):
        envs.load("no_such_module:f")
    with pytest.raises(EnvironmentFailure) as failure:
        envs.load(f"{factories}:raises")
    assert isinstance(failure.value.__cause__, RuntimeError)  # the traceback a developer reads
    located = failure.value.during("s-ac experiment 3, trial 17")
    assert str(located).endswith("; s-ac experiment 3, trial 17")
    assert located.__cause__ is failure.value.__cause__
