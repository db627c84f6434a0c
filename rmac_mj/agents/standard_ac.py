"""S-AC, the paper's standard actor-critic (section 3, Algorithm 1, section 6.1), and its config.

Critic V(x, theta) and actor pi(x, vartheta) are linear in tile-coding features
(:mod:`rmac_mj.approximators.tile_coding`); :class:`StandardActorCritic` maps each step to Algorithm
1's lines (eqs. 2-4) and lists the choices the paper leaves open (docs/standard-ac.md).
"""

from __future__ import annotations

import dataclasses
from numbers import Real
from typing import ClassVar, Literal

import numba
import numpy as np

from rmac_mj.agents.base import Agent
from rmac_mj.agents.exploration import Exploration
from rmac_mj.agents.planning import REHEARSAL, Planning, Replay
from rmac_mj.agents.spaces import ActionSpace, StateSpace
from rmac_mj.agents.task_knowledge import reward_rate
from rmac_mj.approximators.tile_coding import (
    Backend,
    TileCoder,
    TileCodingConfig,
    feature_count,
)
from rmac_mj.constraints import (
    BACKEND,
    TD_LAMBDA,
    InstanceOf,
    Interval,
    Options,
    TupleOf,
    check_config,
    invalid,
)

#: tile_low/tile_high: a bound per state dimension, None keeping the StateSpace's.
_TILE_BOUNDS = TupleOf([Interval(Real), None], what="a list of finite numbers or None entries")


@dataclasses.dataclass(frozen=True)
class StandardACConfig:
    """Hyperparameters of S-AC; defaults are the paper's (section 6.1) unless noted.

    The fields left None are set from the task (``task_units``, ``task_knowledge.with_task_units``);
    on the paper's pendulum each is the paper's value.

    Attributes:
      gamma: discount factor per control step. Paper: 0.97 per 0.03 s; None: 0.97 ** (dt / 0.03),
        the same horizon in seconds at the task's step dt.
      lam: trace decay lambda per control step. Paper: 0.65; None: 0.65 ** (dt / 0.03).
      alpha_a: actor learning rate (eq. 4). Paper: 0.005 at the pendulum's reward scale; None: 0.005
        times min(1, 5 pi^2 / the task's reward scale): slower on larger rewards (a TD error's size
        grows with the reward), never faster on smaller ones (the critic, learning once per real
        step from V = 0, would be outrun; docs/new-task.md). The scale is the task's, or where it
        declares none, the largest |r| of the real transitions so far.
      alpha_c: critic learning rate (eq. 3). Paper: 0.1.
      rate_split: which learning rates are divided over the ``num_tilings`` active weights:
        ``"both"``, ``"actor"`` or ``"none"`` (not in the paper; measured in docs/standard-ac.md).
      tile_coding: the tiling layout of actor and critic. Paper: 16 tilings of 7 x 7 tiles.
      tile_low, tile_high: range of the tile coder per state dimension, overriding the agent's
        StateSpace where given (e.g. a velocity range narrower than the task's nominal box; states
        outside are clipped). None: the StateSpace's box.
      exploration: Delta u schedule. Paper: sigma 1 every third step. A decay is supported;
        ``where`` must be 'always' (S-AC has no process model to measure its uncertainty).
      trace_cutoff: traces below this are dropped (set to 0); 0 keeps every nonzero trace.
      planning: simulated transitions in learned models between trials (``agents.planning``;
        S-AC learns the model only for this). Paper: none.
      replay: replay of stored real trials between trials (``agents.planning``). Paper: none.
      backend: ``"numba"`` (compiled) or ``"numpy"`` (reference); same results.
    """

    gamma: float | None = None
    lam: float | None = None
    alpha_a: float | None = None
    alpha_c: float = 0.1
    rate_split: Literal["both", "actor", "none"] = "both"
    tile_coding: TileCodingConfig = TileCodingConfig()
    tile_low: tuple[float, ...] | None = None
    tile_high: tuple[float, ...] | None = None
    exploration: Exploration = Exploration()
    trace_cutoff: float = 1e-5
    planning: Planning = Planning()
    replay: Replay = Replay()
    backend: Backend = "numba"

    #: The fields set from the task when left None: field -> (rule, value at the paper's pendulum).
    task_units: ClassVar[dict[str, tuple[str, float]]] = {
        "gamma": ("horizon", 0.97),
        "lam": ("horizon", 0.65),
        "alpha_a": ("reward_capped", 0.005),
    }
    parameter_constraints: ClassVar[dict[str, list]] = {
        **TD_LAMBDA,
        "alpha_a": [Interval(Real, 0, 1), None],
        "rate_split": [Options("both", "actor", "none")],
        "tile_coding": [InstanceOf(TileCodingConfig)],
        "tile_low": [_TILE_BOUNDS, None],
        "tile_high": [_TILE_BOUNDS, None],
        "exploration": [InstanceOf(Exploration)],
        "trace_cutoff": [Interval(Real, 0, 1, closed="left")],
        **REHEARSAL,
        "backend": BACKEND,
    }

    def __post_init__(self) -> None:
        check_config(self)
        if self.exploration.where != "always":
            raise invalid(
                "StandardACConfig",
                "exploration.where",
                self.exploration.where,
                "'always': S-AC learns no process model to be uncertain about",
            )


