"""Iterative LQR with control limits (box-constrained DDP; Li and Todorov 2004, Tassa, Mansard and
Todorov 2014) on a :class:`~rmac_mj.solvers.trajopt_problem.Problem`.

Around the current trajectory the dynamics are linearised and the reward expanded to second order; a
backward Riccati pass gives a time-varying affine policy du_k = k_k + K_k dz_k whose feed-forward part
solves a small box-constrained QP per step (so saturated actions get no feedback); a forward pass
simulates that policy on the model, with a line search on k_k and Levenberg-Marquardt regularisation of
the value Hessian. Unlike single shooting over the open-loop sequence, the forward pass applies the
feedback gains, which keeps the rollouts near the linearisation where the return depends exponentially
on early actions (balancing near an unstable upright; docs/optimal.md).
"""

from __future__ import annotations

import itertools
from typing import Protocol

import numpy as np

from rmac_mj.solvers.trajopt_problem import Problem


class Settings(Protocol):
    """What iLQR reads of its settings (:class:`~rmac_mj.solvers.trajopt.TrajoptConfig`'s)."""

    max_iterations: int
    tolerance: float
    fd_step: float
    reward_fd_step: float


def box_qp(
    hessian: np.ndarray, gradient: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """argmin_d 0.5 d^T H d + g^T d subject to lower <= d <= upper, for a small positive definite H.

    The minimum of a convex quadratic over a box is a stationary point of one face; every face (each
    dimension free, at its lower or at its upper bound: 3^m faces) is tried and the best feasible kept.

    Returns:
      d of shape (m,) and the boolean mask of its free (not clamped) dimensions.
    """
    m = gradient.size
    if m == 1:  # the common case in closed form
        d = min(max(-gradient[0] / hessian[0, 0], lower[0]), upper[0])
        return np.array([d]), np.array([lower[0] < d < upper[0]])
    d = np.linalg.solve(hessian, -gradient)
    if np.all(d >= lower) and np.all(d <= upper):
        return d, np.ones(m, dtype=bool)  # the unconstrained minimum lies inside the box
    best, best_value, best_free = None, np.inf, None
    for faces in itertools.product((0, 1, 2), repeat=m):
        faces = np.array(faces)
        free = faces == 0
        d = np.where(faces == 1, lower, upper).astype(float)
        if free.any():
            fixed = ~free
            rhs = -(gradient[free] + hessian[np.ix_(free, fixed)] @ d[fixed])
            d[free] = np.linalg.solve(hessian[np.ix_(free, free)], rhs)
            if np.any(d[free] < lower[free] - 1e-12) or np.any(d[free] > upper[free] + 1e-12):
                continue
        value = 0.5 * d @ hessian @ d + gradient @ d
        if value < best_value - 1e-15:
            best, best_value, best_free = np.clip(d, lower, upper), value, free
    return best, best_free


def _backward_pass(problem: Problem, derivatives, u: np.ndarray, mu: float):
    """Riccati recursion of the cost (minus the reward). Returns (k, K, expected) or None if mu is too
    small for a positive definite Q_uu."""
    a, b, l_z, l_u, l_zz, l_uu, l_uz = derivatives
    horizon, nz, m = u.shape[0], problem.nz, problem.low.size
    v_z, v_zz = np.zeros(nz), np.zeros((nz, nz))
    feedforward, gains = np.zeros((horizon, m)), np.zeros((horizon, m, nz))
    expected = np.zeros(2)
    regulariser = mu * np.eye(nz)
    for k in range(horizon - 1, -1, -1):
        q_z = l_z[k] + a[k].T @ v_z
        q_u = l_u[k] + b[k].T @ v_z
        q_zz = l_zz[k] + a[k].T @ v_zz @ a[k]
        q_uu = l_uu[k] + b[k].T @ v_zz @ b[k]
        q_uz = l_uz[k] + b[k].T @ v_zz @ a[k]
        v_reg = v_zz + regulariser
        q_uu_reg = l_uu[k] + b[k].T @ v_reg @ b[k]
        q_uu_reg = (q_uu_reg + q_uu_reg.T) / 2
        q_uz_reg = l_uz[k] + b[k].T @ v_reg @ a[k]
        try:
            np.linalg.cholesky(q_uu_reg)
        except np.linalg.LinAlgError:
            return None
        d, free = box_qp(q_uu_reg, q_u, problem.low - u[k], problem.high - u[k])
        gain = np.zeros((m, nz))
        if free.any():
            gain[free] = -np.linalg.solve(q_uu_reg[np.ix_(free, free)], q_uz_reg[free])
        feedforward[k], gains[k] = d, gain
        expected += (d @ q_u, 0.5 * d @ q_uu @ d)
        v_z = q_z + gain.T @ q_uu @ d + gain.T @ q_u + q_uz.T @ d
        v_zz = q_zz + gain.T @ q_uu @ gain + gain.T @ q_uz + q_uz.T @ gain
        v_zz = (v_zz + v_zz.T) / 2
    return feedforward, gains, expected


def ilqr(
    problem: Problem, actions: np.ndarray, config: Settings, wrap: bool = True
) -> tuple[np.ndarray, float, int, str]:
    """Improve an action sequence of shape (h, m) by iLQR; return (actions, return, iterations, why).

    h <= H: a shorter sequence optimises the sum of the first h rewards of the trial. ``wrap=False``
    charges the rewards of unwrapped states (``Problem.state_of``).
    """
    alphas = 10.0 ** np.linspace(0, -3, 11)
    # Levenberg-Marquardt regularisation of V_zz, adapted as in Tassa, Erez and Todorov (2012): it grows
    # by factors 1.6, 1.6^2, ... after a failed step and shrinks likewise after a successful one.
    mu, mu_factor, mu_min, mu_max = 1.0, 1.0, 1e-6, 1e10
    u = np.clip(actions, problem.low, problem.high)
    zero_gains = np.zeros((u.shape[0], problem.low.size, problem.nz))
    z, full, u = problem.simulate_policy(
        np.zeros((u.shape[0] + 1, problem.nz)), u, np.zeros_like(u), zero_gains, 0.0
    )
    value = problem.returns_of(z, u, wrap)
    why = "max_iterations"
    for iteration in range(1, config.max_iterations + 1):
        derivatives = (
            *problem.dynamics_jacobians(full, u, config.fd_step),
            *problem.cost_expansion(z, u, config.reward_fd_step, wrap),
        )
        accepted = False
        while not accepted:
            backward = _backward_pass(problem, derivatives, u, mu)
            if backward is None:  # Q_uu not positive definite: regularise more
                mu_factor = max(mu_factor * 1.6, 1.6)
                mu = max(mu * mu_factor, mu_min)
                if mu > mu_max:
                    return u, value, iteration, "regularisation"
                continue
            feedforward, gains, expected = backward
            # The quadratic model's predicted gain of the full step (cost decrease = return increase).
            predicted = -(expected[0] + expected[1])
            if predicted < config.tolerance * (1.0 + abs(value)):
                return u, value, iteration, "converged"  # the model sees nothing left to gain
            for alpha in alphas:
                z_new, full_new, u_new = problem.simulate_policy(z, u, feedforward, gains, alpha)
                new = problem.returns_of(z_new, u_new, wrap)
                # Accept a step that realises a fair part of the gain its model predicts.
                if new - value > 0.1 * -(alpha * expected[0] + alpha * alpha * expected[1]):
                    accepted = True
                    break
            if not accepted:
                mu_factor = max(mu_factor * 1.6, 1.6)
                mu = max(mu * mu_factor, mu_min)
                if mu > mu_max:
                    return u, value, iteration, "regularisation"
        z, full, u, value = z_new, full_new, u_new, new
        mu_factor = min(mu_factor / 1.6, 1 / 1.6)
        mu = mu * mu_factor if mu * mu_factor > mu_min else 0.0
    return u, value, iteration, why
