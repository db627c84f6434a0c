"""The dynamic programme's problem and grid: a one-joint trial read from its environment, the grid of
states (periodic in the angle, a box in the speed), the action sets, one control step from many
states batched with ``mujoco.rollout``, and bilinear interpolation on the grid as a sparse matrix.

Bilinear interpolation is an averager (non-negative weights summing to one), so the approximate
Bellman operator stays monotone and the recursion cannot blow up (Gordon 1995; Munos & Moore 2002).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import scipy.sparse
from dm_control.rl import control
from mujoco import rollout

from rmac_mj._physics_timers import untimed
from rmac_mj.rollout import learner_state_of, steps_per_trial
from rmac_mj.solvers.dynamic_programming_config import OptimalConfig
from rmac_mj.solvers.problem import TrialProblem, stepped_model


class Problem(TrialProblem):
    """The trial of a one-joint task as the DP sees it, read from its environment.

    Attributes:
      model: the task's compiled MuJoCo model (one joint, one actuator, no activation state).
      dynamics: the copy of it that the solver steps (:func:`~rmac_mj.solvers.problem.stepped_model`:
        the same steps to the bit, cheaper).
      n_substeps: physics steps per control step; horizon: control steps per trial.
      low, high: the action range (the action spec's bounds).
      start: the full physics state at the start of a trial (``mj_getState``, FULLPHYSICS).
      angle_low, period: the angle's grid range [angle_low, angle_low + period) (the learner state's box).
      describe: a few words on the problem, for people.
    """

    owner = "optimal"

    def __init__(self, env: control.Environment):
        super().__init__(env)
        model, physics = self.model, env.physics
        if model.nq != 1 or model.nv != 1 or model.na != 0 or model.nu != 1:
            raise ValueError(
                f"optimal: the DP needs a one-joint model with one actuator and no "
                f"activation state (x = [angle, speed]), got nq={model.nq}, nv={model.nv}, "
                f"na={model.na}, nu={model.nu}"
            )
        learner_state = learner_state_of(env)
        if tuple(learner_state.periodic) != (True, False):
            raise ValueError(
                f"optimal: the DP needs x = [angle (periodic), speed], got periodic "
                f"{learner_state.periodic}"
            )
        self.angle_low = float(learner_state.low[0])
        self.period = float(learner_state.high[0]) - self.angle_low
        spec = env.action_spec()
        self.low, self.high = float(np.min(spec.minimum)), float(np.max(spec.maximum))
        self.horizon = steps_per_trial(env)
        self.dynamics = stepped_model(env)
        env.reset()
        self.start = self._full_state(physics.data.ptr)
        self._check_deterministic_start(self.start)
        self.describe = (
            f"horizon {self.horizon} of {self.control_timestep:g} s, actions in "
            f"[{self.low:g}, {self.high:g}]"
        )

    @property
    def start_z(self) -> np.ndarray:
        """z_0 = [qpos, qvel] at the start; shape (2,)."""
        return self.start[1:3].copy()

    def state_of(self, z: np.ndarray) -> np.ndarray:
        """The task's x (angle wrapped) of physics states z = [qpos, qvel], shape (..., 2)."""
        return np.asarray(self.env.physics.state_of(z[..., :1], z[..., 1:]), dtype=float)

    def reward(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """rho(x(z), u), the task's own reward, for states z (..., 2) and actions u (...,)."""
        return np.asarray(self.env.task.reward_of(self.state_of(z), np.asarray(u)[..., None]))

    def identity(self) -> dict[str, Any]:
        """What :func:`~rmac_mj.solvers.dynamic_programming.cache_key` hashes besides the grid: the problem as numbers."""
        return {
            "horizon": self.horizon,
            "control_timestep": self.control_timestep,
            "n_substeps": self.n_substeps,
            "action_range": [self.low, self.high],
            "start": self.start.tolist(),
            "angle_range": [self.angle_low, self.period],
        }


def action_set(problem: Problem, n_actions: int) -> np.ndarray:
    """ndarray of shape (n_actions,): actions evenly spaced over the problem's action range."""
    return np.linspace(problem.low, problem.high, n_actions)


def state_grid(config: OptimalConfig, problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """The grid axes: angles of shape (n_phi,) over one period from ``problem.angle_low``, speeds of
    shape (n_phi_dot,)."""
    phi = problem.angle_low + problem.period * np.arange(config.n_phi) / config.n_phi
    phi_dot = np.linspace(-config.max_phi_dot, config.max_phi_dot, config.n_phi_dot)
    return phi, phi_dot


def simulate_transitions(
    model: mujoco.MjModel,
    phi: np.ndarray,
    phi_dot: np.ndarray,
    u: np.ndarray,
    n_substeps: int,
    n_threads: int = 1,
    chunk: int = 1 << 17,
    progress: Callable[[str], None] | None = None,
) -> np.ndarray:
    """One control step of a one-joint MuJoCo model from many states, batched with ``mujoco.rollout``.

    Args:
      phi, phi_dot, u: ndarrays of shape (n,): start qpos, qvel and the action held.
      n_substeps: physics steps per control step.
    Returns:
      ndarray of shape (n, 2): [qpos, qvel] after the step (the angle *not* wrapped).
    """
    n = phi.shape[0]
    datas = [mujoco.MjData(model) for _ in range(max(1, n_threads))]
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    if size != 3:  # [time, qpos, qvel]: one joint, no activation state
        raise ValueError(f"optimal: a one-joint model has a physics state of 3 numbers, got {size}")
    out = np.empty((n, 2))
    with untimed():  # MuJoCo's profiling clock is 40% of these steps' CPU, and changes no number
        for start in range(0, n, chunk):
            stop = min(n, start + chunk)
            state0 = np.zeros((stop - start, size))
            state0[:, 1] = phi[start:stop]
            state0[:, 2] = phi_dot[start:stop]
            control = u[start:stop].reshape(-1, 1, 1)
            states, _ = rollout.rollout(
                model, datas if len(datas) > 1 else datas[0], state0, control, nstep=n_substeps
            )
            out[start:stop] = states[:, -1, 1:3]
            if progress is not None:
                progress(f"simulated {stop:,} of {n:,} transitions")
    return out


def interpolation_matrix(
    config: OptimalConfig, problem: Problem, next_states: np.ndarray
) -> scipy.sparse.csr_matrix:
    """Bilinear interpolation on the grid as a sparse matrix.

    Args:
      next_states: ndarray of shape (m, 2), [angle, speed] (angle any real; speed clipped to the grid).
    Returns:
      csr_matrix of shape (m, n_phi * n_phi_dot) with 4 non-negative weights summing to 1 per row, so that
      ``W @ V.ravel()`` interpolates a grid function V of shape (n_phi, n_phi_dot) at ``next_states``.
    """
    n_phi, n_dot = config.n_phi, config.n_phi_dot
    d_phi = problem.period / n_phi
    d_dot = 2.0 * config.max_phi_dot / (n_dot - 1)
    s = (next_states[:, 0] - problem.angle_low) / d_phi
    i0 = np.floor(s)
    a = s - i0  # weight of the upper angle node, in [0, 1)
    i0 = i0.astype(np.int64) % n_phi
    i1 = (i0 + 1) % n_phi  # periodic in the angle
    w = (
        np.clip(next_states[:, 1], -config.max_phi_dot, config.max_phi_dot) + config.max_phi_dot
    ) / d_dot
    j0 = np.clip(np.floor(w).astype(np.int64), 0, n_dot - 2)
    b = np.clip(w - j0, 0.0, 1.0)  # weight of the upper speed node
    m = next_states.shape[0]
    # 32-bit indices where they fit: the default table has 2.2 M rows, and this halves its index memory.
    index = np.int32 if max(4 * m, n_phi * n_dot) < np.iinfo(np.int32).max else np.int64
    cols = np.stack(
        [i0 * n_dot + j0, i0 * n_dot + j0 + 1, i1 * n_dot + j0, i1 * n_dot + j0 + 1], axis=1
    ).astype(index)
    vals = np.stack([(1 - a) * (1 - b), (1 - a) * b, a * (1 - b), a * b], axis=1)
    return scipy.sparse.csr_matrix(
        (vals.ravel(), cols.ravel(), np.arange(0, 4 * m + 1, 4, dtype=index)),
        shape=(m, n_phi * n_dot),
    )


def interpolate_value(
    config: OptimalConfig, problem: Problem, value: np.ndarray, states: np.ndarray
) -> np.ndarray:
    """Bilinear interpolation of one grid function ``value`` (n_phi, n_phi_dot) at ``states`` (m, 2);
    shape (m,)."""
    return (
        interpolation_matrix(config, problem, np.asarray(states, dtype=float).reshape(-1, 2))
        @ value.astype(float).ravel()
    )
