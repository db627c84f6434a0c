"""The dynamic programme's grid (rmac_mj.solvers.dynamic_programming_grid): interpolation and
batched transitions."""

from __future__ import annotations

import numpy as np

from rmac_mj import tasks
from rmac_mj.solvers import OptimalConfig
from rmac_mj.solvers import dynamic_programming_grid as dp_grid


def problem() -> dp_grid.Problem:
    return dp_grid.Problem(tasks.load("dc_pendulum", "swingup"))


def test_interpolation_is_bilinear_periodic_in_phi_and_clipped_in_phi_dot():
    config = OptimalConfig(n_phi=8, n_phi_dot=5, max_phi_dot=2.0)
    grid = problem()
    phi, phi_dot = dp_grid.state_grid(config, grid)
    assert phi[0] == -np.pi and phi[-1] < np.pi
    rng = np.random.default_rng(0)
    g = rng.normal(size=8)
    value = g[:, None] + 3.0 * phi_dot[None, :]  # arbitrary in phi, affine in phi_dot
    d_phi = 2 * np.pi / 8
    points = np.array(
        [
            [phi[2], 0.7],  # on a phi node: exact in phi_dot
            [phi[2] + 0.25 * d_phi, -1.3],  # between nodes 2 and 3
            [np.pi - 0.5 * d_phi, 0.0],  # between the last node and -pi (wraps)
            [phi[1] + 4 * np.pi, 0.0],  # two periods away
            [phi[1], 5.0],  # beyond the phi_dot edge: clipped to 2
        ]
    )
    expected = [g[2] + 2.1, 0.75 * g[2] + 0.25 * g[3] - 3.9, 0.5 * (g[7] + g[0]), g[1], g[1] + 6.0]
    np.testing.assert_allclose(
        dp_grid.interpolate_value(config, grid, value, points), expected, atol=1e-12
    )
    weights = dp_grid.interpolation_matrix(config, grid, points)
    assert weights.shape == (5, 40) and np.all(weights.data >= 0)
    np.testing.assert_allclose(np.asarray(weights.sum(axis=1)).ravel(), 1.0)


def test_batched_transitions_match_stepping_one_state_at_a_time():
    import mujoco

    model = problem().model
    rng = np.random.default_rng(1)
    phi, phi_dot, u = rng.uniform(-np.pi, np.pi, 6), rng.uniform(-15, 15, 6), rng.uniform(-3, 3, 6)
    batched = dp_grid.simulate_transitions(
        model, phi, phi_dot, u, n_substeps=3, n_threads=2, chunk=4
    )
    serial = dp_grid.simulate_transitions(model, phi, phi_dot, u, n_substeps=3, n_threads=1)
    np.testing.assert_array_equal(batched, serial)  # threads and chunks never change the numbers
    data = mujoco.MjData(model)
    for k in range(6):
        mujoco.mj_resetData(model, data)
        data.qpos[0], data.qvel[0], data.ctrl[0] = phi[k], phi_dot[k], u[k]
        for _ in range(3):
            mujoco.mj_step(model, data)
        np.testing.assert_allclose(batched[k], [data.qpos[0], data.qvel[0]], rtol=0, atol=1e-12)
