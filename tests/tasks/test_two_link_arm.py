"""The two-link arm: the MJCF model against the rarm benchmark's equations, and the reach task."""

import mujoco
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rmac_mj import tasks
from rmac_mj.models import model_path
from rmac_mj.tasks import two_link_arm

# The benchmark's parameters (ApproxRL `rarm`): lengths, masses, centres of mass, inertias m l^2 / 3
# about the centre of mass, viscous damping, torque limits.
L1, L2, M1, M2 = 0.4, 0.4, 1.25, 0.8
C1, C2 = L1 / 2, L2 / 2
I1, I2 = M1 * L1**2 / 3, M2 * L2**2 / 3
B1, B2 = 0.08, 0.02
TAU_MAX = np.array([1.5, 1.0])
P1 = M1 * C1**2 + M2 * L1**2 + I1
P2 = M2 * C2**2 + I2
P3 = M2 * L1 * C2
DT = 0.05  # the benchmark's sampling time
X0 = np.array([-np.pi / 2, 0.0, np.pi / 2, 0.0])


def mass_matrix(theta2: float) -> np.ndarray:
    c = np.cos(theta2)
    return np.array([[P1 + P2 + 2 * P3 * c, P2 + P3 * c], [P2 + P3 * c, P2]])


def benchmark_ode(t, x, tau):
    """M(q) q'' + C(q, q') q' = tau, x = [theta1, omega1, theta2, omega2] (the benchmark's order)."""
    _, omega1, theta2, omega2 = x
    s = np.sin(theta2)
    coriolis = np.array(
        [[B1 - P3 * omega2 * s, -P3 * (omega1 + omega2) * s], [P3 * omega1 * s, B2]]
    )
    accel = np.linalg.solve(mass_matrix(theta2), tau - coriolis @ np.array([omega1, omega2]))
    return [omega1, accel[0], omega2, accel[1]]


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(model_path("two_link_arm")))


def max_error_against_benchmark(model, x0, torques) -> float:
    """Worst |theta_mujoco - theta_ode| (rad) over a trajectory, torques held over each 0.05 s step."""
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = x0[[0, 2]], x0[[1, 3]]
    n_sub = round(DT / model.opt.timestep)
    x = np.array(x0, dtype=float)
    worst = 0.0
    for tau in torques:
        data.ctrl[:] = tau
        mujoco.mj_step(model, data, n_sub)
        x = solve_ivp(
            benchmark_ode,
            (0.0, DT),
            x,
            args=(np.clip(tau, -TAU_MAX, TAU_MAX),),
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
        ).y[:, -1]
        worst = max(worst, float(np.max(np.abs(data.qpos - x[[0, 2]]))))
    return worst


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("kind", ["uniform", "bang_bang"])
def test_trajectory_matches_benchmark_equations(model, kind, seed):
    """3 s (60 steps) from x_0 under random torques: MuJoCo's RK4 within 1e-4 rad of the ODE."""
    rng = np.random.default_rng(seed)
    draw = rng.uniform(-1, 1, (60, 2)) if kind == "uniform" else rng.choice([-1.0, 1.0], (60, 2))
    assert max_error_against_benchmark(model, X0, draw * TAU_MAX) < 1e-4


def test_out_of_range_torques_are_saturated_like_the_benchmark(model):
    rng = np.random.default_rng(3)
    assert max_error_against_benchmark(model, X0, rng.uniform(-3, 3, (20, 2))) < 1e-4


