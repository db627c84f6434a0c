"""Numba kernels of LLR on one memory: the fast path of :class:`~.llr.LLRMemory`.

Each follows the numpy reference (``llr_numpy``) step by step: the same neighbours and, up to
rounding, the same local models. A memory is an :class:`LLRState` (fields listed there);
:func:`nearest` keeps neighbour lists across insertions, :func:`query` keeps nothing.
"""

from __future__ import annotations

import collections

import numpy as np
from numba import njit, types
from numba.experimental import structref

from rmac_mj.approximators._llr_fit import fit
from rmac_mj.approximators._llr_redundancy import score
from rmac_mj.approximators._llr_search import canonical, distances, place, smallest, wrap

# Codes shared with llr.py.
REPLACE_OLDEST = 0
REPLACE_NEAREST = 1
REPLACE_REDUNDANCY = 2
#: Indices of ``counters``.
COUNT, CLOCK, VERSION = 0, 1, 2
#: How many neighbour lists a memory keeps: a learner's current and previous state, and one more so
#: that a search out of turn (the first state of a trial, a simulated transition) does not evict them.
KEPT = 3

#: The memory's own arrays (see :class:`LLRState`), shared with ``LLRMemory``.
LLRArrays = collections.namedtuple(
    "LLRArrays",
    ["Xt", "Y", "stamp", "counters", "redundancy", "weights", "in_period", "out_period"],
)
#: The memory's settings (see :class:`LLRState`).
LLRSettings = collections.namedtuple(
    "LLRSettings",
    ["n_neighbours", "norm", "clip", "replacement", "eig_cutoff", "ridge", "measure", "smoothing"],
)
#: A local affine model: the prediction (m,) at the query point and beta (m, n+1), with
#: beta @ [x; 1] == prediction at the query point (offsets of periodic inputs wrapped).
LocalFit = collections.namedtuple("LocalFit", ["prediction", "beta"])


