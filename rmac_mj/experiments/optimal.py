"""A near-optimal reference for the swing-up: the best sum of rewards per 3 s trial, by dynamic programming.

The learners are scored by the undiscounted sum of the 100 rewards of a trial that starts in
x_0 = [pi, 0] (section 6). For a deterministic, time-invariant system and a fixed horizon the best such
sum is the value V_0(x_0) of the finite-horizon Bellman recursion

    V_H(x) = 0,    V_t(x) = max_u [ rho(x, u) + V_{t+1}(f(x, u)) ],   t = H-1, ..., 0,
    rho(x, u) = -x^T Q x - P u^2   (phi wrapped to [-pi, pi)),

with f one 0.03 s control step of the *same* MuJoCo model the tasks simulate (3 RK4 substeps of 10 ms).
It is solved on a grid (periodic in phi, a box in phi_dot) with a finite action set that contains the
extremes +-u_max, and V_{t+1} is read between grid nodes by bilinear interpolation. Why this choice:

- *Finite horizon, undiscounted*: it is exactly the learners' metric, not a discounted surrogate; a
  stationary policy of a discounted problem would answer a different question.
- *Transition table once*: the dynamics do not depend on time, so f(x_i, u_a) is simulated once for every
  grid node and action (batched with ``mujoco.rollout``) and stored as a sparse interpolation matrix;
  each of the H backups is then one sparse mat-vec and a max.
- *Bilinear interpolation* is an averager (non-negative weights summing to one), so the approximate
  Bellman operator stays monotone and the recursion cannot blow up (Gordon 1995; Munos & Moore 2002).
- *No time discretisation error*: the DP steps with the true control period, so the only errors are the
  state interpolation and the finite action set, which the convergence check measures.

The DP value is an approximation; the number to report is the return of its greedy policy simulated on the
MuJoCo model from x_0 (one-step look-ahead on V_{t+1} from the exact, off-grid state). Being the return of
an actual admissible policy on the actual model, it is a lower bound on the true optimum; the DP value
next to it is its check. Results are cached as JSON keyed by a hash of the model XML, the config and the
solver version, so ``rmac-mj optimal`` and Fig. 2 reuse them.

    from rmac_mj.experiments.optimal import optimal_return
    result = optimal_return()          # solves once (under a minute on 2 cores), then reads the cache
    print(result.simulated_return, result.dp_value)
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import pathlib
import time
from typing import Any, Callable

import mujoco
import numpy as np
import scipy.sparse
from mujoco import rollout

from rmac_mj._cache import user_cache_dir
from rmac_mj.models import model_path
from rmac_mj.tasks import dc_pendulum

#: Bumped whenever a change to this module changes the numbers it computes: old cache entries are ignored.
SOLVER_VERSION = 1


@dataclasses.dataclass(frozen=True)
class OptimalConfig:
    """What is solved and how finely.

    The task's numbers (horizon, control step, Q, P, x_0) default to the module constants of
    ``rmac_mj.tasks.dc_pendulum``, the single source of truth the learners' environment uses; the voltage
    range is the model actuator's ``ctrlrange``.
    """

    n_phi: int = 361
    """Grid nodes in phi over one period [-pi, pi) (periodic; spacing 2 pi / n_phi rad)."""
    n_phi_dot: int = 241
    """Grid nodes in phi_dot over [-max_phi_dot, max_phi_dot], ends included."""
    max_phi_dot: float = 20.0
    """Half-width of the phi_dot grid (rad/s). Next states beyond it are clipped to its edge. The swing-up
    needs about 20 rad/s (energy to reach the top from rest below: sqrt(4 M g l / J) = 21.8 rad/s);
    the solver raises if the greedy trajectory comes within 10% of the edge."""
    n_actions: int = 25
    """Voltages evenly spaced over the actuator's control range, extremes included (0.25 V apart)."""
    lookahead_actions: int = 121
    """Voltages (same range) the greedy policy chooses from when simulated: its one-step look-ahead is
    cheap, so it may search finer than the DP's backups (0.05 V apart; a superset of the DP's 25)."""
    horizon: int = round(dc_pendulum.DEFAULT_TIME_LIMIT / dc_pendulum.CONTROL_TIMESTEP)
    """Control steps per trial (100: 3 s of 0.03 s)."""
    control_timestep: float = dc_pendulum.CONTROL_TIMESTEP
    """Seconds per control step; a whole number of the model's physics timesteps."""
    state_weights: tuple[float, float] = tuple(dc_pendulum.STATE_WEIGHTS)
    """Diagonal of Q, for (phi, phi_dot)."""
    action_weight: float = dc_pendulum.ACTION_WEIGHT
    """P."""
    start_state: tuple[float, float] = tuple(float(v) for v in dc_pendulum.SWINGUP_START)
    """x_0 = (phi, phi_dot) of the trial (rad, rad/s)."""
    check_convergence: bool = True
    """Also solve on a grid of half the resolution in each state dimension and with half as many action
    intervals, and report how much the answers move."""
    n_threads: int = 0
    """Threads for the batched transition simulation; 0 means ``os.cpu_count()``. Does not change results."""

    def __post_init__(self) -> None:
        for name in ("n_phi", "n_phi_dot", "n_actions", "lookahead_actions", "horizon"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool):
                raise TypeError(f"OptimalConfig.{name} must be an int, got {value!r}")
        if self.n_phi < 4:
            raise ValueError(f"OptimalConfig.n_phi must be >= 4, got {self.n_phi}")
        if self.n_phi_dot < 3:
            raise ValueError(f"OptimalConfig.n_phi_dot must be >= 3, got {self.n_phi_dot}")
        if self.n_actions < 2:
            raise ValueError(f"OptimalConfig.n_actions must be >= 2 (the two extremes), got {self.n_actions}")
        if self.lookahead_actions < 2:
            raise ValueError(f"OptimalConfig.lookahead_actions must be >= 2, got {self.lookahead_actions}")
        if self.horizon < 1:
            raise ValueError(f"OptimalConfig.horizon must be >= 1, got {self.horizon}")
        for name in ("max_phi_dot", "control_timestep"):
            value = getattr(self, name)
            if not (np.isscalar(value) and np.isfinite(value) and value > 0):
                raise ValueError(f"OptimalConfig.{name} must be a positive finite number, got {value!r}")
        q = np.asarray(self.state_weights, dtype=float)
        if q.shape != (2,) or not np.all(np.isfinite(q)) or np.any(q < 0):
            raise ValueError(f"OptimalConfig.state_weights must be 2 finite numbers >= 0 (diag Q), "
                             f"got {self.state_weights!r}")
        if not (np.isscalar(self.action_weight) and np.isfinite(self.action_weight)
                and self.action_weight >= 0):
            raise ValueError(f"OptimalConfig.action_weight must be a finite number >= 0, "
                             f"got {self.action_weight!r}")
        x0 = np.asarray(self.start_state, dtype=float)
        if x0.shape != (2,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"OptimalConfig.start_state must be finite (phi, phi_dot), "
                             f"got {self.start_state!r}")
        if abs(x0[1]) > self.max_phi_dot:
            raise ValueError(f"OptimalConfig.start_state phi_dot={x0[1]} lies outside the grid "
                             f"[-{self.max_phi_dot}, {self.max_phi_dot}]")
        if not isinstance(self.n_threads, (int, np.integer)) or self.n_threads < 0:
            raise ValueError(f"OptimalConfig.n_threads must be an int >= 0, got {self.n_threads!r}")
        # Store canonical Python types so that the config hashes and serialises the same however given.
        object.__setattr__(self, "state_weights", tuple(float(v) for v in q))
        object.__setattr__(self, "start_state", tuple(float(v) for v in x0))
        for name in ("max_phi_dot", "control_timestep", "action_weight"):
            object.__setattr__(self, name, float(getattr(self, name)))

    @classmethod
    def from_json_dict(cls, d: dict[str, Any]) -> "OptimalConfig":
        """The config of ``dataclasses.asdict(config)`` read back from JSON (lists to tuples)."""
        return cls(**{**d, "state_weights": tuple(d["state_weights"]),
                      "start_state": tuple(d["start_state"])})

    def coarser(self) -> "OptimalConfig":
        """The convergence check's problem: about half the nodes per state dimension, half the action
        intervals of the DP and of the look-ahead (the extremes and every other voltage stay in each
        set), no further check."""
        return dataclasses.replace(self, n_phi=max(4, self.n_phi // 2),
                                   n_phi_dot=max(3, (self.n_phi_dot + 1) // 2),
                                   n_actions=max(2, (self.n_actions + 1) // 2),
                                   lookahead_actions=max(2, (self.lookahead_actions + 1) // 2),
                                   check_convergence=False)


@dataclasses.dataclass(frozen=True)
class SolveSummary:
    """The answer of one DP solve (one grid and action set)."""

    n_phi: int
    n_phi_dot: int
    n_actions: int
    dp_value: float
    """V_0(x_0) of the grid DP (interpolated)."""
    simulated_return: float
    """Sum of the H rewards of the greedy policy simulated on the MuJoCo model from x_0."""
    runtime_s: float


@dataclasses.dataclass(frozen=True)
class OptimalResult:
    """The near-optimal reference.

    Attributes:
      simulated_return: the number to report: return of the DP's greedy policy, simulated on the model.
      dp_value: the DP's own estimate V_0(x_0), its check.
      config: the ``OptimalConfig`` solved.
      fine: the ``SolveSummary`` of the configured grid.
      coarse: the ``SolveSummary`` of ``config.coarser()``, or None without the convergence check.
      states: ndarray of shape (horizon + 1, 2): greedy trajectory x_0..x_H, phi wrapped (rad, rad/s).
      actions: ndarray of shape (horizon,): voltages u_0..u_{H-1} (V).
      rewards: ndarray of shape (horizon,): r_1..r_H.
      model_sha256: hash of the model XML solved on.
      runtime_s: wall time of the whole computation (s); that of the run that filled the cache if cached.
      versions: package versions that computed it.
      from_cache: True when read from the cache rather than computed now.
    """

    simulated_return: float
    dp_value: float
    config: OptimalConfig
    fine: SolveSummary
    coarse: SolveSummary | None
    states: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    model_sha256: str
    runtime_s: float
    versions: dict[str, str]
    from_cache: bool = False

    @property
    def convergence_gap(self) -> float | None:
        """|simulated return (fine) - simulated return (coarse)|, or None without the check."""
        if self.coarse is None:
            return None
        return abs(self.fine.simulated_return - self.coarse.simulated_return)

    def describe(self) -> str:
        """A few lines for people: the return, its check, the convergence and the cost."""
        c = self.config
        lines = [f"near-optimal return per trial (greedy DP policy simulated on the model): "
                 f"{self.simulated_return:.2f}",
                 f"DP value V_0(x_0): {self.dp_value:.2f}  "
                 f"(grid {c.n_phi} x {c.n_phi_dot} over phi x phi_dot in [-pi, pi) x "
                 f"[-{c.max_phi_dot:g}, {c.max_phi_dot:g}] rad/s, {c.n_actions} actions in the DP, "
                 f"{c.lookahead_actions} in the look-ahead, horizon {c.horizon})"]
        if self.coarse is not None:
            lines.append(f"coarser grid {self.coarse.n_phi} x {self.coarse.n_phi_dot}, "
                         f"{self.coarse.n_actions} actions: {self.coarse.simulated_return:.2f} "
                         f"(DP {self.coarse.dp_value:.2f}); "
                         f"convergence gap {self.convergence_gap:.2f}")
        cached = " (read from the cache)" if self.from_cache else ""
        lines.append(f"computed in {self.runtime_s:.1f} s{cached}")
        return "\n".join(lines)

    def to_json_dict(self) -> dict[str, Any]:
        """A plain dict (lists and numbers) that ``json.dump`` writes and ``from_json_dict`` reads."""
        return {
            "simulated_return": self.simulated_return,
            "dp_value": self.dp_value,
            "convergence_gap": self.convergence_gap,
            "config": dataclasses.asdict(self.config),
            "fine": dataclasses.asdict(self.fine),
            "coarse": None if self.coarse is None else dataclasses.asdict(self.coarse),
            "states": self.states.tolist(),
            "actions": self.actions.tolist(),
            "rewards": self.rewards.tolist(),
            "model_sha256": self.model_sha256,
            "runtime_s": self.runtime_s,
            "versions": dict(self.versions),
            "solver_version": SOLVER_VERSION,
        }

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> "OptimalResult":
        config = OptimalConfig.from_json_dict(d["config"])
        return cls(simulated_return=float(d["simulated_return"]), dp_value=float(d["dp_value"]),
                   config=config, fine=SolveSummary(**d["fine"]),
                   coarse=None if d["coarse"] is None else SolveSummary(**d["coarse"]),
                   states=np.asarray(d["states"], dtype=float).reshape(-1, 2),
                   actions=np.asarray(d["actions"], dtype=float),
                   rewards=np.asarray(d["rewards"], dtype=float),
                   model_sha256=str(d["model_sha256"]), runtime_s=float(d["runtime_s"]),
                   versions=dict(d["versions"]), from_cache=from_cache)


# --------------------------------------------------------------------------------------------------
# The problem: grid, actions, rewards, transitions


def _load_model(model_xml: str) -> mujoco.MjModel:
    model = mujoco.MjModel.from_xml_string(model_xml)
    if model.nq != 1 or model.nv != 1 or model.na != 0 or model.nu != 1:
        raise ValueError(f"optimal: the DP needs a 1-dof model with one actuator and no activation "
                         f"state (x = [phi, phi_dot]), got nq={model.nq}, nv={model.nv}, na={model.na}, "
                         f"nu={model.nu}")
    return model


def _n_substeps(model: mujoco.MjModel, control_timestep: float) -> int:
    n = control_timestep / model.opt.timestep
    if abs(n - round(n)) > 1e-8 or round(n) < 1:
        raise ValueError(f"OptimalConfig.control_timestep={control_timestep} is not a whole number of the "
                         f"model's physics timestep {model.opt.timestep} s")
    return int(round(n))


def action_set(model: mujoco.MjModel, n_actions: int) -> np.ndarray:
    """ndarray of shape (n_actions,): voltages evenly spaced over the actuator's control range (V)."""
    low, high = model.actuator_ctrlrange[0]
    return np.linspace(low, high, n_actions)


def state_grid(config: OptimalConfig) -> tuple[np.ndarray, np.ndarray]:
    """The grid axes: phi of shape (n_phi,) in [-pi, pi), phi_dot of shape (n_phi_dot,)."""
    phi = -np.pi + 2.0 * np.pi * np.arange(config.n_phi) / config.n_phi
    phi_dot = np.linspace(-config.max_phi_dot, config.max_phi_dot, config.n_phi_dot)
    return phi, phi_dot


def reward(config: OptimalConfig, phi, phi_dot, u):
    """rho(x, u) = -x^T Q x - P u^2 with phi wrapped to [-pi, pi); broadcasts over array arguments."""
    phi = dc_pendulum.wrap_angle(phi)
    q_phi, q_phi_dot = config.state_weights
    return -(q_phi * phi**2 + q_phi_dot * np.asarray(phi_dot)**2) - config.action_weight * np.asarray(u)**2


def simulate_transitions(model: mujoco.MjModel, phi: np.ndarray, phi_dot: np.ndarray, u: np.ndarray,
                         n_substeps: int, n_threads: int = 1, chunk: int = 1 << 17) -> np.ndarray:
    """One control step of the MuJoCo model from many states, batched with ``mujoco.rollout``.

    Args:
      phi, phi_dot, u: ndarrays of shape (n,): start angle (rad), speed (rad/s), voltage held (V).
      n_substeps: physics steps per control step.
    Returns:
      ndarray of shape (n, 2): [phi, phi_dot] after the step, phi *not* wrapped.
    """
    n = phi.shape[0]
    datas = [mujoco.MjData(model) for _ in range(max(1, n_threads))]
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    assert size == 3, size  # [time, qpos, qvel]: checked by _load_model's nq = nv = 1, na = 0
    out = np.empty((n, 2))
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        state0 = np.zeros((stop - start, size))
        state0[:, 1] = phi[start:stop]
        state0[:, 2] = phi_dot[start:stop]
        control = u[start:stop].reshape(-1, 1, 1)
        states, _ = rollout.rollout(model, datas if len(datas) > 1 else datas[0], state0, control,
                                    nstep=n_substeps)
        out[start:stop] = states[:, -1, 1:3]
    return out


def interpolation_matrix(config: OptimalConfig, next_states: np.ndarray) -> scipy.sparse.csr_matrix:
    """Bilinear interpolation on the grid as a sparse matrix.

    Args:
      next_states: ndarray of shape (m, 2), [phi, phi_dot] (phi any real; phi_dot clipped to the grid).
    Returns:
      csr_matrix of shape (m, n_phi * n_phi_dot) with 4 non-negative weights summing to 1 per row, so that
      ``W @ V.ravel()`` interpolates a grid function V of shape (n_phi, n_phi_dot) at ``next_states``.
    """
    n_phi, n_dot = config.n_phi, config.n_phi_dot
    d_phi = 2.0 * np.pi / n_phi
    d_dot = 2.0 * config.max_phi_dot / (n_dot - 1)
    s = (next_states[:, 0] + np.pi) / d_phi
    i0 = np.floor(s)
    a = s - i0                                   # weight of the upper phi node, in [0, 1)
    i0 = i0.astype(np.int64) % n_phi
    i1 = (i0 + 1) % n_phi                        # periodic in phi
    w = (np.clip(next_states[:, 1], -config.max_phi_dot, config.max_phi_dot) + config.max_phi_dot) / d_dot
    j0 = np.clip(np.floor(w).astype(np.int64), 0, n_dot - 2)
    b = np.clip(w - j0, 0.0, 1.0)                # weight of the upper phi_dot node
    m = next_states.shape[0]
    # 32-bit indices where they fit: the default table has 2.2 M rows, and this halves its index memory.
    index = np.int32 if max(4 * m, n_phi * n_dot) < np.iinfo(np.int32).max else np.int64
    cols = np.stack([i0 * n_dot + j0, i0 * n_dot + j0 + 1, i1 * n_dot + j0, i1 * n_dot + j0 + 1],
                    axis=1).astype(index)
    vals = np.stack([(1 - a) * (1 - b), (1 - a) * b, a * (1 - b), a * b], axis=1)
    return scipy.sparse.csr_matrix((vals.ravel(), cols.ravel(), np.arange(0, 4 * m + 1, 4, dtype=index)),
                                   shape=(m, n_phi * n_dot))


# --------------------------------------------------------------------------------------------------
# The solver


def solve_values(config: OptimalConfig, model: mujoco.MjModel) -> np.ndarray:
    """Backward finite-horizon DP on the grid.

    Returns:
      ndarray of shape (horizon + 1, n_phi, n_phi_dot), float32: V_t on the grid for t = 0..H (V_H = 0).
    """
    n_sub = _n_substeps(model, config.control_timestep)
    phi, phi_dot = state_grid(config)
    actions = action_set(model, config.n_actions)
    n_states, n_act = config.n_phi * config.n_phi_dot, config.n_actions
    # Row s * n_act + a is the transition from grid node s (phi-major) under action a.
    pp, dd, uu = np.meshgrid(phi, phi_dot, actions, indexing="ij")
    threads = config.n_threads or os.cpu_count() or 1
    next_states = simulate_transitions(model, pp.ravel(), dd.ravel(), uu.ravel(), n_sub, threads)
    transition = interpolation_matrix(config, next_states)
    rewards = reward(config, pp, dd, uu).reshape(n_states, n_act)
    values = np.zeros((config.horizon + 1, n_states), dtype=np.float32)
    v = np.zeros(n_states)
    for t in range(config.horizon - 1, -1, -1):
        v = (rewards + (transition @ v).reshape(n_states, n_act)).max(axis=1)
        values[t] = v
    return values.reshape(config.horizon + 1, config.n_phi, config.n_phi_dot)


def interpolate_value(config: OptimalConfig, value: np.ndarray, states: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of one grid function.

    Args:
      value: ndarray of shape (n_phi, n_phi_dot).
      states: ndarray of shape (m, 2).
    Returns:
      ndarray of shape (m,).
    """
    return interpolation_matrix(config, np.asarray(states, dtype=float).reshape(-1, 2)) @ \
        value.astype(float).ravel()


def greedy_rollout(config: OptimalConfig, model: mujoco.MjModel, values: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate the DP's greedy policy on the model from ``config.start_state``.

    At step k, from the exact (off-grid) state x_k, each of ``config.lookahead_actions`` voltages is
    simulated for one control step and scored rho(x_k, u) + V_{k+1}(x_{k+1}); the best is applied
    (ties: the lowest voltage).

    Returns:
      states (horizon + 1, 2) with phi wrapped, actions (horizon,), rewards (horizon,).
    """
    n_sub = _n_substeps(model, config.control_timestep)
    actions = action_set(model, config.lookahead_actions)
    data = mujoco.MjData(model)
    # Raw index 0 is the hinge: _load_model admits only models with one joint dof and one actuator.
    data.qpos[0], data.qvel[0] = config.start_state
    states = np.empty((config.horizon + 1, 2))
    applied = np.empty(config.horizon)
    rewards = np.empty(config.horizon)
    for k in range(config.horizon):
        phi, phi_dot = float(data.qpos[0]), float(data.qvel[0])
        states[k] = dc_pendulum.wrap_angle(phi), phi_dot
        candidates = simulate_transitions(model, np.full(len(actions), phi), np.full(len(actions), phi_dot),
                                          actions, n_sub)
        scores = reward(config, phi, phi_dot, actions) + interpolate_value(config, values[k + 1], candidates)
        u = actions[int(np.argmax(scores))]
        rewards[k] = reward(config, phi, phi_dot, u)
        applied[k] = u
        data.ctrl[0] = u
        for _ in range(n_sub):
            mujoco.mj_step(model, data)
    states[-1] = dc_pendulum.wrap_angle(float(data.qpos[0])), float(data.qvel[0])
    return states, applied, rewards


def _solve_once(config: OptimalConfig, model: mujoco.MjModel, values: np.ndarray | None = None
                ) -> tuple[SolveSummary, np.ndarray, np.ndarray, np.ndarray]:
    """Solve (or take the given ``values``), then simulate the greedy policy."""
    start = time.perf_counter()
    if values is None:
        values = solve_values(config, model)
    dp_value = float(interpolate_value(config, values[0], np.asarray(config.start_state))[0])
    states, actions, rewards = greedy_rollout(config, model, values)
    peak = float(np.max(np.abs(states[:, 1])))
    if peak > 0.9 * config.max_phi_dot:
        raise ValueError(f"optimal: the greedy trajectory reaches |phi_dot| = {peak:.1f} rad/s, within 10% "
                         f"of the grid edge max_phi_dot={config.max_phi_dot}; widen the grid")
    summary = SolveSummary(n_phi=config.n_phi, n_phi_dot=config.n_phi_dot, n_actions=config.n_actions,
                           dp_value=dp_value, simulated_return=float(np.sum(rewards)),
                           runtime_s=time.perf_counter() - start)
    return summary, states, actions, rewards


def solve(config: OptimalConfig = OptimalConfig(), model_xml: str | None = None) -> OptimalResult:
    """Solve without the cache (see ``optimal_return``). ``model_xml``: MJCF text, default the package's."""
    start = time.perf_counter()
    if model_xml is None:
        model_xml = model_path("dc_pendulum").read_text()
    model, values = _solved(config, model_xml)  # kept for an exploration floor that follows
    fine, states, actions, rewards = _solve_once(config, model, values)
    coarse = _solve_once(config.coarser(), model)[0] if config.check_convergence else None
    return OptimalResult(simulated_return=fine.simulated_return, dp_value=fine.dp_value, config=config,
                         fine=fine, coarse=coarse, states=states, actions=actions, rewards=rewards,
                         model_sha256=hashlib.sha256(model_xml.encode()).hexdigest(),
                         runtime_s=time.perf_counter() - start, versions=_versions())


# --------------------------------------------------------------------------------------------------
# The cache


def default_cache_dir() -> pathlib.Path:
    """``$RMAC_MJ_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/rmac-mj``, else ``~/.cache/rmac-mj``."""
    return user_cache_dir()


def cache_key(config: OptimalConfig, model_xml: str) -> str:
    """Hex digest identifying a result: the model XML, every config field but ``n_threads``, the solver."""
    fields = dataclasses.asdict(config)
    fields.pop("n_threads")  # changes the speed, never the numbers
    blob = json.dumps({"model": hashlib.sha256(model_xml.encode()).hexdigest(), "config": fields,
                       "solver_version": SOLVER_VERSION}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def optimal_return(config: OptimalConfig = OptimalConfig(), cache_dir: str | os.PathLike | None = None,
                   refresh: bool = False, model_xml: str | None = None,
                   announce: Callable[[str], None] | None = None) -> OptimalResult:
    """The near-optimal return per trial, from the cache if there, else solved and cached.

    Args:
      config: grid, actions and task parameters.
      cache_dir: directory of ``optimal-<key>.json`` files; default ``default_cache_dir()``.
      refresh: solve again even if cached (and overwrite the entry).
      model_xml: MJCF text to solve on; default the package's ``dc_pendulum.xml``.
      announce: called with a one-line message before a solve (about a minute), e.g. ``print``.
    """
    if not isinstance(config, OptimalConfig):
        raise TypeError(f"optimal_return: config must be an OptimalConfig, got {type(config).__name__}")
    if model_xml is None:
        model_xml = model_path("dc_pendulum").read_text()
    directory = pathlib.Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = directory / f"optimal-{cache_key(config, model_xml)}.json"
    from rmac_mj.experiments.files import cached_json
    return cached_json(
        path, lambda document: OptimalResult.from_json_dict(document, from_cache=True),
        lambda: solve(config, model_xml), refresh=refresh, announce=announce,
        message=(f"computing the near-optimal reference by dynamic programming (about a minute on 2 "
                 f"cores; cached after, in {directory})"))


def _versions() -> dict[str, str]:
    import scipy
    import rmac_mj
    return {"rmac_mj": rmac_mj.__version__, "mujoco": mujoco.__version__, "numpy": np.__version__,
            "scipy": scipy.__version__}


# --------------------------------------------------------------------------------------------------
# The exploration floor: the near-optimal policy under the protocol's exploration


@dataclasses.dataclass(frozen=True)
class ExplorationFloor:
    """What the near-optimal policy scores per trial while exploring as the learners do.

    During learning every ``period``-th step (``k % period == phase``) gets N(0, sigma^2) noise added
    to the action, saturated to the actuator range (section 6.1: sigma = 1 V every third step). No
    learner's exploring trial can average much better than this policy's, so an exploring learning
    curve is judged against ``mean`` and a greedy trial against the near-optimal return.

    Attributes:
      mean, std: of the sum of rewards over ``rollouts`` noisy trials from x_0.
      ci95: Student-t 95% confidence interval of ``mean``.
      returns: ndarray of shape (rollouts,): each noisy trial's return.
      sigma, period, phase: the exploration schedule (V, steps, step).
      rollouts, seed: how many noisy trials, and the seed of their noise.
      config: the ``OptimalConfig`` of the DP whose greedy policy explores.
      runtime_s, from_cache: as in :class:`OptimalResult`.
    """

    mean: float
    std: float
    ci95: tuple[float, float]
    returns: np.ndarray
    sigma: float
    period: int
    phase: int
    rollouts: int
    seed: int
    config: OptimalConfig
    runtime_s: float
    from_cache: bool = False

    def describe(self) -> str:
        low, high = self.ci95
        cached = ", read from the cache" if self.from_cache else f", computed in {self.runtime_s:.1f} s"
        return (f"exploration floor (the same policy with N(0, {self.sigma:g}^2) V added every "
                f"{_ordinal(self.period)} step, saturated): {self.mean:.1f} per trial, std "
                f"{self.std:.1f}, 95% CI [{low:.1f}, {high:.1f}] over {self.rollouts} noisy trials "
                f"(seed {self.seed}{cached})")

    def to_json_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "std": self.std, "ci95": list(self.ci95),
                "returns": self.returns.tolist(), "sigma": self.sigma, "period": self.period,
                "phase": self.phase, "rollouts": self.rollouts, "seed": self.seed,
                "config": dataclasses.asdict(self.config), "runtime_s": self.runtime_s,
                "solver_version": SOLVER_VERSION}

    @classmethod
    def from_json_dict(cls, d: dict[str, Any], from_cache: bool = True) -> "ExplorationFloor":
        config = OptimalConfig.from_json_dict(d["config"])
        return cls(mean=float(d["mean"]), std=float(d["std"]),
                   ci95=(float(d["ci95"][0]), float(d["ci95"][1])),
                   returns=np.asarray(d["returns"], dtype=float), sigma=float(d["sigma"]),
                   period=int(d["period"]), phase=int(d["phase"]), rollouts=int(d["rollouts"]),
                   seed=int(d["seed"]), config=config, runtime_s=float(d["runtime_s"]),
                   from_cache=from_cache)


def _ordinal(n: int) -> str:
    if n == 1:
        return ""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def noisy_rollouts(config: OptimalConfig, model: mujoco.MjModel, values: np.ndarray, sigma: float,
                   period: int, phase: int, rollouts: int, rng: np.random.Generator) -> np.ndarray:
    """Returns of ``rollouts`` trials of the DP's greedy policy with exploration noise.

    Every trial starts in ``config.start_state``; at step k the greedy voltage is chosen exactly as in
    :func:`greedy_rollout` (one-step look-ahead on V_{k+1} over ``config.lookahead_actions``), then on
    exploring steps (``k % period == phase``) N(0, sigma^2) is added and the sum clipped to the
    actuator's range; the reward is paid for the applied voltage. The trials run in lockstep, one
    batched ``mujoco.rollout`` per step.

    Returns:
      ndarray of shape (rollouts,): the sum of the H rewards of each trial.
    """
    n_sub = _n_substeps(model, config.control_timestep)
    actions = action_set(model, config.lookahead_actions)
    low, high = model.actuator_ctrlrange[0]
    threads = config.n_threads or os.cpu_count() or 1
    phi = np.full(rollouts, config.start_state[0])
    phi_dot = np.full(rollouts, config.start_state[1])
    total = np.zeros(rollouts)
    n_act = len(actions)
    for k in range(config.horizon):
        candidates = simulate_transitions(model, np.repeat(phi, n_act), np.repeat(phi_dot, n_act),
                                          np.tile(actions, rollouts), n_sub, threads)
        scores = (reward(config, phi[:, None], phi_dot[:, None], actions[None, :])
                  + interpolate_value(config, values[k + 1], candidates).reshape(rollouts, n_act))
        u = actions[np.argmax(scores, axis=1)]  # ties: the lowest voltage, as greedy_rollout
        if sigma > 0 and k % period == phase:
            u = np.clip(u + rng.normal(0.0, sigma, size=rollouts), low, high)
        total += reward(config, phi, phi_dot, u)
        next_states = simulate_transitions(model, phi, phi_dot, u, n_sub, threads)
        phi, phi_dot = next_states[:, 0], next_states[:, 1]
    return total


@functools.lru_cache(maxsize=1)
def _solved(config: OptimalConfig, model_xml: str) -> tuple[mujoco.MjModel, np.ndarray]:
    """The model and the DP's values (35 MB at the default grid), kept for the next floor: a sweep
    over exploration settings asks for several floors of one DP."""
    model = _load_model(model_xml)
    return model, solve_values(config, model)


def exploration_floor(sigma: float = 1.0, period: int = 3, phase: int = 0, rollouts: int = 100,
                      seed: int = 0, config: OptimalConfig = OptimalConfig(),
                      cache_dir: str | os.PathLike | None = None, refresh: bool = False,
                      model_xml: str | None = None,
                      announce: Callable[[str], None] | None = None) -> ExplorationFloor:
    """The near-optimal policy's return under exploration, from the cache if there, else computed.

    The DP of :func:`optimal_return` is solved again unless this process just solved it (its values
    are not cached on disk, only its answer), then ``rollouts`` noisy trials are simulated (:func:`noisy_rollouts`). Defaults: the paper's
    exploration (section 6.1), 100 trials.

    Args:
      sigma: exploration noise std (V), >= 0.
      period, phase: explore at steps k with ``k % period == phase``.
      rollouts: noisy trials to average, >= 2.
      seed: seed of the noise.
      config, cache_dir, refresh, model_xml, announce: as in :func:`optimal_return`.
    """
    if not isinstance(config, OptimalConfig):
        raise TypeError(f"exploration_floor: config must be an OptimalConfig, got {type(config).__name__}")
    if isinstance(sigma, bool) or not (np.isscalar(sigma) and np.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"exploration_floor: sigma must be a finite number >= 0, got {sigma!r}")
    for name, value, minimum in (("period", period, 1), ("phase", phase, 0), ("rollouts", rollouts, 2),
                                 ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise ValueError(f"exploration_floor: {name} must be an integer >= {minimum}, got {value!r}")
    if phase >= period:
        raise ValueError(f"exploration_floor: phase must be in [0, period={period}), got {phase}")
    if model_xml is None:
        model_xml = model_path("dc_pendulum").read_text()
    sigma, period, phase, rollouts, seed = float(sigma), int(period), int(phase), int(rollouts), int(seed)
    key = hashlib.sha256(json.dumps([cache_key(config, model_xml), sigma, period, phase, rollouts, seed])
                         .encode()).hexdigest()[:20]
    directory = pathlib.Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()

    def compute() -> ExplorationFloor:
        start = time.perf_counter()
        model, values = _solved(config, model_xml)
        returns = noisy_rollouts(config, model, values, sigma, period, phase, rollouts,
                                 np.random.default_rng(seed))
        mean, low, high = confidence_interval(returns)
        return ExplorationFloor(mean=float(mean), std=float(returns.std(ddof=1)),
                                ci95=(float(low), float(high)), returns=returns, sigma=sigma,
                                period=period, phase=phase, rollouts=rollouts, seed=seed,
                                config=config, runtime_s=time.perf_counter() - start)
    from rmac_mj.experiments.files import cached_json
    from rmac_mj.experiments.metrics import confidence_interval
    return cached_json(
        directory / f"exploration-floor-{key}.json",
        lambda document: ExplorationFloor.from_json_dict(document, from_cache=True), compute,
        refresh=refresh, announce=announce,
        message=(f"computing the exploration floor ({rollouts} noisy trials of the near-optimal "
                 f"policy, after its dynamic programming: about a minute; cached after, in "
                 f"{directory})"))