# --------------------------------------------------------------------------------------------------
# Compiled kernels. Each mirrors a numpy method of StandardActorCritic below (the numpy version), operation for operation.


@numba.njit(cache=True)
def _policy_numba(actor, tiles, low, high, out):
    """out = clip(sum_j actor[tiles[j]], low, high): pi(x), shape (m,)."""
    for i in range(out.shape[0]):
        s = 0.0
        for t in tiles:
            s += actor[t, i]
        out[i] = min(max(s, low[i]), high[i])
    return out


@numba.njit(cache=True)
def _act_numba(actor, tiles, low, high, noise, u, du):
    """Lines 6 and 8: u = clip(pi(x) + noise, low, high), du = u - pi(x), pi(x) saturated."""
    _policy_numba(actor, tiles, low, high, du)
    for i in range(u.shape[0]):
        u[i] = min(max(du[i] + noise[i], low[i]), high[i])
        du[i] = u[i] - du[i]


@numba.njit(cache=True)
def _learn_numba(
    critic,
    actor,
    traces,
    trace_idx,
    n_traces,
    prev_tiles,
    tiles,
    reward,
    gamma,
    decay,
    cutoff,
    a_critic,
    a_actor,
    prev_du,
    a_low,
    a_high,
):
    """Lines 10-13 of Algorithm 1 in place; returns (delta_k, number of live traces)."""
    v_prev = 0.0
    v_next = 0.0
    for t in prev_tiles:
        v_prev += critic[t]
    for t in tiles:
        v_next += critic[t]
    delta = reward + gamma * v_next - v_prev
    if not np.isfinite(delta):
        return delta, n_traces  # overflow: refused, nothing changed (the caller says so)
    # Line 12 moves each weight with a trace (at most 1) by at most |a_critic delta|: refused
    # before anything changes when that could pass the largest float.
    largest = 0.0
    for i in range(n_traces):
        largest = max(largest, abs(critic[trace_idx[i]]))
    for t in prev_tiles:
        largest = max(largest, abs(critic[t]))
    if not np.isfinite(largest + abs(a_critic * delta)):
        return np.inf, n_traces
    # Line 11: decay the live traces, drop the ones below the cutoff, replace those of x_{k-1}.
    live = 0
    for i in range(n_traces):
        t = trace_idx[i]
        traces[t] *= decay
        if traces[t] >= cutoff:
            trace_idx[live] = t
            live += 1
        else:
            traces[t] = 0.0
    for t in prev_tiles:
        if traces[t] == 0.0:
            trace_idx[live] = t
            live += 1
        traces[t] = 1.0
    # Line 12.
    step = a_critic * delta
    for i in range(live):
        t = trace_idx[i]
        critic[t] += step * traces[t]
    # Line 13, keeping pi(x_{k-1}) within the bounds.
    num_tilings = prev_tiles.shape[0]
    for i in range(actor.shape[1]):
        if prev_du[i] == 0.0:
            continue
        s = a_actor * delta * prev_du[i]
        raw = 0.0
        for t in prev_tiles:
            raw += actor[t, i]
        new = raw + num_tilings * s
        if new > max(a_high[i], raw) or new < min(a_low[i], raw):
            new = min(max(new, min(a_low[i], raw)), max(a_high[i], raw))
            s = (new - raw) / num_tilings
        for t in prev_tiles:
            actor[t, i] += s
    return delta, live


