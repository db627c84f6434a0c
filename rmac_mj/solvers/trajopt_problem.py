"""The trial of a deterministic task as iLQR sees it: its own MuJoCo model, simulated in batches, and
the derivatives of the dynamics and the reward.

With z = [qpos, qvel] and x = s(z) the task's state (``physics.state_of``, angles wrapped), one control
step is z_k = f(z_{k-1}, u_{k-1}) (the action held over the physics substeps) and the reward is the
task's own r_k = rho(x_{k-1}, u_{k-1}) (``task.reward_of``); no formula of a task is repeated here.

- *Dynamics* A_k = df/dz, B_k = df/du by central finite differences of one control step, every
  perturbed (state, action) pair of the whole horizon simulated in one ``mujoco.rollout`` call
  (one-sided in an action at its bound, so no perturbed action saturates).
- *Reward* gradient and Hessian by central differences of ``task.reward_of`` in x (batched), chained
  through the Jacobian of ``state_of``, which is linear in z up to the wrapping of angles.
"""

from __future__ import annotations

import itertools
import os

import mujoco
import numpy as np
from dm_control.rl import control
from mujoco import rollout

from rmac_mj.solvers.problem import TrialProblem

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: Largest action dimension: the per-step box QP enumerates the 3^m faces of the box.
MAX_ACTION_DIM = 4


