"""The dc_pendulum tasks: rewards, episode length, start states, errors (the contract every task
meets, dm_env conformance and seeding included, is tests/tasks/test_suite_contract.py)."""

import mujoco
import numpy as np
import pytest

from rmac_mj import tasks


def test_registry_mirrors_dm_control_suite():
    assert ("dc_pendulum", "swingup") in tasks.ALL_TASKS
    assert ("dc_pendulum", "balance") in tasks.ALL_TASKS
    assert set(tasks.TASKS_BY_DOMAIN["dc_pendulum"]) == {"swingup", "balance"}
    with pytest.raises(ValueError, match="unknown domain_name"):
        tasks.load("cartpole", "swingup")
    with pytest.raises(ValueError, match="unknown task_name"):
        tasks.load("dc_pendulum", "spin")


def test_swingup_is_exactly_100_steps_and_starts_down():
    env = tasks.load("dc_pendulum", "swingup")
    timestep = env.reset()
    assert timestep.first()
    assert timestep.observation["angle"][0] == pytest.approx(-np.pi)  # pi, wrapped to [-pi, pi)
    assert timestep.observation["velocity"][0] == 0.0
    np.testing.assert_allclose(timestep.observation["orientation"], [-1.0, 0.0], atol=1e-12)
    steps = 0
    while not timestep.last():
        timestep = env.step([0.0])
        steps += 1
    assert steps == 100
    assert env.physics.data.time == pytest.approx(3.0)
    assert env.reset().observation["angle"][0] == pytest.approx(-np.pi)


def test_reward_of_known_state_and_action_by_hand():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    with env.physics.reset_context():
        env.physics.set_state_vector(0.5, -2.0)
    timestep = env.step([1.5])
    assert timestep.reward == pytest.approx(-(5 * 0.5**2 + 0.1 * 2.0**2) - 1.0 * 1.5**2)
    # phi is wrapped before it is charged: 2 pi - 0.5 costs what -0.5 costs.
    with env.physics.reset_context():
        env.physics.set_state_vector(2 * np.pi - 0.5, 0.0)
    assert env.step([0.0]).reward == pytest.approx(-5 * 0.5**2)


def test_out_of_range_voltage_is_saturated_and_charged_as_applied():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    reward = env.step([7.0]).reward
    assert env.physics.voltage() == 3.0
    assert reward == pytest.approx(-5 * np.pi**2 - 9.0)
    reference = tasks.load("dc_pendulum", "swingup")
    reference.reset()
    reference.step([3.0])
    assert env.physics.state() == pytest.approx(reference.physics.state())


def test_physics_named_accessors():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    with env.physics.reset_context():
        env.physics.set_state_vector(3 * np.pi + 0.25, 4.0)
    physics = env.physics
    assert physics.angle() == pytest.approx(-np.pi + 0.25)
    assert physics.angular_velocity() == 4.0
    env.step([2.0])
    physics.forward()  # actuator_force is otherwise from the last substep's first RK4 stage
    assert physics.voltage() == 2.0
    K, R = 0.0536, 9.5
    assert physics.motor_torque() == pytest.approx(
        K / R * 2.0 - K * K / R * physics.angular_velocity()
    )


@pytest.mark.parametrize(
    "action, match",
    [([np.nan], "finite"), ([np.inf], "finite"), ([1.0, 2.0], "shape"), ([[1.0]], "shape")],
)
def test_bad_actions_raise_before_stepping(action, match):
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    with pytest.raises(ValueError, match=match):
        env.step(action)
    assert env.physics.data.time == 0.0


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"time_limit": -1.0}, "time_limit"),
        ({"time_limit": 3.01}, "time_limit"),
        ({"control_timestep": 0.025}, "control_timestep"),
        ({"control_timestep": 0.0}, "control_timestep"),
        ({"state_weights": (1.0, -1.0)}, "state_weights"),
        ({"state_weights": (1.0,)}, "state_weights"),
        ({"action_weights": np.nan}, "action_weights"),
        ({"start_state": (0.0,)}, "start_state"),
        ({"start_noise": -0.1}, "start_noise"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_bad_task_kwargs_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        tasks.load("dc_pendulum", "swingup", task_kwargs=kwargs)


def test_task_kwargs_change_the_task():
    env = tasks.load(
        "dc_pendulum",
        "swingup",
        task_kwargs={
            "time_limit": 1.5,
            "control_timestep": 0.05,
            "state_weights": (1, 0),
            "action_weights": 0.0,
            "start_state": (1.0, 0.0),
        },
    )
    timestep = env.reset()
    assert timestep.observation["angle"][0] == pytest.approx(1.0)
    rewards = []
    while not timestep.last():
        timestep = env.step([0.0])
        rewards.append(timestep.reward)
    assert len(rewards) == 30
    assert rewards[0] == pytest.approx(-1.0)


def test_balance_starts_near_upright_with_seeded_noise():
    starts = []
    for seed in (1, 1, 2):
        env = tasks.load("dc_pendulum", "balance", task_kwargs={"random": seed})
        starts.append(env.reset().observation["angle"][0])
    assert starts[0] == starts[1] != starts[2]
    assert all(0 < abs(s) <= 0.1 for s in starts)


def test_one_frame_renders_offscreen_and_is_not_blank():
    env = tasks.load("dc_pendulum", "swingup")
    env.reset()
    renderer = mujoco.Renderer(env.physics.model.ptr, height=120, width=160)
    try:
        renderer.update_scene(env.physics.data.ptr, camera="front")
        frame = renderer.render()
    finally:
        renderer.close()
    assert frame.shape == (120, 160, 3)
    assert frame.std() > 5.0  # not a uniform colour