@structref.register
class LLRStateType(types.StructRef):
    """The numba type of :class:`LLRState`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class LLRState(structref.StructRefProxy):
    """A memory's arrays and settings, named, for compiled code.

    Made by :func:`new_state` from :class:`LLRArrays` and :class:`LLRSettings`; opaque to Python
    (read the arrays through the owning ``LLRMemory``). Fields:

    ======================  ========================================================================
    ``Xt``                  (n, N) inputs, stored by dimension so that the distance loop runs over
                            contiguous memory and vectorises; periodic inputs are kept in
                            [-period/2, period/2)
    ``Y``                   (N, m) outputs
    ``stamp``               (N,) int64 insertion times
    ``counters``            int64 (3,): ``counters[COUNT]`` samples stored, ``counters[CLOCK]`` the
                            next stamp, ``counters[VERSION]`` changes to the inputs (any insert,
                            fit, reset or load), so that a neighbour list can tell whether it is
                            still current; read them with :func:`size` and :func:`version`
    ``redundancy``          (N,) redundancy score of each sample (higher: more redundant), kept only
                            under ``REPLACE_REDUNDANCY`` (see ``insert_among``)
    ``weights``             (n,) input weights of the distance and of the regression
    ``in_period``           (n,) period of each periodic input, 0 elsewhere
    ``out_period``          (m,) period of each periodic output, 0 elsewhere
    ``n_neighbours``        K
    ``norm``                1 or 2
    ``clip``                clip predictions to the neighbours' output range
    ``replacement``         ``REPLACE_OLDEST``, ``REPLACE_NEAREST`` or ``REPLACE_REDUNDANCY``
    ``eig_cutoff``          relative eigenvalue cutoff of the normal matrix (see ``_llr_fit.fit``)
    ``ridge``               ridge added to the slopes' diagonal
    ``measure``             ``MEASURE_DISTANCE`` or ``MEASURE_MISFIT``: what the redundancy measures
    ``smoothing``           eta, the exponential smoothing factor of the scores
    ``dist``, ``best``,     scratch space of the neighbour search: (N,) distances, (K+1,) the
    ``seen``, ``lanes``     distances of a list, (N,) flags (all False between searches), (L,) lane
                            minima
    ``last_point``          (n,) where the last search was made, ``last_nearest`` the nearest sample
                            it found (-1: none) and ``last_version`` the memory's version then
    ``kept_*``              the neighbour lists the memory keeps (:func:`nearest`): ``kept_idx``
                            (KEPT, K+1), ``kept_dist`` (KEPT, K+1), ``kept_count`` (KEPT,) entries
                            (-1: none), ``kept_version`` (KEPT,), ``kept_point`` (KEPT, n),
                            ``kept_used`` (KEPT,) when each was last asked for, on the clock
                            ``kept_clock``; a new search replaces the least recently used
    ======================  ========================================================================
    """


structref.define_boxing(LLRStateType, LLRState)

_VECTOR = types.float64[::1]
_MATRIX = types.float64[:, ::1]
_INTS = types.int64[::1]
#: The one concrete type of every LLRState (C-contiguous float64/int64 arrays).
LLR_STATE_TYPE = LLRStateType(
    [
        ("Xt", _MATRIX),
        ("Y", _MATRIX),
        ("stamp", _INTS),
        ("counters", _INTS),
        ("redundancy", _VECTOR),
        ("weights", _VECTOR),
        ("in_period", _VECTOR),
        ("out_period", _VECTOR),
        ("n_neighbours", types.int64),
        ("norm", types.int64),
        ("clip", types.boolean),
        ("replacement", types.int64),
        ("eig_cutoff", types.float64),
        ("ridge", types.float64),
        ("measure", types.int64),
        ("smoothing", types.float64),
        ("dist", _VECTOR),
        ("best", _VECTOR),
        ("seen", types.boolean[::1]),
        ("lanes", _VECTOR),
        ("last_nearest", types.int64),
        ("last_point", _VECTOR),
        ("last_version", types.int64),
        ("kept_idx", types.int64[:, ::1]),
        ("kept_dist", _MATRIX),
        ("kept_count", _INTS),
        ("kept_version", _INTS),
        ("kept_point", _MATRIX),
        ("kept_used", _INTS),
        ("kept_clock", types.int64),
    ]
)


@njit(cache=True)
def new_state(arrays, settings):
    """An :class:`LLRState` over the memory's ``arrays`` (an :class:`LLRArrays`, not copied) with its
    ``settings`` (an :class:`LLRSettings`) and fresh scratch space."""
    state = structref.new(LLR_STATE_TYPE)
    state.Xt = arrays.Xt
    state.Y = arrays.Y
    state.stamp = arrays.stamp
    state.counters = arrays.counters
    state.redundancy = arrays.redundancy
    state.weights = arrays.weights
    state.in_period = arrays.in_period
    state.out_period = arrays.out_period
    state.n_neighbours = settings.n_neighbours
    state.norm = settings.norm
    state.clip = settings.clip
    state.replacement = settings.replacement
    state.eig_cutoff = settings.eig_cutoff
    state.ridge = settings.ridge
    state.measure = settings.measure
    state.smoothing = settings.smoothing
    n, capacity, k = arrays.Xt.shape[0], arrays.Y.shape[0], settings.n_neighbours
    state.dist = np.empty(capacity)
    state.best = np.empty(k + 1)
    state.seen = np.zeros(capacity, dtype=np.bool_)
    n_lanes = 64
    while n_lanes < 2 * (k + 1):
        n_lanes *= 2
    state.lanes = np.empty(n_lanes)
    state.last_nearest = -1
    state.last_point = np.empty(n)
    state.last_version = -1
    state.kept_idx = np.zeros((KEPT, k + 1), dtype=np.int64)
    state.kept_dist = np.zeros((KEPT, k + 1))
    state.kept_count = np.full(KEPT, -1, dtype=np.int64)
    state.kept_version = np.zeros(KEPT, dtype=np.int64)
    state.kept_point = np.zeros((KEPT, n))
    state.kept_used = np.zeros(KEPT, dtype=np.int64)
    state.kept_clock = 0
    return state


@njit(cache=True, inline="always")
def size(state):
    """The number of samples stored."""
    return state.counters[COUNT]


@njit(cache=True, inline="always")
def version(state):
    """The count of changes to the memory's inputs so far."""
    return state.counters[VERSION]


