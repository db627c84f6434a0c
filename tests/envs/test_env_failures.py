"""An outside environment that fails (raises, exits, hands back non-finite, absurd or malformed
observations and rewards) is refused as one EnvironmentFailure naming the SPEC, the phase and its own
message, never a bare traceback of the package nor a learner that silently took the value."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from rmac_mj import envs
from rmac_mj.errors import EnvironmentFailure, UserInputError

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
        _steps(envs.load(spec, kwargs, **DECLARED))
    assert f"env '{spec}'" in str(failure.value) and "\n" not in str(failure.value)


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