class Problem(TrialProblem):
    """The trial of a deterministic dm-control environment as an optimal-control problem on its model.

    The task must provide ``reward_of(x, u)`` and its physics ``state_of(qpos, qvel)`` (both batched),
    the actuators must saturate to the action spec's bounds, the joints must be hinges or slides
    (qpos and qvel of equal size, no activation state) and every reset must give the same state.

    Attributes:
      horizon: H, control steps per trial (counted by stepping the environment).
      n_substeps: physics steps per control step.
      low, high: ndarrays of shape (m,): the action box.
      initial_state: the model's full physics state at the start (``mj_getState``, FULLPHYSICS).
    """

    owner = "trajopt"

    def __init__(self, env: control.Environment, n_threads: int = 0):
        super().__init__(env)
        physics = env.physics
        model = self.model
        if model.nq != model.nv or model.na != 0:
            raise ValueError(
                f"trajopt: needs hinge or slide joints and no activation state, got "
                f"nq={model.nq}, nv={model.nv}, na={model.na}"
            )
        spec = env.action_spec()
        self.low = np.broadcast_to(np.asarray(spec.minimum, dtype=float), spec.shape).copy()
        self.high = np.broadcast_to(np.asarray(spec.maximum, dtype=float), spec.shape).copy()
        if spec.shape != (model.nu,) or not (
            np.all(np.isfinite(self.low))
            and np.all(np.isfinite(self.high))
            and np.all(self.low < self.high)
        ):
            raise ValueError(
                f"trajopt: the action spec must be a finite box of shape (nu,) = "
                f"({model.nu},), got {spec}"
            )
        if model.nu > MAX_ACTION_DIM:
            raise ValueError(f"trajopt: at most {MAX_ACTION_DIM} actions, got {model.nu}")
        # The trial's length from the environment itself: run it once with the box's centre.
        timestep = env.reset()
        self.initial_state = self._full_state(physics.data.ptr)
        self.horizon, self.centre_return = 0, 0.0
        centre = (self.low + self.high) / 2
        while not timestep.last():
            timestep = env.step(centre)
            self.centre_return += float(timestep.reward)
            self.horizon += 1
        self._check_deterministic_start(self.initial_state)
        self.nz = model.nq + model.nv
        self._z = slice(1, 1 + self.nz)  # the full physics state is [time, qpos, qvel, ...]
        # state_of is linear in z = [qpos, qvel] up to the wrapping of angles: its Jacobian, read at
        # z = 0 (far from any wrap) by differences of 1, is exact.
        zero = np.zeros((1 + self.nz, self.nz))
        zero[1:] = np.eye(self.nz)
        xs = self.state_of(zero)
        self.state_jacobian = (xs[1:] - xs[0]).T  # (n, nz)
        self.n = self.state_jacobian.shape[0]
        self._z0 = self.initial_state[self._z].copy()
        self._x0 = self.state_of(self._z0)
        threads = n_threads or os.cpu_count() or 1
        self._datas = [mujoco.MjData(model) for _ in range(threads)]
        self._data = mujoco.MjData(model)

    def state_of(self, z: np.ndarray, wrap: bool = True) -> np.ndarray:
        """The task's x of physics states z = [qpos, qvel] of shape (..., nz); shape (..., n).

        With ``wrap=False``, x is continued from x_0 without wrapping (x_0 + S (z - z_0)): the angles
        then count whole turns, so a trajectory that loops around is charged for it.
        """
        if not wrap:
            return self._x0 + (z - self._z0) @ self.state_jacobian.T
        nq = self.model.nq
        return np.asarray(self.env.physics.state_of(z[..., :nq], z[..., nq:]), dtype=float)

    def returns_of(self, z: np.ndarray, u: np.ndarray, wrap: bool = True) -> float:
        """Sum of the rewards of a trajectory: z of shape (h + 1, nz), u of shape (h, m)."""
        return float(self.env.task.reward_of(self.state_of(z[:-1], wrap), u).sum())

    def rollout(self, initial: np.ndarray, control: np.ndarray) -> np.ndarray:
        """``mujoco.rollout`` of full physics states ``initial`` (B, nstate) under ``control``
        (B, steps, m), on this problem's threads: the states after every physics step."""
        datas = self._datas if len(self._datas) > 1 else self._datas[0]
        states, _ = rollout.rollout(self.model, datas, initial, control)
        return states

    def trajectories(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Replay many action sequences open-loop from x_0 (batched).

        Args:
          actions: ndarray of shape (B, H, m), inside the action box.
        Returns:
          states x_0..x_H of shape (B, H + 1, n) and rewards r_1..r_H of shape (B, H).
        """
        control = np.repeat(actions, self.n_substeps, axis=1)  # held over the substeps
        ends = self.rollout(self.initial_state, control)[:, self.n_substeps - 1 :: self.n_substeps]
        z0 = np.broadcast_to(self.initial_state[self._z], (actions.shape[0], 1, self.nz))
        states = self.state_of(np.concatenate([z0, ends[..., self._z]], axis=1))
        return states, self.env.task.reward_of(states[:, :-1], actions)

    def simulate_policy(
        self,
        z_ref: np.ndarray,
        u_ref: np.ndarray,
        feedforward: np.ndarray,
        gains: np.ndarray,
        alpha: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One forward pass: u_k = clip(u_ref_k + alpha k_k + K_k (z_k - z_ref_k)) simulated from x_0.

        Returns:
          physics states z of shape (H + 1, nz), full states of shape (H, nstate) before each step, and
          applied actions of shape (H, m).
        """
        model, data = self.model, self._data
        mujoco.mj_setState(model, data, self.initial_state, _FULL)
        horizon = u_ref.shape[0]
        z = np.empty((horizon + 1, self.nz))
        full = np.empty((horizon, self.initial_state.size))
        u = np.empty_like(u_ref)
        nq = model.nq
        for k in range(horizon):
            z[k, :nq], z[k, nq:] = data.qpos, data.qvel
            mujoco.mj_getState(model, data, full[k], _FULL)
            u[k] = np.clip(
                u_ref[k] + alpha * feedforward[k] + gains[k] @ (z[k] - z_ref[k]),
                self.low,
                self.high,
            )
            data.ctrl[:] = u[k]
            mujoco.mj_step(model, data, self.n_substeps)
        z[-1, :nq], z[-1, nq:] = data.qpos, data.qvel
        return z, full, u

    def dynamics_jacobians(
        self, full: np.ndarray, u: np.ndarray, step: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """A_k = df/dz of shape (H, nz, nz) and B_k = df/du of shape (H, nz, m) by central differences.

        All 2 (nz + m) perturbed control steps of every k run in one batched rollout; an action at a
        bound is perturbed one-sidedly, inwards.
        """
        horizon, nz, m = u.shape[0], self.nz, self.low.size
        dz = np.eye(nz) * step
        du_up = (
            np.minimum(u[:, None, :] + np.eye(m) * step * (self.high - self.low), self.high)
            - u[:, None, :]
        )
        du_down = (
            np.maximum(u[:, None, :] - np.eye(m) * step * (self.high - self.low), self.low)
            - u[:, None, :]
        )
        rows = 2 * nz + 2 * m
        initial = np.repeat(full[:, None, :], rows, axis=1)  # (H, rows, nstate)
        initial[:, :nz, self._z] += dz
        initial[:, nz : 2 * nz, self._z] -= dz
        controls = np.repeat(u[:, None, :], rows, axis=1)
        controls[:, 2 * nz : 2 * nz + m] += du_up
        controls[:, 2 * nz + m :] += du_down
        ends = self.rollout(
            initial.reshape(horizon * rows, -1),
            np.repeat(controls.reshape(horizon * rows, 1, m), self.n_substeps, axis=1),
        )
        z_next = ends[:, -1, self._z].reshape(horizon, rows, nz)
        a = (z_next[:, :nz] - z_next[:, nz : 2 * nz]).transpose(0, 2, 1) / (2 * step)
        width = np.einsum("kjj->kj", du_up - du_down)  # (H, m)
        b = (z_next[:, 2 * nz : 2 * nz + m] - z_next[:, 2 * nz + m :]).transpose(0, 2, 1) / width[
            :, None, :
        ]
        return a, b

    def cost_expansion(self, z: np.ndarray, u: np.ndarray, step: float, wrap: bool = True):
        """Gradient and Hessian of the cost l = -rho(s(z), u) at every step, by central differences in x.

        Returns:
          l_z (H, nz), l_u (H, m), l_zz (H, nz, nz), l_uu (H, m, m), l_uz (H, m, nz).
        """
        x = self.state_of(z[:-1], wrap)
        y = np.concatenate([x, u], axis=1)  # (H, n + m)
        n, d = self.n, y.shape[1]
        e = np.eye(d) * step
        # Perturbations: +-e_i (gradient) and +-e_i +-e_j (Hessian), all evaluated in one call.
        signs = np.array(list(itertools.product((1.0, -1.0), repeat=2)))  # (4, 2)
        pairs = (
            signs[:, 0, None, None, None] * e[None, :, None, :]
            + signs[:, 1, None, None, None] * e[None, None, :, :]
        )  # (4, d, d, d)
        points = np.concatenate([np.stack([e, -e]).reshape(2 * d, d), pairs.reshape(4 * d * d, d)])
        shifted = y[:, None, :] + points[None]  # (H, P, d)
        rho = self.env.task.reward_of(shifted[..., :n], shifted[..., n:])
        grad = (rho[:, :d] - rho[:, d : 2 * d]) / (2 * step)
        quad = rho[:, 2 * d :].reshape(-1, 4, d, d)
        hess = (quad[:, 0] - quad[:, 1] - quad[:, 2] + quad[:, 3]) / (4 * step * step)
        hess = (hess + hess.transpose(0, 2, 1)) / 2
        s = self.state_jacobian
        l_x, l_u = -grad[:, :n], -grad[:, n:]
        l_xx, l_uu, l_ux = -hess[:, :n, :n], -hess[:, n:, n:], -hess[:, n:, :n]
        return l_x @ s, l_u, s.T @ l_xx @ s, l_uu, l_ux @ s