# -- state-level operations ---------------------------------------------------------------------


@njit(cache=True)
def _search(state, xq, k, idx_out, best, seed):
    """The min(k, count) nearest samples to a canonical xq, by (distance, index), with their
    distances (``seed``: see ``smallest``); remembers where it searched and the nearest sample (see
    ``insert``)."""
    count = state.counters[COUNT]
    distances(state.Xt, 0, count, xq, state.weights, state.in_period, state.norm, state.dist)
    nk = smallest(state.dist, count, k, idx_out, best, seed, state.seen, state.lanes)
    state.last_nearest = idx_out[0] if nk > 0 else -1
    for j in range(xq.shape[0]):
        state.last_point[j] = xq[j]
    state.last_version = state.counters[VERSION]
    return nk


@njit(cache=True, inline="always")
def fit_at(state, xq, idx, nk, beta_out, pred_out):
    """The local model at a canonical xq from the neighbours ``idx[:nk]`` (see ``fit``)."""
    fit(state.Xt, state.Y, idx, nk, xq, state, state.clip, beta_out, pred_out)


@njit(cache=True)
def query(state, x, idx_out, beta_out, pred_out):
    """Neighbour search and fit at ``x`` (shape (n,)); writes the neighbours (nearest first) to
    ``idx_out`` (K,), the local model to ``beta_out`` (m, n+1) and the prediction to ``pred_out``
    (m,); returns the number of neighbours found (-1: x not finite)."""
    if not np.all(np.isfinite(x)):
        return -1
    xq = np.empty(x.shape[0])
    canonical(x, state.in_period, xq)
    nk = _search(state, xq, state.n_neighbours, idx_out, state.best, idx_out[:0])
    fit_at(state, xq, idx_out, nk, beta_out, pred_out)
    return nk


@njit(cache=True)
def neighbours(state, xq, idx_out):
    """K(xq) for a canonical xq (periodic entries in [-period/2, period/2)): the nearest samples,
    nearest first, written to ``idx_out`` (K,); returns how many."""
    return _search(state, xq, state.n_neighbours, idx_out, state.best, idx_out[:0])


@njit(cache=True, inline="always")
def candidates(state, xq, idx_out, dist_out, seed):
    """The min(K+1, count) nearest samples to a canonical xq, nearest first, with their distances
    (``idx_out``, ``dist_out``: shape (K+1,)); returns how many. The first min(K, count) are K(xq),
    and the list can be carried across one insertion with ``refresh``. ``seed``: distinct samples
    likely near xq (e.g. such a list of a point close by), to search faster; empty for none. The
    result does not depend on them."""
    return _search(state, xq, state.n_neighbours + 1, idx_out, dist_out, seed)


@njit(cache=True, inline="always")
def refresh(state, xq, idx, dist, n, slot):
    """Carry the complete neighbour list ``idx[:n]`` of a canonical xq (the min(K+1, count) nearest
    samples, as ``candidates`` gives them), with distances ``dist[:n]``, across one insertion into
    ``slot``; returns how many of its entries are now exact (at least min(K, count)).

    Every other sample kept its distance and every sample outside the list lies beyond all of it.
    So the replaced sample leaves the list and the new one is placed by its distance; the list is
    then exact except, when the replaced sample was in it, for a new sample that ranks last (a
    sample outside the list may lie before it), which is dropped.
    """
    capacity = idx.shape[0]
    distances(state.Xt, slot, slot + 1, xq, state.weights, state.in_period, state.norm, state.dist)
    kept = np.int64(0)  # not a literal 0, for which numba would compile place once more
    for a in range(n):
        if idx[a] != slot:
            idx[kept] = idx[a]
            dist[kept] = dist[a]
            kept += 1
    removed = kept < n
    outsiders = state.counters[COUNT] > n  # samples that were not in the list
    n = place(dist, idx, kept, capacity, state.dist[slot], slot)
    if removed and outsiders and n == kept + 1 and idx[kept] == slot:
        n = kept
    return n