@pytest.mark.parametrize(
    "q", [(0.0, 0.0), (0.3, 0.7), (-2.0, 2.0), (1.0, -np.pi / 2), (0.0, np.pi)]
)
def test_mass_matrix_is_the_benchmarks(model, q):
    """mj_fullM equals [[P1 + P2 + 2 P3 cos t2, P2 + P3 cos t2], [P2 + P3 cos t2, P2]] everywhere."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    full = np.zeros((2, 2))
    mujoco.mj_fullM(model, data, full)
    np.testing.assert_allclose(full, mass_matrix(q[1]), rtol=0, atol=1e-14)


def test_p1_p2_p3_by_hand(model):
    """P1 = 0.24467, P2 = 0.074667, P3 = 0.064 read back from the mass matrix at t2 = 0 and pi/2."""
    data = mujoco.MjData(model)
    full = np.zeros((2, 2))
    data.qpos[:] = 0.0, np.pi / 2
    mujoco.mj_forward(model, data)
    mujoco.mj_fullM(model, data, full)
    p2 = full[1, 1]
    p1 = full[0, 0] - p2
    data.qpos[:] = 0.0, 0.0
    mujoco.mj_forward(model, data)
    mujoco.mj_fullM(model, data, full)
    p3 = full[0, 1] - p2
    assert p1 == pytest.approx(1.25 * 0.2**2 + 0.8 * 0.4**2 + 1.25 * 0.4**2 / 3, abs=1e-12)
    assert p2 == pytest.approx(0.8 * 0.2**2 + 0.8 * 0.4**2 / 3, abs=1e-12)
    assert p3 == pytest.approx(0.8 * 0.4 * 0.2, abs=1e-12)
    assert (p1, p2, p3) == pytest.approx((0.2446667, 0.0746667, 0.064), abs=1e-7)


def test_model_numbers(model):
    np.testing.assert_allclose(model.dof_damping, [B1, B2])
    np.testing.assert_allclose(model.actuator_ctrlrange, [[-1.5, 1.5], [-1.0, 1.0]])
    assert model.opt.timestep == 0.01 and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    # Gravity along -z and both hinges along z: gravity exerts no torque in any pose.
    data = mujoco.MjData(model)
    for q in [(0.0, 0.0), (1.0, 2.0), (-2.5, 0.4)]:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.qfrc_bias, 0.0, atol=1e-12)


def test_scene_loads_and_renders_the_arm_from_above():
    physics = two_link_arm.Physics.from_xml_string(*two_link_arm.get_model_and_assets())
    assert physics.model.ncam == 1 and physics.model.name2id("top", "camera") == 0
    renderer = mujoco.Renderer(physics.model.ptr, height=120, width=160)
    try:
        renderer.update_scene(physics.data.ptr, camera="top")
        frame = renderer.render()
    finally:
        renderer.close()
    assert frame.shape == (120, 160, 3) and frame.std() > 5.0


def test_random_torques_give_no_mujoco_warning(model):
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for tau in rng.uniform(-2, 2, (600, 2)):
        data.ctrl[:] = tau
        mujoco.mj_step(model, data, 5)
    assert not any(w.number for w in data.warning)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))


# --------------------------------------------------------------------------------------------------
# The reach task


def test_reach_is_60_steps_from_x0():
    env = tasks.load("two_link_arm", "reach")
    timestep = env.reset()
    np.testing.assert_allclose(timestep.observation["position"], [-np.pi / 2, np.pi / 2])
    np.testing.assert_array_equal(timestep.observation["velocity"], [0.0, 0.0])
    np.testing.assert_allclose(
        np.concatenate([timestep.observation[k] for k in env.task.learner_state.keys]), X0
    )
    steps = 0
    while not timestep.last():
        timestep = env.step([0.0, 0.0])
        steps += 1
    assert steps == 60
    assert env.physics.data.time == pytest.approx(3.0)


def test_reward_of_a_hand_worked_state():
    """r = -(1 * 0.5^2 + 0.05 * 2^2 + 1 * 0.3^2 + 0.05 * 1^2) = -0.59, for the state before the step."""
    env = tasks.load("two_link_arm", "reach")
    env.reset()
    with env.physics.reset_context():
        env.physics.set_state_vector(
            [0.5, -2.0, 0.3 - 2 * np.pi, 1.0]
        )  # theta2 wrapped before charged
    assert env.step([1.5, -1.0]).reward == pytest.approx(-0.59, abs=1e-12)
    env = tasks.load("two_link_arm", "reach", task_kwargs={"action_weights": (2.0, 0.5)})
    env.reset()
    with env.physics.reset_context():
        env.physics.set_state_vector([0.0, 0.0, 0.0, 0.0])
    # Torques outside the limits are saturated and charged as applied: 2 * 1.5^2 + 0.5 * 1^2 = 5.
    assert env.step([7.0, -3.0]).reward == pytest.approx(-5.0, abs=1e-12)
    np.testing.assert_array_equal(env.physics.torques(), [1.5, -1.0])


def test_reward_of_matches_the_step_reward_along_a_trajectory():
    env = tasks.load("two_link_arm", "reach")
    env.reset()
    rng = np.random.default_rng(0)
    for tau in rng.uniform(-1, 1, (10, 2)) * TAU_MAX:
        x = env.physics.state()
        reward = env.step(tau).reward
        assert reward == pytest.approx(
            -(x[0] ** 2 + 0.05 * x[1] ** 2 + x[2] ** 2 + 0.05 * x[3] ** 2), abs=1e-12
        )


def test_learner_state_is_the_benchmarks_order():
    env = tasks.load("two_link_arm", "reach")
    env.reset()
    with env.physics.reset_context():
        env.physics.set_state_vector([0.1, 0.2, 0.3, 0.4])
    observation = env.task.get_observation(env.physics)
    hints = env.task.learner_state
    assert hints.keys == ("shoulder", "elbow")
    np.testing.assert_allclose(
        np.concatenate([observation[k] for k in hints.keys]), [0.1, 0.2, 0.3, 0.4]
    )
    np.testing.assert_allclose(observation["position"], [0.1, 0.3])
    np.testing.assert_allclose(observation["velocity"], [0.2, 0.4])
    assert hints.periodic == (True, False, True, False)
    assert len(hints.labels) == 4 and len(hints.action_labels) == 2


def test_start_state_and_noise_kwargs():
    env = tasks.load("two_link_arm", "reach", task_kwargs={"start_state": (0.1, 0.0, -0.2, 0.5)})
    np.testing.assert_allclose(env.reset().observation["shoulder"], [0.1, 0.0])
    np.testing.assert_allclose(env.reset().observation["elbow"], [-0.2, 0.5])
    starts = [
        tasks.load("two_link_arm", "reach", task_kwargs={"start_noise": 0.1, "random": seed})
        .reset()
        .observation["position"]
        for seed in (1, 1, 2)
    ]
    np.testing.assert_array_equal(starts[0], starts[1])
    assert not np.array_equal(starts[0], starts[2])
    assert np.all(np.abs(starts[0] - X0[[0, 2]]) <= 0.1)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"time_limit": 3.02}, "time_limit"),
        ({"control_timestep": 0.015}, "control_timestep"),
        ({"state_weights": (1.0, 0.05, 1.0)}, "state_weights"),
        ({"state_weights": (1.0, -0.05, 1.0, 0.05)}, "state_weights"),
        ({"action_weights": (np.nan, 0.0)}, "action_weights"),
        ({"start_state": (0.0, 0.0)}, "start_state"),
        ({"start_noise": 4.0}, "start_noise"),
    ],
)
def test_bad_task_kwargs_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        tasks.load("two_link_arm", "reach", task_kwargs=kwargs)


def test_full_weight_matrices_are_accepted():
    q = np.diag([1.0, 0.05, 1.0, 0.05])
    env = tasks.load(
        "two_link_arm", "reach", task_kwargs={"state_weights": q, "action_weights": np.eye(2)}
    )
    env.reset()
    assert env.step([1.0, 0.0]).reward == pytest.approx(-(np.pi**2 / 2) - 1.0)


def test_model_path_finds_folder_models_and_single_files():
    from rmac_mj.models import available_models

    assert model_path("two_link_arm").name == "two_link_arm.xml"
    assert model_path("two_link_arm").parent.name == "two_link_arm"
    assert model_path("two_link_arm", scene=True).name == "scene.xml"
    assert model_path("dc_pendulum").is_file()
    assert {"dc_pendulum", "two_link_arm"} <= set(available_models())
    with pytest.raises(ValueError, match="no model named 'cartpole'"):
        model_path("cartpole")
    if not (model_path("dc_pendulum").parent / "scene.xml").is_file():
        with pytest.raises(ValueError, match="no scene.xml"):
            model_path("dc_pendulum", scene=True)


@pytest.mark.slow
def test_a_tiny_reproduce_on_the_arm_end_to_end(tmp_path):
    """Both learners learn the arm through the same runner and command as the pendulum: RMAC with the
    2^2 vertices of its reachable set, S-AC with tile coding over four dimensions."""
    import json

    from rmac_mj.cli import main
    from rmac_mj.results import load_snapshot

    out = tmp_path / "arm"
    assert (
        main(
            [
                "reproduce",
                "--domain",
                "two_link_arm",
                "--task",
                "reach",
                "--algorithms",
                "rmac,s-ac",
                "--experiments",
                "1",
                "--trials",
                "2",
                "--jobs",
                "1",
                "--no-optimal",
                "--no-progress",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trial_seconds"] == pytest.approx(3.0)
    for algorithm in ("rmac", "s-ac"):
        assert len(summary[algorithm]["mean_return_per_trial"]) == 2
    rmac, meta = load_snapshot(out / "snapshots/rmac/exp_000/trial_0002.npz")
    assert meta["domain"] == "two_link_arm" and rmac.vertices.shape == (4, 2)
    sac, _ = load_snapshot(out / "snapshots/s-ac/exp_000/trial_0002.npz")
    assert sac.coder.dim == 4
