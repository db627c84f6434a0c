"""A near-optimal return by trajectory optimisation: the best return of a trial from a fixed x_0.

For a deterministic task (a fixed start state, no noise) the best sum of rewards per trial is the maximum
over the action sequence u_0..u_{H-1} (inside the action box) of

    J(u) = sum_{k=1..H} r_k,   r_k = rho(x_{k-1}, u_{k-1}),   z_k = f(z_{k-1}, u_{k-1}),   x_k = s(z_k),

with f one control step of the task's *own* MuJoCo model (z = [qpos, qvel], the action held over the
physics substeps), s the task's state map (``physics.state_of``: angles wrapped) and rho the task's own
reward (``task.reward_of``). No formula of a task is repeated here.

The maximiser is iterative LQR with control limits (box-constrained DDP; Li and Todorov 2004, Tassa,
Mansard and Todorov 2014): around the current trajectory the dynamics are linearised and the reward
expanded to second order, a backward Riccati pass gives a time-varying affine policy
du_k = k_k + K_k dz_k whose feed-forward part solves a small box-constrained QP per step (so saturated
actions get no feedback), and a forward pass simulates that policy on the model with a line search on
k_k and Levenberg-Marquardt regularisation of the value Hessian. Derivatives come from the model:

- *dynamics* A_k = df/dz, B_k = df/du by central finite differences of one control step, every
  perturbed (state, action) pair of the whole horizon simulated in one ``mujoco.rollout`` call
  (multi-threaded C; one-sided in an action at its bound, so no perturbed action saturates);
- *reward* gradient and Hessian by central differences of ``task.reward_of`` in x (batched numpy), chained
  through the Jacobian of ``state_of``, which is linear in z up to the wrapping of angles.

Why iLQR and not a plain gradient method over the open-loop sequence (single shooting, e.g. L-BFGS-B with
finite-difference gradients): on the pendulum swing-up, balancing near the unstable upright makes the
return of an open-loop sequence depend on early actions through exp(10.9 t) (~1e10 over 2 s), and
L-BFGS-B (actions held 4 steps) from seven starts stalled at -1963, against the DP's -748.1. iLQR's forward pass
applies the feedback gains, which keeps the rollouts near the linearisation; it recovers -748 on the
pendulum (docs/optimal.md).

Each start runs in two phases. The reward charges wrapped angles, so a trajectory that loops once
around is, in trajectory space, separated from one that does not by worse trajectories: iLQR from zero
on the pendulum settled at -1236 with a full turn late in the trial, and from the corners of the action
box the arm settled at -223 to -530 after spinning. Phase 1 therefore optimises the same reward of the
angles *continued* from x_0 (not wrapped, ``Problem.state_of(wrap=False)``), which charges every turn;
phase 2 optimises the task's own reward from there. The starts are zero, each corner of the action box
held throughout, each corner switched to its opposite half way, and random sequences; the best is kept,
and how many starts agree on it is the check that it is not a poor local optimum.

The reported number is the return of the found action sequence replayed open-loop on the model (it is
deterministic, so the replay is the trajectory of the final forward pass): the return of an admissible
sequence on the actual model, hence a lower bound on the true optimum. Results are cached like
``optimal.py``'s (JSON keyed by the model, the task's source, the config and ``SOLVER_VERSION``).

    from rmac_mj import tasks
    from rmac_mj.solvers import trajopt
    result = trajopt.optimise(tasks.load(domain, task))
    print(result.describe())

Like a CleanRL file, the solver reads top to bottom in one module (config, result, the problem read
from the environment, derivatives, the box QP, the backward and forward passes, starts, cache), which
is why it runs past 400 lines.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import time
from typing import Any

import mujoco
import numpy as np
from dm_control.rl import control
from mujoco import rollout

from rmac_mj.results.files import cached_json
from rmac_mj.solvers.problem import TrialProblem, cache_directory, versions
from rmac_mj.solvers.problem import cache_key as problem_cache_key

#: Bumped whenever a change to this module changes the numbers it computes: old cache entries are ignored.
SOLVER_VERSION = 1

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
#: Largest action dimension: the per-step box QP enumerates the 3^m faces of the box.
MAX_ACTION_DIM = 4


@dataclasses.dataclass(frozen=True)
class TrajoptConfig:
    """How hard to search. The problem itself (model, horizon, reward, x_0) comes from the environment."""

    max_iterations: int = 300
    """iLQR iterations per start and phase (each: derivatives, a backward pass, a line search)."""
    tolerance: float = 1e-9
    """A phase stops when the gain its quadratic model predicts for a full step is below this fraction
    of (1 + |return|)."""
    random_starts: int = 2
    """Random starts (uniform in the action box) in addition to the zero, corner and switched starts."""
    corner_starts: bool = True
    """Also start from every corner of the action box held throughout, and from every corner switched
    to its opposite half way through the trial (2 * 2^m starts)."""
    fd_step: float = 1e-6
    """Finite-difference step of the dynamics: in each of qpos and qvel (rad, rad/s) and as a fraction of
    each action's range."""
    reward_fd_step: float = 1e-4
    """Finite-difference step of the reward's gradient and Hessian in x and u (exact for a quadratic
    reward up to rounding)."""
    seed: int = 0
    """Seed of the random starts."""
    n_threads: int = 0
    """Threads for the batched rollouts; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("max_iterations", "random_starts", "seed", "n_threads"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"TrajoptConfig.{name} must be an int, got {value!r}")
            if value < 0:
                raise ValueError(f"TrajoptConfig.{name} must be >= 0, got {value}")
        if self.max_iterations < 1:
            raise ValueError(
                f"TrajoptConfig.max_iterations must be >= 1, got {self.max_iterations}"
            )
        if not isinstance(self.corner_starts, (bool, np.bool_)):
            raise TypeError(
                f"TrajoptConfig.corner_starts must be a bool, got {self.corner_starts!r}"
            )
        for name in ("tolerance", "fd_step", "reward_fd_step"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and 0 < value < 1):
                raise ValueError(f"TrajoptConfig.{name} must be a number in (0, 1), got {value!r}")
            object.__setattr__(self, name, float(value))
        object.__setattr__(self, "corner_starts", bool(self.corner_starts))


@dataclasses.dataclass(frozen=True)
class StartSummary:
    """One iLQR run from one initial sequence."""

    start: str
    """Which start: "zero", "corner (...)", "switch (...) half way", "random i"."""
    initial_return: float
    simulated_return: float
    iterations: int
    """iLQR iterations of both phases (unwrapped, then wrapped angles)."""
    stopped: str
    """Why the last phase stopped: "converged", "max_iterations" or "regularisation" (no step improved
    any more)."""


@dataclasses.dataclass(frozen=True)
class TrajoptResult:
    """The best return found.

    Attributes:
      simulated_return: the number to report, sum of the H rewards of ``actions`` replayed on the model.
      actions: ndarray of shape (H, m): the best sequence.
      states: ndarray of shape (H + 1, n): x_0..x_H of the task's state (``physics.state_of``).
      rewards: ndarray of shape (H,): r_1..r_H.
      starts: one ``StartSummary`` per start, in the order run.
      config: the ``TrajoptConfig``.
      problem: what was solved: domain and task when known, horizon, control timestep, x_0, bounds.
      runtime_s: wall time (s) of the run that computed it.
      versions: package versions that computed it.
      from_cache: True when read from the cache rather than computed now.
    """

    simulated_return: float
    actions: np.ndarray
    states: np.ndarray
    rewards: np.ndarray
    starts: tuple[StartSummary, ...]
    config: TrajoptConfig
    problem: dict[str, Any]
    runtime_s: float
    versions: dict[str, str]
    from_cache: bool = False

    def starts_within(self, fraction: float) -> int:
        """How many starts ended within ``fraction`` of |best return| of the best return."""
        margin = fraction * abs(self.simulated_return)
        return sum(s.simulated_return >= self.simulated_return - margin for s in self.starts)

    def describe(self) -> str:
        """A few lines for people: the return, its check (agreement of the starts), the cost."""
        p = self.problem
        name = f"{p['domain']}/{p['task']}: " if p.get("domain") else ""
        returns = sorted((s.simulated_return for s in self.starts), reverse=True)
        lines = [
            f"{name}near-optimal return per trial (iLQR, best of {len(self.starts)} starts, "
            f"replayed on the model): {self.simulated_return:.2f}",
            f"{p['horizon']} steps of {p['control_timestep']:g} s, {p['n_actions']} action(s); "
            f"{self.starts_within(1e-3)} of {len(self.starts)} starts within 0.1% of the best",
            "returns of the starts: " + ", ".join(f"{r:.2f}" for r in returns),
        ]
        cached = " (read from the cache)" if self.from_cache else ""
        lines.append(f"computed in {self.runtime_s:.1f} s{cached}")
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """A plain dict (lists and numbers) that ``json.dump`` writes and ``from_json_dict`` reads."""
        return {
            "simulated_return": self.simulated_return,
            "actions": self.actions.tolist(),
            "states": self.states.tolist(),
            "rewards": self.rewards.tolist(),
            "starts": [dataclasses.asdict(s) for s in self.starts],
            "config": dataclasses.asdict(self.config),
            "problem": self.problem,
            "runtime_s": self.runtime_s,
            "versions": dict(self.versions),
            "solver_version": SOLVER_VERSION,
        }

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> TrajoptResult:
        problem = dict(d["problem"])
        return cls(
            simulated_return=float(d["simulated_return"]),
            actions=np.asarray(d["actions"], dtype=float).reshape(problem["horizon"], -1),
            states=np.asarray(d["states"], dtype=float).reshape(problem["horizon"] + 1, -1),
            rewards=np.asarray(d["rewards"], dtype=float),
            starts=tuple(StartSummary(**s) for s in d["starts"]),
            config=TrajoptConfig(**d["config"]),
            problem=problem,
            runtime_s=float(d["runtime_s"]),
            versions=dict(d["versions"]),
            from_cache=from_cache,
        )


# --------------------------------------------------------------------------------------------------
# The problem, read from the environment


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


# --------------------------------------------------------------------------------------------------
# iLQR with control limits


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
    problem: Problem, actions: np.ndarray, config: TrajoptConfig, wrap: bool = True
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


def _starts(problem: Problem, config: TrajoptConfig) -> list[tuple[str, np.ndarray]]:
    """Initial sequences (name, ndarray of shape (H, m))."""
    m, horizon = problem.low.size, problem.horizon
    starts = [("zero", np.clip(np.zeros((horizon, m)), problem.low, problem.high))]
    if config.corner_starts:
        corners = [
            np.where([(c >> i) & 1 for i in range(m)], problem.high, problem.low)
            for c in range(2**m)
        ]
        for corner in corners:
            label = ", ".join(f"{v:+g}" for v in corner)
            starts.append((f"corner ({label})", np.tile(corner, (horizon, 1))))
        half = horizon // 2
        for corner in corners:
            label = ", ".join(f"{v:+g}" for v in corner)
            opposite = problem.low + problem.high - corner
            starts.append(
                (
                    f"switch ({label}) half way",
                    np.vstack([np.tile(corner, (half, 1)), np.tile(opposite, (horizon - half, 1))]),
                )
            )
    rng = np.random.default_rng(config.seed)
    for i in range(config.random_starts):
        starts.append((f"random {i}", rng.uniform(problem.low, problem.high, size=(horizon, m))))
    return starts


def optimise(env: control.Environment, config: TrajoptConfig = TrajoptConfig()) -> TrajoptResult:
    """The best return of a deterministic environment's trial by iLQR from several starts, uncached.

    Args:
      env: a dm-control environment of this suite whose task has a fixed start (e.g.
        ``tasks.load(domain, task)``); it is reset and stepped.
      config: the search's settings.
    """
    if not isinstance(config, TrajoptConfig):
        raise TypeError(f"optimise: config must be a TrajoptConfig, got {type(config).__name__}")
    start_time = time.perf_counter()
    problem = Problem(env, config.n_threads)
    summaries, best_u, best_value = [], None, -np.inf
    for name, guess in _starts(problem, config):
        initial = float(problem.trajectories(guess[None])[1].sum())
        # Phase 1 charges whole turns (angles unwrapped), so that no start settles into looping
        # around; phase 2 optimises the task's own reward from there.
        u, _, unwrapped_iterations, _ = ilqr(problem, guess, config, wrap=False)
        u, value, iterations, why = ilqr(problem, u, config, wrap=True)
        summaries.append(
            StartSummary(
                start=name,
                initial_return=initial,
                simulated_return=value,
                iterations=unwrapped_iterations + iterations,
                stopped=why,
            )
        )
        if value > best_value:
            best_u, best_value = u, value
    states, rewards = problem.trajectories(best_u[None])  # the open-loop replay is what is reported
    problem_info = {
        "horizon": problem.horizon,
        "n_actions": int(problem.low.size),
        "control_timestep": float(env.control_timestep()),
        "n_substeps": problem.n_substeps,
        "start_state": states[0, 0].tolist(),
        "action_low": problem.low.tolist(),
        "action_high": problem.high.tolist(),
    }
    return TrajoptResult(
        simulated_return=float(rewards[0].sum()),
        actions=best_u,
        states=states[0],
        rewards=rewards[0],
        starts=tuple(summaries),
        config=config,
        problem=problem_info,
        runtime_s=time.perf_counter() - start_time,
        versions=versions(),
    )


# --------------------------------------------------------------------------------------------------
# The cache


def cache_key(env: control.Environment, identity: dict[str, Any], config: TrajoptConfig) -> str:
    """Hex digest identifying a result (:func:`rmac_mj.solvers.problem.cache_key` of this solver)."""
    return problem_cache_key(env, identity, config, SOLVER_VERSION)


def cached_optimise(
    env: control.Environment,
    identity: dict[str, Any],
    config: TrajoptConfig = TrajoptConfig(),
    cache_dir: str | os.PathLike | None = None,
    refresh: bool = False,
    announce=None,
) -> TrajoptResult:
    """``optimise`` of ``env``, from the cache if there.

    Args:
      env: the task's environment (it is reset and stepped).
      identity: what names the problem (``problem.problem_identity``: domain, task, task_kwargs).
      config: the search's settings.
      cache_dir: directory of ``trajopt-<key>.json`` files; default ``problem.default_cache_dir()``.
      refresh: solve again even if cached (and overwrite the entry).
      announce: called with a one-line message before a solve (not for a cache hit), e.g. ``print``.
    """
    if not isinstance(config, TrajoptConfig):
        raise TypeError(
            f"cached_optimise: config must be a TrajoptConfig, got {type(config).__name__}"
        )
    directory = cache_directory(cache_dir)
    path = directory / f"trajopt-{cache_key(env, identity, config)}.json"
    name = f"{identity.get('domain')}/{identity.get('task')}"

    def compute() -> TrajoptResult:
        result = optimise(env, config)
        return dataclasses.replace(
            result,
            problem={
                "domain": identity.get("domain"),
                "task": identity.get("task"),
                **result.problem,
            },
        )

    return cached_json(
        path,
        lambda document: TrajoptResult.from_json_dict(document, from_cache=True),
        compute,
        refresh=refresh,
        announce=announce,
        message=(
            f"computing the near-optimal return of {name} by trajectory optimisation "
            f"(iLQR, under a minute on 2 cores), cached in {directory}"
        ),
    )
