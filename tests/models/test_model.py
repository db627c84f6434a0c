"""The MJCF model as a model: Table 1 read back, and trajectories against the paper's ODE."""

import mujoco
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rmac_mj.models import model_path

# Table 1 of the paper.
J, M, G, L, B, K, R = 1.91e-4, 0.055, 9.81, 0.042, 3e-6, 0.0536, 9.5
CONTROL_DT = 0.03


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_path(str(model_path("dc_pendulum")))


def ode(t, y, u):
    """J phi'' = M g l sin(phi) - (b + K^2/R) phi' + (K/R) u  (section 6)."""
    phi, phi_dot = y
    return [phi_dot, (M * G * L * np.sin(phi) - (B + K * K / R) * phi_dot + K / R * u) / J]


def max_error_against_ode(model, x0, voltages):
    data = mujoco.MjData(model)
    data.qpos[0], data.qvel[0] = x0
    n_sub = round(CONTROL_DT / model.opt.timestep)
    y = np.array(x0, dtype=float)
    worst = 0.0
    for u in voltages:
        data.ctrl[0] = u
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
        y = solve_ivp(
            ode, (0.0, CONTROL_DT), y, args=(u,), method="DOP853", rtol=1e-12, atol=1e-12
        ).y[:, -1]
        worst = max(worst, abs(data.qpos[0] - y[0]))
    return worst


@pytest.mark.parametrize(
    "case",
    [
        "free_near_upright",
        "constant_3V_from_down",
        "random_uniform_0",
        "random_uniform_1",
        "random_uniform_2",
    ],
)
def test_trajectory_matches_equation_of_motion(model, case):
    rng = np.random.default_rng(int(case[-1]) if case[-1].isdigit() else 0)
    x0, voltages = {
        "free_near_upright": ((0.05, 0.0), np.zeros(100)),
        "constant_3V_from_down": ((np.pi, 0.0), np.full(100, 3.0)),
    }.get(case, ((np.pi, 0.0), rng.uniform(-3, 3, 100)))
    assert max_error_against_ode(model, x0, voltages) < 1e-4  # rad, over a 3 s trial


def test_each_control_step_matches_equation_of_motion_under_bang_bang(model):
    """Per-step error, ODE restarted from MuJoCo's state: the integrator's own accuracy.

    Over whole trajectories that hover near the unstable upright any difference grows like
    exp(sqrt(M g l / J) t) = exp(10.9 t), so the per-step error is the bound that holds for every
    voltage sequence (see models/dc_pendulum/README.md).
    """
    data = mujoco.MjData(model)
    data.qpos[0] = np.pi
    n_sub = round(CONTROL_DT / model.opt.timestep)
    rng = np.random.default_rng(0)
    worst = 0.0
    for u in rng.choice([-3.0, 3.0], 300):
        data.ctrl[0] = u
        y0 = np.array([data.qpos[0], data.qvel[0]])
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
        y = solve_ivp(
            ode, (0.0, CONTROL_DT), y0, args=(u,), method="DOP853", rtol=1e-12, atol=1e-12
        ).y[:, -1]
        worst = max(worst, abs(data.qpos[0] - y[0]))
    assert worst < 5e-6  # rad per 0.03 s step (measured: 1.3e-6)


def test_parameters_read_back_equal_table_1(model):
    body = model.body("pendulum")
    assert body.mass[0] == pytest.approx(M)
    assert np.linalg.norm(body.ipos) == pytest.approx(L)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    inertia = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, inertia)
    assert inertia[0, 0] == pytest.approx(J, rel=1e-9)  # inertia about the axis
    assert model.dof_damping[0] == pytest.approx(B)
    assert model.opt.gravity[2] == pytest.approx(-G)
    assert tuple(model.actuator_ctrlrange[0]) == (-3.0, 3.0)
    assert model.actuator_ctrllimited[0]


@pytest.mark.parametrize("u, phi_dot", [(3.0, 0.0), (-1.5, 0.0), (0.0, 10.0), (2.0, -7.0)])
def test_motor_torque_is_gain_and_back_emf(model, u, phi_dot):
    data = mujoco.MjData(model)
    data.qvel[0] = phi_dot
    data.ctrl[0] = u
    mujoco.mj_forward(model, data)
    assert data.actuator_force[0] == pytest.approx(
        K / R * u - K * K / R * phi_dot, rel=1e-9, abs=1e-12
    )


def test_visual_geoms_have_no_mass_and_no_contacts(model):
    assert np.all(model.geom_contype == 0) and np.all(model.geom_conaffinity == 0)
    assert model.body("pendulum").mass[0] == pytest.approx(M)  # geoms add nothing to Table 1's mass


def test_zero_is_upright_and_pi_hangs_down(model):
    data = mujoco.MjData(model)
    for phi, z_sign in [(0.0, 1.0), (np.pi, -1.0)]:
        data.qpos[0] = phi
        mujoco.mj_forward(model, data)
        com_height = (
            data.xipos[model.body("pendulum").id][2] - data.xpos[model.body("pendulum").id][2]
        )
        assert com_height == pytest.approx(z_sign * L)


def test_model_simulates_without_warnings(model):
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    for _ in range(1000):
        data.ctrl[0] = rng.uniform(-3, 3)
        mujoco.mj_step(model, data)
    assert np.all(data.warning.number == 0)


def test_scene_adds_floor_light_and_camera_but_not_dynamics(model):
    """scene.xml (what the tasks simulate) steps bit for bit like the bare model."""
    scene = mujoco.MjModel.from_xml_path(str(model_path("dc_pendulum", scene=True)))
    assert scene.camera("front").id >= 0 and scene.geom("floor").id >= 0
    assert scene.vis.global_.offwidth == 640 and scene.vis.global_.offheight == 480
    with pytest.raises(KeyError):
        model.camera("front")  # the camera belongs to the scene
    datas = [mujoco.MjData(model), mujoco.MjData(scene)]
    rng = np.random.default_rng(1)
    for data in datas:
        data.qpos[0] = np.pi
    for u in rng.uniform(-3, 3, 300):
        for m, data in zip((model, scene), datas):
            data.ctrl[0] = u
            mujoco.mj_step(m, data)
        assert datas[0].qpos[0] == datas[1].qpos[0] and datas[0].qvel[0] == datas[1].qvel[0]
    assert np.all(datas[1].warning.number == 0)