@njit(cache=True, inline="always")
def _kept_at(state, xq):
    """The kept list searched at the canonical xq on the memory as it is, -1 if none."""
    for c in range(KEPT):
        if state.kept_count[c] >= 0 and state.kept_version[c] == state.counters[VERSION]:
            same = True
            for j in range(xq.shape[0]):
                same = same and state.kept_point[c, j] == xq[j]
            if same:
                return c
    return -1


@njit(cache=True)
def nearest(state, xq):
    """K(xq) for a canonical xq, nearest first: ``(indices, how many)``, exactly what a new search
    gives. The indices are a view of the kept list: copy them to keep them past the next change of
    the memory.

    A learner comes back to the points it visits: RMAC asks for K(x_k) when it acts in x_k and again
    one step later, when x_k has become x_{k-1} and the memory has taken one insertion. The K+1
    nearest samples of the ``KEPT`` points last asked about are kept, and every insertion carries
    each kept list across itself (:func:`refresh`: the replaced sample leaves, the new one is placed
    by its distance, every other sample keeps its distance), which gives exactly the list a new
    search would (docs/performance.md); a list that can no longer vouch for K entries, or whose
    memory changed otherwise (a fit, a reset, a load), is searched again. :func:`insert` takes the
    nearest sample from the last search when that was made at the same point on the memory as it
    is."""
    c = _kept_at(state, xq)
    if c < 0:
        c = int(np.argmin(state.kept_used))  # the least recently used list gives way
        seeds = int(np.argmax(state.kept_used))  # the last one asked for: near xq on a trajectory
        n_seeds = max(state.kept_count[seeds], 0) if seeds != c else 0
        state.kept_count[c] = candidates(
            state, xq, state.kept_idx[c], state.kept_dist[c], state.kept_idx[seeds, :n_seeds]
        )
        state.kept_version[c] = state.counters[VERSION]
        for j in range(xq.shape[0]):
            state.kept_point[c, j] = xq[j]
    state.kept_clock += 1
    state.kept_used[c] = state.kept_clock
    return state.kept_idx[c], min(state.kept_count[c], state.n_neighbours)


@njit(cache=True)
def local_fit(state, xq):
    """The local affine model at a canonical xq from K(xq) (:func:`nearest`): a :class:`LocalFit`."""
    idx, nk = nearest(state, xq)
    m, n = state.Y.shape[1], xq.shape[0]
    prediction = np.empty(m)
    beta = np.empty((m, n + 1))
    fit_at(state, xq, idx, nk, beta, prediction)
    return LocalFit(prediction, beta)


@njit(cache=True, inline="always")
def _carry_kept(state, before, count_before, slot):
    """Carry the kept lists of version ``before`` across the insertion into ``slot`` (``refresh``),
    which the memory took holding ``count_before`` samples. Only a complete list, the min(K+1,
    count_before) nearest samples, can be carried; one that ``refresh`` shortened is dropped at the
    next insertion (an outside sample might then come before a newcomer it ranks last)."""
    complete = min(state.n_neighbours + 1, count_before)
    for c in range(KEPT):
        if state.kept_count[c] < 0 or state.kept_version[c] != before:
            continue
        if state.kept_count[c] != complete:
            state.kept_count[c] = -1
            continue
        state.kept_count[c] = refresh(
            state,
            state.kept_point[c],
            state.kept_idx[c],
            state.kept_dist[c],
            state.kept_count[c],
            slot,
        )
        state.kept_version[c] = state.counters[VERSION]


