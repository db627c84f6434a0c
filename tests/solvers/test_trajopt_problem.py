"""The trial on its model as iLQR sees it (rmac_mj.solvers.trajopt_problem): read from the
environment, its simulated derivatives and its unwrapped states."""

from __future__ import annotations

import numpy as np
import pytest

from rmac_mj import tasks
from rmac_mj.solvers.trajopt_problem import Problem


@pytest.fixture(scope="module")
def arm_problem():
    return Problem(tasks.load("two_link_arm", "reach"), n_threads=1)


def test_problem_reads_horizon_bounds_and_start_from_the_environment(arm_problem):
    p = arm_problem
    assert (p.horizon, p.n_substeps, p.nz) == (60, 5, 4)
    np.testing.assert_array_equal(p.low, [-1.5, -1.0])
    np.testing.assert_array_equal(p.high, [1.5, 1.0])
    assert p.centre_return == pytest.approx(-60 * np.pi**2 / 2)  # at rest at x_0 for 60 steps
    with pytest.raises(ValueError, match="random"):
        Problem(tasks.load("two_link_arm", "reach", task_kwargs={"start_noise": 0.1, "random": 0}))


def test_dynamics_jacobians_predict_small_perturbations(arm_problem):
    p = arm_problem
    rng = np.random.default_rng(0)
    u = rng.uniform(p.low, p.high, (p.horizon, 2)) * 0.9
    z, full, u = p.simulate_policy(
        np.zeros((61, 4)), u, np.zeros_like(u), np.zeros((60, 2, 4)), 0.0
    )
    a, b = p.dynamics_jacobians(full[:5], u[:5], 1e-6)
    for k in range(5):
        dz, du = rng.normal(size=4) * 1e-4, rng.normal(size=2) * 1e-4
        moved = full[k].copy()
        moved[1:5] += dz
        end = p.rollout(moved[None], np.tile(u[k] + du, (1, 5, 1)))[0, -1, 1:5]
        predicted = z[k + 1] + a[k] @ dz + b[k] @ du
        assert np.max(np.abs(end - predicted)) < 1e-7  # second order: |d|^2 ~ 1e-8


def test_cost_expansion_of_the_quadratic_reward_is_exact(arm_problem):
    p = arm_problem
    z = np.random.default_rng(1).normal(size=(61, 4))
    u = np.zeros((60, 2))
    l_z, l_u, l_zz, l_uu, l_uz = p.cost_expansion(z, u, 1e-4)
    q = np.diag([1.0, 0.05, 1.0, 0.05])
    s = p.state_jacobian  # x = S z (up to wrapping)
    x = p.state_of(z[:-1])
    np.testing.assert_allclose(l_zz, np.broadcast_to(2 * s.T @ q @ s, l_zz.shape), atol=1e-6)
    np.testing.assert_allclose(l_z, 2 * x @ q @ s, atol=1e-8)
    np.testing.assert_allclose(l_uu, 0.0, atol=1e-6)  # R = 0
    np.testing.assert_allclose(l_u, 0.0, atol=1e-8)
    np.testing.assert_allclose(l_uz, 0.0, atol=1e-6)


def test_unwrapped_states_count_whole_turns(arm_problem):
    p = arm_problem
    z = p.initial_state[1:5].copy()
    z[0] += 2 * np.pi  # one turn of the shoulder
    np.testing.assert_allclose(p.state_of(z), p.state_of(p.initial_state[1:5]), atol=1e-12)
    assert p.state_of(z, wrap=False)[0] == pytest.approx(-np.pi / 2 + 2 * np.pi)
