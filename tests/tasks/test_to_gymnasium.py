"""The suite as Gymnasium environments: registered ids, Gymnasium's checker, and the very same
episodes as the dm-control tasks."""

import numpy as np
import pytest

gymnasium = pytest.importorskip(
    "gymnasium",
    reason='needs the [gymnasium] extra: pip install -c constraints.txt -e ".[gymnasium]"',
)

from gymnasium.utils.env_checker import check_env  # noqa: E402

from rmac_mj import tasks  # noqa: E402
from rmac_mj.rollout import state_of, steps_per_trial  # noqa: E402
from rmac_mj.tasks import to_gymnasium as gymnasium_env

IDS = [gymnasium_env.env_id(domain, task) for domain, task in tasks.ALL_TASKS]


def test_every_task_of_the_suite_is_registered():
    assert "rmac_mj/DCPendulum-Swingup-v0" in IDS and "rmac_mj/TwoLinkArm-Reach-v0" in IDS
    assert len(set(IDS)) == len(tasks.ALL_TASKS)
    for name in IDS:
        assert name in gymnasium.registry


#: What Gymnasium's checker may advise and the suite declines: the tasks keep their own action units
#: (volts, newton-metres), and speeds have no hard bound.
ADVICE = (
    "symmetric and normalized space",
    "minimum value is -infinity",
    "maximum value is infinity",
)


@pytest.mark.parametrize("name", IDS)
def test_gymnasiums_checker_passes(name):
    """No error, and no warning but the known advice (the checker reports real problems, e.g. an
    observation outside its space or a seed that does not repeat the reset, as warnings)."""
    import warnings

    env = gymnasium.make(name)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)  # rendering: its own test below
    unexpected = [str(w.message) for w in caught if not any(a in str(w.message) for a in ADVICE)]
    assert not unexpected


@pytest.mark.parametrize("domain, task", tasks.ALL_TASKS)
def test_an_episode_equals_the_dm_control_episode_step_for_step(domain, task):
    """Same seed, same actions: the same observations (x with periodic entries as cos, sin), rewards
    and trial length, and the trial ends as a truncation."""
    env = gymnasium.make(
        gymnasium_env.env_id(domain, task),
        task_kwargs={"start_noise": 0.1} if task != "balance" else None,
    )
    reference = tasks.load(
        domain,
        task,
        task_kwargs={"random": 5, **({"start_noise": 0.1} if task != "balance" else {})},
    )
    learner_state = reference.task.learner_state
    periodic = np.asarray(learner_state.periodic)

    def expected(timestep):
        x = state_of(timestep.observation, learner_state)
        return np.concatenate([[np.cos(v), np.sin(v)] if p else [v] for v, p in zip(x, periodic)])

    observation, _ = env.reset(seed=5)
    timestep = reference.reset()
    np.testing.assert_array_equal(observation, expected(timestep))
    rng = np.random.default_rng(0)
    low, high = env.action_space.low, env.action_space.high
    steps = 0
    while True:
        action = rng.uniform(low, high).astype(np.float32)
        observation, reward, terminated, truncated, _ = env.step(action)
        timestep = reference.step(action.astype(np.float64))
        steps += 1
        np.testing.assert_array_equal(observation, expected(timestep))
        assert reward == timestep.reward and not terminated
        assert truncated == timestep.last()
        if truncated:
            break
    assert steps == steps_per_trial(reference)


def test_seeding_repeats_the_start_and_continues_the_stream():
    env = gymnasium.make("rmac_mj/TwoLinkArm-Reach-v0", task_kwargs={"start_noise": 0.3})
    first, _ = env.reset(seed=3)
    second, _ = env.reset()
    again, _ = env.reset(seed=3)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, second)  # the task's random start, drawn afresh


def test_rgb_array_rendering_draws_the_current_state():
    env = gymnasium.make(
        "rmac_mj/DCPendulum-Swingup-v0", render_mode="rgb_array", width=64, height=48
    )
    env.reset(seed=0)
    hanging = env.render()
    assert hanging.shape == (48, 64, 3) and hanging.dtype == np.uint8
    for _ in range(40):
        env.step(np.array([3.0], dtype=np.float32))
    assert not np.array_equal(env.render(), hanging)
    env.close()
    with pytest.raises(ValueError, match="render_mode"):
        gymnasium_env.SuiteEnv("dc_pendulum", "swingup", render_mode="depth_array")
