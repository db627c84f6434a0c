"""The LLR critic RMAC and MLAC share: V(x) from samples [x | V], learned by TD(lambda).

Algorithm 2 lines 22-28, one eligibility trace per sample: :class:`LLRCritic` in Python
(``backend='numpy'``) or compiled (``backend='numba'``); RMAC's compiled step calls
:func:`td_update` directly on a :class:`CriticState`.
"""

from __future__ import annotations

import collections
import math

import numpy as np
from numba import njit, types
from numba.experimental import structref

from rmac_mj.approximators.llr import (
    LLR_STATE_TYPE,
    LLRMemory,
    llr_add_weighted,
    llr_canonical,
    llr_insert_among,
    llr_local_fit,
    llr_nearest,
    llr_size,
)

#: The TD settings of a critic: discount gamma, trace decay lambda, learning rate alpha_c.
CriticSettings = collections.namedtuple("CriticSettings", ["gamma", "lam", "alpha"])


@structref.register
class CriticStateType(types.StructRef):
    """The numba type of :class:`CriticState`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class CriticState(structref.StructRefProxy):
    """An LLR critic for compiled code: ``memory`` (the memory's LLRState), ``traces`` (N,) and the
    settings ``gamma``, ``lam``, ``alpha``. Made by :func:`new_critic`; opaque to Python."""


structref.define_boxing(CriticStateType, CriticState)

CRITIC_STATE_TYPE = CriticStateType(
    [
        ("memory", LLR_STATE_TYPE),
        ("traces", types.float64[::1]),
        ("gamma", types.float64),
        ("lam", types.float64),
        ("alpha", types.float64),
    ]
)


@njit(cache=True)
def new_critic(memory, traces, settings):
    """A :class:`CriticState` over a memory's state and a traces array (not copied), with its
    :class:`CriticSettings`."""
    critic = structref.new(CRITIC_STATE_TYPE)
    critic.memory = memory
    critic.traces = traces
    critic.gamma = settings.gamma
    critic.lam = settings.lam
    critic.alpha = settings.alpha
    return critic


@njit(cache=True)
def set_rate(critic, alpha):
    """alpha_c of the updates that follow (a trial's, when it decays)."""
    critic.alpha = alpha


@njit(cache=True, inline="always")
def value_fit(critic, x):
    """V(x) and its local linear model: a ``LocalFit`` (prediction (1,), beta (1, n+1)); periodic
    entries of x are wrapped here (as ``LLRMemory.query`` does). K(x) is kept for the update at x
    that follows one step later."""
    memory = critic.memory
    xq = np.empty(x.shape[0])
    llr_canonical(x, memory.in_period, xq)
    return llr_local_fit(memory, xq)


@njit(cache=True)
def td_bound(critic, v, reward, v_next):
    """A bound on every value after :func:`td_update` (inf: the update would overflow): |V_i| and
    |v| plus |alpha_c delta|, the traces being at most 1. Known before anything changes, so that
    a learner refuses an overflowing update with nothing changed."""
    delta = reward + critic.gamma * v_next - v
    if not np.isfinite(delta):
        return np.inf
    Y = critic.memory.Y
    largest = abs(v)
    for i in range(llr_size(critic.memory)):
        largest = max(largest, abs(Y[i, 0]))
    bound = largest + abs(critic.alpha * delta)
    return bound if np.isfinite(bound) else np.inf


@njit(cache=True, inline="always")
def td_overflows(critic, v, reward, v_next):
    """Whether the update of :func:`td_update` would overflow (:func:`td_bound`)."""
    return not np.isfinite(td_bound(critic, v, reward, v_next))


@njit(cache=True, inline="always")
def td_update(critic, x, v, reward, v_next):
    """Lines 23-27 for the transition from a canonical x with V(x) = ``v`` to x' with V(x') =
    ``v_next``: insert [x | v], then the TD(lambda) step on every sample. Returns delta; a delta
    that is not finite (arithmetic overflow) is returned without anything stored."""
    memory, traces = critic.memory, critic.traces
    delta = reward + critic.gamma * v_next - v  # line 24
    if not np.isfinite(delta):
        return delta  # refused: nothing is stored (the caller says so)
    near, nk = llr_nearest(memory, x)
    near = near[:nk].copy()  # K(x) before the insertion
    v_in = np.empty(1)
    v_in[0] = v
    slot = llr_insert_among(memory, x, v_in, near, nk)  # line 23
    decay = critic.lam * critic.gamma
    for i in range(llr_size(memory)):
        traces[i] *= decay  # line 26
    for a in range(nk):
        traces[near[a]] = 1.0
    traces[slot] = 1.0
    step = np.empty(1)
    step[0] = critic.alpha * delta
    llr_add_weighted(memory, traces, step)  # line 27
    return delta


def _check_traces(owner: str, state: dict[str, np.ndarray]) -> None:
    """ValueError unless a learner's state to restore holds traces in [0, 1] and a step k >= 0."""
    traces = state["traces"]
    if np.any((traces < 0) | (traces > 1)):
        raise ValueError(f"{owner}: state 'traces' must lie in [0, 1] (eligibility traces)")
    if int(state["k"]) < 0:
        raise ValueError(f"{owner}: state 'k' must be >= 0, got {int(state['k'])}")


class LLRCritic:
    """V(x) by an LLR memory and TD(lambda) with one trace per sample.

    One transition (x, r, x') with V(x) = v is learned as (Algorithm 2)::

        V' = V(x')                                                       line 22
        insert [x | v] in M^C                                            line 23
        delta = r + gamma V' - v                                         line 24
        e_i = 1 for i in K_+(x) (K(x) and the inserted sample), else lambda gamma e_i   line 26
        V_i <- V_i + alpha_c delta e_i for every sample i                line 27

    Args:
      memory: the critic memory M^C, samples [x | V] (output_dim 1); its ``backend`` decides whether
        the update runs compiled.
      gamma, lam: discount and trace decay.
      alpha: the learning rate alpha_c (``alpha`` may be changed between updates).

    State: ``memory`` and ``traces`` (shape (capacity,), e(s_i) of line 26).
    """

    def __init__(self, memory: LLRMemory, gamma: float, lam: float, alpha: float) -> None:
        if memory.output_dim != 1:
            raise ValueError(
                f"LLRCritic: the memory must hold values (output_dim 1), got "
                f"output_dim={memory.output_dim}"
            )
        self.memory = memory
        self.gamma, self.lam, self._alpha = float(gamma), float(lam), float(alpha)
        self.traces = np.zeros(memory.capacity)
        self.kernel_state = self._new_kernel_state()

    def _new_kernel_state(self) -> CriticState | None:
        if self.memory.backend != "numba":
            return None
        return new_critic(
            self.memory.kernel_state,
            self.traces,
            CriticSettings(gamma=self.gamma, lam=self.lam, alpha=self._alpha),
        )

    def __getstate__(self) -> dict:
        # The structref is a view of the arrays pickled here; it is made anew when unpickled.
        return {k: v for k, v in self.__dict__.items() if k != "kernel_state"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.kernel_state = self._new_kernel_state()

    @property
    def alpha(self) -> float:
        """alpha_c, the learning rate of the updates that follow."""
        return self._alpha

    @alpha.setter
    def alpha(self, value: float) -> None:
        self._alpha = float(value)
        if self.kernel_state is not None:
            set_rate(self.kernel_state, self._alpha)

    def begin_trial(self) -> None:
        """Line 3: every trace 0."""
        self.traces[:] = 0.0

    def value(self, x: np.ndarray) -> float:
        """V(x), the memory's LLR estimate (0 on an empty memory, line 2)."""
        return float(self.memory.query(x)[0][0])

    def update(
        self, x: np.ndarray, v: float, reward: float, x_next: np.ndarray
    ) -> tuple[float, float]:
        """Lines 22-27 for the transition from the canonical x, with V(x) = ``v``, to the canonical
        x_next with reward ``reward``; returns V(x_next), computed before the update (line 22), and
        delta (not finite: the update was refused, nothing stored)."""
        v_next = self.next_value(x_next)  # line 22
        return v_next, self.td_update(x, v, reward, v_next)

    def next_value(self, x_next: np.ndarray) -> float:
        """V(x') of line 22 for the canonical x_next, as :meth:`update` computes it (compiled: K(x')
        is kept for the update at x' one step later)."""
        if self.kernel_state is not None:
            return float(value_fit(self.kernel_state, x_next).prediction[0])
        return self.value(x_next)

    def overflows(self, v: float, reward: float, v_next: float) -> bool:
        """Whether :meth:`td_update` with these values would overflow (see :func:`td_bound`); a
        learner asks before it changes anything."""
        return not math.isfinite(self.update_bound(v, reward, v_next))

    def update_bound(self, v: float, reward: float, v_next: float) -> float:
        """A bound on every value after :meth:`td_update` with these values, inf when it would
        overflow (:func:`td_bound`)."""
        if self.kernel_state is not None:
            return float(td_bound(self.kernel_state, v, reward, v_next))
        delta = reward + self.gamma * v_next - v
        if not math.isfinite(delta):
            return math.inf
        values = self.memory.Y_[: self.memory.n_samples_, 0]
        largest = max(abs(v), float(np.abs(values).max())) if len(values) else abs(v)
        bound = largest + abs(self._alpha * delta)
        return bound if math.isfinite(bound) else math.inf

    def td_update(self, x: np.ndarray, v: float, reward: float, v_next: float) -> float:
        """Lines 23-27 (see :func:`td_update`); returns delta. A delta that is not finite (the
        values overflow) is returned with nothing stored."""
        if self.kernel_state is not None:
            return float(td_update(self.kernel_state, x, v, reward, v_next))
        delta = reward + self.gamma * v_next - v  # line 24
        if not math.isfinite(delta):
            return delta
        near = self.memory.neighbours(x)
        slot = self.memory.insert(x, [v], int(near[0]) if len(near) else None)  # line 23
        self.traces *= self.lam * self.gamma  # line 26
        self.traces[near] = 1.0
        self.traces[slot] = 1.0
        self.memory.add_weighted(self.traces, [self._alpha * delta])  # line 27
        return delta
