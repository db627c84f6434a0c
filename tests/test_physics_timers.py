"""MuJoCo's profiling timers off (``_physics_timers.untimed``): the same trajectories to the bit,
no clock read inside the block, the bindings' clock back after it."""

from __future__ import annotations

import threading

import mujoco
import numpy as np

from rmac_mj import _physics_timers, tasks


def _trajectory(env, actions):
    env.reset()
    states = []
    for u in actions:
        env.step(u)
        states.append(env.physics.get_state().copy())
    return np.array(states)


def _step_time(physics) -> float:
    return float(physics.data.timer[int(mujoco.mjtTimer.mjTIMER_STEP)].duration)


def test_the_library_global_is_found():
    assert _physics_timers._callback() is not None


def test_the_same_trajectories_without_timers_and_no_clock_read():
    for domain, task in (("dc_pendulum", "swingup"), ("two_link_arm", "reach")):
        env = tasks.load(domain, task)
        spec = env.action_spec()
        actions = np.random.default_rng(0).uniform(spec.minimum, spec.maximum, (100, *spec.shape))
        timed = _trajectory(env, actions)
        assert _step_time(env.physics) > 0.0  # the bindings' clock runs outside the block
        with _physics_timers.untimed():
            untimed = _trajectory(env, actions)
            assert _step_time(env.physics) == 0.0  # reset zeroes the timers; no clock read since
        np.testing.assert_array_equal(untimed, timed)


def test_nested_and_concurrent_blocks_put_the_clock_back_after_the_last():
    callback = _physics_timers._callback()
    clock = callback.value
    entered, release = threading.Event(), threading.Event()

    def other():
        with _physics_timers.untimed():
            entered.set()
            release.wait(5)

    thread = threading.Thread(target=other)
    with _physics_timers.untimed():
        assert callback.value is None
        thread.start()
        entered.wait(5)
        with _physics_timers.untimed():
            assert callback.value is None
        assert callback.value is None
    assert callback.value is None  # the other thread's block is still open
    release.set()
    thread.join(5)
    assert callback.value == clock