class StandardActorCritic(Agent):
    """Standard actor-critic (Algorithm 1) with tile-coded actor and critic.

    Per control step k:

    * line 6:  Delta u_k, Gaussian noise every ``exploration.period``-th step, else 0 (section 6.1);
    * line 8:  u_k = pi(x_k, vartheta_{k-1}) + Delta u_k, saturated to the action bounds;
    * line 10: delta_k = r_k + gamma V(x_k, theta_{k-1}) - V(x_{k-1}, theta_{k-1})          (eq. 2);
    * line 11: replacing traces, e(tiles of x_{k-1}) = 1, all others decay by lambda * gamma;
    * line 12: theta_k = theta_{k-1} + alpha_c delta_k sum_x dV/dtheta(x) e_k(x)           (eq. 3);
    * line 13: vartheta_k = vartheta_{k-1} + alpha_a delta_k Delta u_{k-1} dpi/dvartheta(x_{k-1})
      (eq. 4).

    Where the paper is silent or ambiguous:

    * **Whose trace is set (line 11).** Algorithm 1 writes e_k(x_k) = 1, but delta_k is the TD error
      of x_{k-1} (eq. 2) and eq. 3 updates V at x_{k-1}; the trace of x_{k-1} is set to 1, Sutton
      and Barto's TD(lambda) with replacing traces, which reduces to eq. 3 for lambda = 0.
    * **Learning rate per tiling or split** (``rate_split``): dV/dtheta is 1 on each of the T active
      tiles, so a step of alpha on every active weight moves V(x) by T alpha. ``"both"`` divides
      alpha_c and alpha_a by T, ``"actor"`` only alpha_a, ``"none"`` applies both in full.
    * **The exploration in eq. 4** is the perturbation actually applied, u_{k-1} - pi(x_{k-1}) after
      saturation: noise that the bounds cut off was not tried, so it is not credited.
    * **The actor's output stays within the action bounds**: pi(x) is read saturated, and an actor
      update never pushes pi(x_{k-1}) beyond a bound (it may move it back inside).
    * **End of a trial** (``stop``): a time limit bootstraps the last TD error from V(x_K); a
      terminal state (``stop(..., terminal=True)``) takes V(x_K) = 0.
    * **Finite traces** (footnote 1): traces below ``trace_cutoff`` are exactly 0 (with lambda gamma
      = 0.63 and the default 1e-5: the last ~25 states).

    Args:
      state_space: the task's nominal state box (n dimensions).
      action_space: the action bounds (m dimensions); actions and pi(x) are saturated to them.
      config: hyperparameters.
      seed: seed or Generator of the exploration noise.

    Attributes (learned state ends in an underscore):
      critic_: ndarray of shape (num_features,), theta.
      actor_: ndarray of shape (num_features, m), vartheta.
      last_delta_: the most recent TD error delta_k.
    """

    name = "s-ac"
    display_name = "S-AC"
    config_class = StandardACConfig

    def __init__(
        self,
        state_space: StateSpace,
        action_space: ActionSpace,
        config: StandardACConfig = StandardACConfig(),
        seed: int | np.random.Generator | None = None,
    ) -> None:
        super().__init__(state_space, action_space, config, seed)
        config = self.config  # with the task's units (Agent.__init__)

        low, high = state_space.low.copy(), state_space.high.copy()
        for name, bound in (("tile_low", low), ("tile_high", high)):
            override = getattr(config, name)
            if override is None:
                continue
            if len(override) != state_space.dim:
                raise ValueError(
                    f"StandardACConfig.{name} has {len(override)} entries, the state has "
                    f"{state_space.dim} dimensions"
                )
            for d, v in enumerate(override):
                if v is not None:
                    bound[d] = v
        self.coder = TileCoder(low, high, state_space.periodic, config.tile_coding, config.backend)
        T = self.coder.num_tilings
        #: The step per active weight of the critic and of the actor (see ``rate_split``).
        self.rate_c = config.alpha_c / T if config.rate_split == "both" else config.alpha_c
        self._split_a = T if config.rate_split in ("both", "actor") else 1
        #: The largest |r| of the real transitions so far, the reward's scale alpha_a follows when
        #: the task declares none (config.alpha_a None); None when alpha_a is fixed.
        self.reward_scale_ = None if config.alpha_a is not None else 0.0
        self._learns_scale = True
        self._set_rate_a()
        self._decay = config.gamma * config.lam
        self._a_low = action_space.low
        self._a_high = action_space.high
        m = action_space.dim

        # Algorithm 1 line 2: theta_0 = 0 (V starts at 0, section 6.1) and vartheta_0 = 0.
        self.critic_ = np.zeros(self.coder.num_features)
        self.actor_ = np.zeros((self.coder.num_features, m))
        self._traces = np.zeros(self.coder.num_features)
        self._trace_idx = np.zeros(self.coder.num_features, dtype=np.int64)
        self._n_traces = 0
        self._prev_tiles = np.zeros(T, dtype=np.int64)
        self._tiles = np.zeros(T, dtype=np.int64)
        #: Where a step's tiles are found before the step is learned (committed when it is not
        #: refused); not part of the state.
        self._next_tiles = np.zeros(T, dtype=np.int64)
        self._prev_du = np.zeros(m)
        self._k = 0  # control step within the trial
        self.last_delta_ = 0.0

    @classmethod
    def _memory_parts(
        cls, config: StandardACConfig, state_space: StateSpace, action_space: ActionSpace
    ) -> tuple[int, int]:
        """theta, vartheta (one weight per tile, times m), the traces and their index, and the
        tilings' offsets (see :meth:`Agent.memory_estimate`), counted without building the coder."""
        features = feature_count(state_space.periodic, config.tile_coding)
        offsets = 8 * config.tile_coding.num_tilings * (state_space.dim + 2)
        per_feature = 8 * (3 + action_space.dim)
        return per_feature * features + offsets, per_feature * features

    def _set_rate_a(self) -> None:
        self.rate_a = self._rate_a(self.reward_scale_)

    def _rate_a(self, reward_scale: float | None) -> float:
        """The step per active weight of the actor with the reward's running scale ``reward_scale``."""
        alpha_a = self.config.alpha_a
        if alpha_a is None:
            rule, paper_rate = type(self.config).task_units["alpha_a"]
            alpha_a = reward_rate(paper_rate, reward_scale, rule)
        return alpha_a / self._split_a if self._split_a != 1 else alpha_a

    def _set_rehearsing(self, rehearsing: bool) -> None:
        """While rehearsing (planning, replay), the reward's running scale stays as it is."""
        self._learns_scale = not rehearsing

    # ----------------------------------------------------------------------------------- protocol
    def _start(self, x0: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Lines 1-4: reset the traces, apply u_0 = pi(x_0) + Delta u_0 (or the given u_0, when
        replaying); returns shape (m,)."""
        self._traces[self._trace_idx[: self._n_traces]] = 0.0
        self._n_traces = 0
        self._k = 0
        self._tiles_of(x0, self._prev_tiles)
        u, self._prev_du = self._act(self._prev_tiles, 0, u)
        return u

    def _step(self, reward: float, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Lines 6-14 for r_k and x_k; returns u_k of shape (m,) (the given u_k, when replaying).
        A refused transition changes nothing: the tiles and the step count are committed after."""
        k, tiles = self._k + 1, self._next_tiles
        self._tiles_of(x, tiles)
        u, du = self._act(tiles, k, u)  # line 8 uses vartheta_{k-1}: act before learning
        self._learn(reward, self.config.gamma, tiles)
        self._k, self._next_tiles, self._tiles = k, self._tiles, tiles
        self._prev_tiles, self._tiles = self._tiles, self._prev_tiles
        self._prev_du = du
        return u

    def _stop(self, reward: float, x: np.ndarray, terminal: bool) -> None:
        """Learn from the trial's last transition: bootstrapping from V(x_K), or, when x_K is
        terminal, from its value 0 (the discount of that one update is 0)."""
        tiles = self._next_tiles
        self._tiles_of(x, tiles)
        self._learn(reward, 0.0 if terminal else self.config.gamma, tiles)
        self._next_tiles, self._tiles = self._tiles, tiles

    def _greedy_action(self, x: np.ndarray) -> np.ndarray:
        """pi(x) saturated to the action bounds, shape (m,); no exploration, no learning."""
        return self._policy(self.coder.active_tiles(x))

    def _value(self, x: np.ndarray) -> float:
        """V(x, theta)."""
        return float(self.critic_[self.coder.active_tiles(x)].sum())

    # ------------------------------------------------------------------------------------- state
    def _state(self) -> dict[str, np.ndarray]:
        """theta, vartheta, the eligibility traces and the running trial's bookkeeping."""
        return {
            "critic": self.critic_.copy(),
            "actor": self.actor_.copy(),
            "traces": self._traces.copy(),
            "trace_idx": self._trace_idx.copy(),
            "n_traces": np.array(self._n_traces),
            "prev_tiles": self._prev_tiles.copy(),
            "tiles": self._tiles.copy(),
            "prev_du": self._prev_du.copy(),
            "k": np.array(self._k),
            "last_delta": np.array(self.last_delta_),
            **(
                {} if self.reward_scale_ is None else {"reward_scale": np.array(self.reward_scale_)}
            ),
        }

    def _check_state(self, state: dict[str, np.ndarray]) -> None:
        features, n_traces = self.coder.num_features, int(state["n_traces"])
        if not 0 <= n_traces <= features:
            raise ValueError(f"s-ac: state 'n_traces' must lie in [0, {features}], got {n_traces}")
        for key, entries in (
            ("trace_idx", state["trace_idx"][:n_traces]),
            ("prev_tiles", state["prev_tiles"]),
            ("tiles", state["tiles"]),
        ):
            if np.any((entries < 0) | (entries >= features)):
                raise ValueError(f"s-ac: state {key!r} must hold tile indices in [0, {features})")
        if np.any((state["traces"] < 0) | (state["traces"] > 1)) or int(state["k"]) < 0:
            raise ValueError("s-ac: state 'traces' must lie in [0, 1] and 'k' be >= 0")
        if "reward_scale" in state and not float(state["reward_scale"]) >= 0:
            raise ValueError("s-ac: state 'reward_scale' must be a finite number >= 0")

    def _load_state(self, state: dict[str, np.ndarray]) -> None:
        self.critic_ = np.array(state["critic"], dtype=float)
        self.actor_ = np.array(state["actor"], dtype=float)
        self._traces = np.array(state["traces"], dtype=float)
        self._trace_idx = np.array(state["trace_idx"], dtype=np.int64)
        self._prev_tiles = np.array(state["prev_tiles"], dtype=np.int64)
        self._tiles = np.array(state["tiles"], dtype=np.int64)
        self._prev_du = np.array(state["prev_du"], dtype=float)
        self._n_traces = int(state["n_traces"])
        self._k = int(state["k"])
        self.last_delta_ = float(state["last_delta"])
        if self.reward_scale_ is not None:
            self.reward_scale_ = float(state["reward_scale"])
            self._set_rate_a()

    # ---------------------------------------------------------------------------------- internals
    def _tiles_of(self, x: np.ndarray, out: np.ndarray) -> None:
        """Active tiles of a checked x, written into ``out``."""
        if self.config.backend == "numba":
            self.coder.active_tiles_into(x, out)
        else:
            out[:] = self.coder._active_tiles_numpy(self.coder.check_state(x))

    def _policy(self, tiles: np.ndarray) -> np.ndarray:
        if self.config.backend == "numba":
            return _policy_numba(
                self.actor_, tiles, self._a_low, self._a_high, np.empty(self.action_space.dim)
            )
        return np.clip(self.actor_[tiles].sum(axis=0), self._a_low, self._a_high)

    def _act(
        self, tiles: np.ndarray, k: int, u: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Lines 6 and 8: u_k = sat(pi(x_k) + Delta u_k) and the applied exploration u_k - pi(x_k);
        a given u_k (replay) is taken as applied, its exploration relative to today's pi(x_k)."""
        if u is not None:
            return u.copy(), u - self._policy(tiles)
        noise = self.config.exploration.sample(k, self.action_space.dim, self.rng, self.trial)
        if self.config.backend == "numba":
            m = self.action_space.dim
            u, du = np.empty(m), np.empty(m)
            _act_numba(self.actor_, tiles, self._a_low, self._a_high, noise, u, du)
            return u, du
        pi = self._policy(tiles)
        u = np.clip(pi + noise, self._a_low, self._a_high)
        return u, u - pi

    def _learn(self, reward: float, gamma: float, tiles: np.ndarray) -> None:
        """Lines 10-13 for the transition x_{k-1} -> x_k (tiles in _prev_tiles and ``tiles``), with
        the discount ``gamma`` of V(x_k) in the TD error (0 for a terminal x_k). A transition
        whose update would overflow is refused before anything changes."""
        c = self.config
        scale, rate_a = self.reward_scale_, self.rate_a
        if scale is not None and self._learns_scale and abs(reward) > scale:
            scale = abs(reward)
            rate_a = self._rate_a(scale)
        if c.backend == "numba":
            delta, n_traces = _learn_numba(
                self.critic_,
                self.actor_,
                self._traces,
                self._trace_idx,
                self._n_traces,
                self._prev_tiles,
                tiles,
                reward,
                gamma,
                self._decay,
                c.trace_cutoff,
                self.rate_c,
                rate_a,
                self._prev_du,
                self._a_low,
                self._a_high,
            )
            if not np.isfinite(delta):
                raise self._overflow(f"the TD error with reward {reward!r}")
            self.last_delta_, self._n_traces = delta, n_traces
        else:
            self._learn_numpy(reward, gamma, tiles, rate_a)
        if scale != self.reward_scale_:
            self.reward_scale_, self.rate_a = scale, rate_a

    def _learn_numpy(self, reward: float, gamma: float, tiles: np.ndarray, rate_a: float) -> None:
        """Reference implementation of lines 10-13 (dense traces, same cutoff): the new traces and
        critic are computed aside and kept only when finite."""
        c, prev = self.config, self._prev_tiles
        # Line 10 (eq. 2).
        delta = reward + gamma * self.critic_[tiles].sum() - self.critic_[prev].sum()
        if not np.isfinite(delta):
            raise self._overflow(f"the TD error with reward {reward!r}")
        # Line 11: replacing traces; the trace of x_{k-1}, whose value is being corrected, is set.
        traces = self._traces * self._decay
        traces[traces < c.trace_cutoff] = 0.0
        traces[prev] = 1.0
        # Line 12 (eq. 3 with traces): dV/dtheta(x) is the indicator of x's tiles.
        critic = self.critic_ + (self.rate_c * delta) * traces
        if not np.all(np.isfinite(critic)):
            raise self._overflow(f"the TD error with reward {reward!r}")
        self._traces[:] = traces
        self._n_traces = int(np.count_nonzero(self._traces))
        self._trace_idx[: self._n_traces] = np.flatnonzero(self._traces)
        self.critic_[:] = critic
        # Line 13 (eq. 4): dpi/dvartheta(x_{k-1}) is the indicator of x_{k-1}'s tiles.
        T = prev.shape[0]
        raw = self.actor_[prev].sum(axis=0)
        step = rate_a * delta * self._prev_du
        new = raw + T * step
        lo, hi = np.minimum(self._a_low, raw), np.maximum(self._a_high, raw)
        clipped = (new > hi) | (new < lo)
        step = np.where(clipped, (np.clip(new, lo, hi) - raw) / T, step)
        step = np.where(self._prev_du == 0.0, 0.0, step)
        self.actor_[prev] += step
        self.last_delta_ = float(delta)