@njit(cache=True)
def insert(state, x, y, nearest):
    """Store [x | y]; returns its slot (-1: x or y not finite, nothing stored).

    ``nearest`` is the slot of the stored input closest to x (used by the 'nearest' replacement
    policy once the memory is full; -1 to find it: from the last search if that was made at x on
    the memory as it is, else by a search). Under 'redundancy' K(x) is searched and the sample
    stored by ``insert_among``."""
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        return -1
    counters = state.counters
    if state.replacement == REPLACE_REDUNDANCY:
        xq = np.empty(x.shape[0])
        canonical(x, state.in_period, xq)
        idx = np.empty(state.n_neighbours, dtype=np.int64)
        nk = _search(state, xq, state.n_neighbours, idx, state.best, idx[:0])
        return insert_among(state, x, y, idx, nk)
    one = np.empty(1, dtype=np.int64)
    if counters[COUNT] >= state.Y.shape[0] and state.replacement == REPLACE_NEAREST:
        if nearest < 0:
            xq = np.empty(x.shape[0])
            canonical(x, state.in_period, xq)
            if (
                state.last_version == counters[VERSION]
                and state.last_nearest >= 0
                and np.all(state.last_point == xq)
            ):
                nearest = state.last_nearest
            else:
                one_d = np.empty(1)
                distances(
                    state.Xt,
                    0,
                    counters[COUNT],
                    xq,
                    state.weights,
                    state.in_period,
                    state.norm,
                    state.dist,
                )
                smallest(
                    state.dist,
                    counters[COUNT],
                    np.int64(1),
                    one,
                    one_d,
                    one[:0],
                    state.seen,
                    state.lanes,
                )
                nearest = one[0]
        one[0] = nearest
        return insert_among(state, x, y, one, np.int64(1))
    # np.int64: a literal count would make numba compile insert_among once per value
    return insert_among(state, x, y, one, np.int64(0))


@njit(cache=True)
def insert_among(state, x, y, idx, nk):
    """Store [x | y] given K(x) = ``idx[:nk]``, the nearest samples to x on the memory as it is,
    nearest first (as ``neighbours`` or the first K of ``candidates`` give them); returns its slot
    (-1: x or y not finite, nothing stored).

    Once full: 'nearest' replaces idx[0], 'oldest' the oldest sample, 'redundancy' the sample of
    highest redundancy score after the neighbours' scores are updated (``score``; first of equals).
    Under 'redundancy' the scores are kept while the memory fills too."""
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        return -1
    Xt, counters = state.Xt, state.counters
    count = counters[COUNT]
    xq = np.empty(x.shape[0])
    canonical(x, state.in_period, xq)
    own = 0.0
    if state.replacement == REPLACE_REDUNDANCY:
        own = score(state, xq, y, idx, nk)
    if count < state.Y.shape[0]:
        slot = count
        counters[COUNT] = count + 1
    elif state.replacement == REPLACE_NEAREST:
        slot = idx[0]
    elif state.replacement == REPLACE_REDUNDANCY:
        rho = state.redundancy
        slot = 0
        for i in range(1, count):
            if rho[i] > rho[slot]:
                slot = i
    else:  # oldest
        slot = int(np.argmin(state.stamp))
    for j in range(Xt.shape[0]):
        Xt[j, slot] = xq[j]
    for o in range(y.shape[0]):
        state.Y[slot, o] = y[o]
    state.stamp[slot] = counters[CLOCK]
    if state.replacement == REPLACE_REDUNDANCY:
        state.redundancy[slot] = own
    counters[CLOCK] += 1
    counters[VERSION] += 1
    _carry_kept(state, counters[VERSION] - 1, count, slot)
    return slot


@njit(cache=True)
def move_outputs(state, idx, nk, target, rate):
    """y_i += rate * wrap(target - y_i) for the samples ``idx[:nk]``, then periodic outputs are
    wrapped to one period (RMAC's reference update, Algorithm 2 line 20)."""
    Y, period = state.Y, state.out_period
    for a in range(nk):
        i = idx[a]
        for j in range(Y.shape[1]):
            y = Y[i, j] + rate * wrap(target[j] - Y[i, j], period[j])
            Y[i, j] = wrap(y, period[j])


@njit(cache=True)
def add_weighted(state, weights, delta):
    """y_i += delta * weights_i for every stored sample i (a TD(lambda) update with eligibility
    traces ``weights``, Algorithm 2 line 27); weights has at least ``counters[COUNT]`` entries."""
    Y = state.Y
    for i in range(state.counters[COUNT]):
        for o in range(Y.shape[1]):
            Y[i, o] += delta[o] * weights[i]
