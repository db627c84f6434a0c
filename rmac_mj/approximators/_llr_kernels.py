"""Numba kernels of Local Linear Regression (the fast path of :mod:`rmac_mj.approximators.llr`).

Every function here mirrors one of the plain numpy reference functions in ``llr.py`` step by step
(same distance, same tie-breaking, same normal-equation fit), so the two back ends give the same
neighbours and, up to rounding, the same local models; ``tests/test_llr.py`` cross-checks them.

A memory is passed to compiled code as an :class:`LLRState`, a numba structref whose named fields are
the memory's own arrays (shared with :class:`~rmac_mj.approximators.llr.LLRMemory`, so compiled
updates change the memory) and its settings:

======================  ============================================================================
``Xt``                  (n, N) inputs, stored by dimension so that the distance loop runs over
                        contiguous memory and vectorises (5x faster than row-wise here); periodic
                        inputs are kept in [-period/2, period/2)
``Y``                   (N, m) outputs
``stamp``               (N,) int64 insertion times
``meta``                int64 [count, clock, version]: the number of stored samples, the next
                        stamp, and a counter of changes to the inputs (any insert, fit, reset or
                        load), so that a neighbour list can tell whether it is still current
``weights``             (n,) input weights of the distance and of the regression
``in_period``           (n,) period of each periodic input, 0 elsewhere
``out_period``          (m,) period of each periodic output, 0 elsewhere
``dist``                (N,) scratch space for distances
``best``                (K+1,) scratch space for the distances of a neighbour list
``seen``                (N,) scratch flags of the neighbour search, all False between searches
``lanes``               (L,) scratch space of the neighbour search (L >= 64, >= 2 (K+1))
``last_point``          (n,) where the last search was made, ``last_nearest`` the nearest sample
                        it found (-1: none) and ``last_version`` the memory's version then
``n_neighbours``        K
``norm``                1 or 2
``clip``                clip predictions to the neighbours' output range
``replacement``         ``REPLACE_OLDEST``, ``REPLACE_NEAREST`` or ``REPLACE_REDUNDANCY``
``redundancy``          (N,) redundancy score of each sample (higher: more redundant), kept only
                        under ``REPLACE_REDUNDANCY`` (see ``insert_among``)
``measure``             ``MEASURE_DISTANCE`` or ``MEASURE_MISFIT``: what the score measures
``smoothing``           eta, the exponential smoothing factor of the scores
``eig_cutoff``          relative eigenvalue cutoff of the normal matrix (see ``fit``)
``ridge``               ridge added to the slopes' diagonal
======================  ============================================================================

A learner whose own step is compiled (RMAC) calls the state-level functions at the end of this module
(``query``, ``neighbours``, ``candidates``, ``refresh``, ``fit_at``, ``insert``, ``insert_among``,
``move_outputs``,
``add_weighted``) through the names ``llr.py`` exports; a structref crosses the Python/numba
boundary much faster than a tuple of arrays.

Searching a point once where the algorithm searches it twice does not change what is found
(docs/performance.md): a neighbour list of K+1 candidates stays exact across one insertion
(``refresh``: the replaced sample leaves, the new one is placed by its distance, every other
sample keeps its distance), so a caller that searched a point before inserting need not search it
again; and ``insert`` takes the nearest sample from the last search when that was made at the
same point on the memory as it is.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.experimental import structref

# Codes shared with llr.py.
REPLACE_OLDEST = 0
REPLACE_NEAREST = 1
REPLACE_REDUNDANCY = 2
MEASURE_DISTANCE = 0
MEASURE_MISFIT = 1


@structref.register
class LLRStateType(types.StructRef):
    """The numba type of :class:`LLRState`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class LLRState(structref.StructRefProxy):
    """A memory's arrays and settings, named, for compiled code (fields: see the module docstring).

    Made by :func:`new_state`; opaque to Python (read the arrays through the owning ``LLRMemory``).
    """


structref.define_boxing(LLRStateType, LLRState)

#: The one concrete type of every LLRState (C-contiguous float64/int64 arrays).
LLR_STATE_TYPE = LLRStateType([
    ("Xt", types.float64[:, ::1]), ("Y", types.float64[:, ::1]), ("stamp", types.int64[::1]),
    ("meta", types.int64[::1]), ("weights", types.float64[::1]),
    ("in_period", types.float64[::1]), ("out_period", types.float64[::1]),
    ("dist", types.float64[::1]), ("n_neighbours", types.int64), ("norm", types.int64),
    ("clip", types.boolean), ("replacement", types.int64), ("eig_cutoff", types.float64),
    ("ridge", types.float64), ("best", types.float64[::1]), ("last_nearest", types.int64),
    ("last_point", types.float64[::1]), ("last_version", types.int64),
    ("seen", types.boolean[::1]), ("lanes", types.float64[::1]),
    ("redundancy", types.float64[::1]), ("measure", types.int64), ("smoothing", types.float64)])


@njit(cache=True)
def new_state(Xt, Y, stamp, meta, weights, in_period, out_period, dist, n_neighbours, norm, clip,
              replacement, eig_cutoff, ridge, redundancy, measure, smoothing):
    """An :class:`LLRState` over the given arrays (not copied)."""
    state = structref.new(LLR_STATE_TYPE)
    state.redundancy = redundancy
    state.measure = measure
    state.smoothing = smoothing
    state.Xt = Xt
    state.Y = Y
    state.stamp = stamp
    state.meta = meta
    state.weights = weights
    state.in_period = in_period
    state.out_period = out_period
    state.dist = dist
    state.n_neighbours = n_neighbours
    state.norm = norm
    state.clip = clip
    state.replacement = replacement
    state.eig_cutoff = eig_cutoff
    state.ridge = ridge
    state.best = np.empty(n_neighbours + 1)
    state.last_nearest = -1
    state.last_point = np.empty(Xt.shape[0])
    state.last_version = -1
    state.seen = np.zeros(Y.shape[0], dtype=np.bool_)
    n_lanes = 64
    while n_lanes < 2 * (n_neighbours + 1):
        n_lanes *= 2
    state.lanes = np.empty(n_lanes)
    return state


@njit(cache=True)
def wrap(d: float, period: float) -> float:
    """d mapped to [-period/2, period/2) when period > 0; d itself otherwise."""
    if period > 0.0:
        return d - period * np.floor(d / period + 0.5)
    return d


@njit(cache=True)
def canonical(x, period, out):
    """Periodic entries of x (shape (n,)) mapped to [-period/2, period/2); others copied."""
    for j in range(x.shape[0]):
        out[j] = wrap(x[j], period[j])


@njit(cache=True, fastmath=True)
def distances(Xt, start, count, xq, w, period, norm, d):
    """d[i] = sum_j |w_j wrap(x_ij - xq_j)| (norm 1) or sum_j (w_j wrap(x_ij - xq_j))^2 (norm 2,
    the squared 2-norm, which orders identically) for the samples start <= i < count.

    Stored and query inputs lie in [-period/2, period/2), so a difference needs at most one shift
    by a period; the branch-free loops over contiguous rows vectorise. One sample's distance is
    computed by the same code as all of them (``start = count - 1``), so it is the same number.
    """
    d[start:count] = 0.0
    for j in range(Xt.shape[0]):
        p = period[j]
        half = 0.5 * p
        wj = w[j]
        q = xq[j]
        row = Xt[j]
        if p > 0.0 and norm == 1:
            for i in range(start, count):
                e = row[i] - q
                d[i] += abs(wj * (e - p * (e >= half) + p * (e < -half)))
        elif p > 0.0:
            for i in range(start, count):
                e = row[i] - q
                e = wj * (e - p * (e >= half) + p * (e < -half))
                d[i] += e * e
        elif norm == 1:
            for i in range(start, count):
                d[i] += abs(wj * (row[i] - q))
        else:
            for i in range(start, count):
                e = wj * (row[i] - q)
                d[i] += e * e


@njit(cache=True)
def place(best, idx, found, k, di, i):
    """Insert the pair (di, i) into the ``found`` smallest pairs so far, ``best``/``idx`` ordered by
    (distance, index), keeping at most k; returns the new count."""
    if found < k:
        pos = found
        found += 1
    elif di < best[k - 1] or (di == best[k - 1] and i < idx[k - 1]):
        pos = k - 1
    else:
        return found
    while pos > 0 and (best[pos - 1] > di or (best[pos - 1] == di and idx[pos - 1] > i)):
        best[pos] = best[pos - 1]
        idx[pos] = idx[pos - 1]
        pos -= 1
    best[pos] = di
    idx[pos] = i
    return found


@njit(cache=True, fastmath=True)
def lane_minima(d, count, n_lanes, lanes):
    """lanes[l] = min of d[i] over i < count with i = l modulo n_lanes (n_lanes <= count): vertical
    minima, which vectorise (with n_lanes an argument: read from lanes.shape, LLVM did not); each
    is one of the values."""
    for lane in range(n_lanes):
        lanes[lane] = d[lane]
    stop = count - count % n_lanes
    for start in range(n_lanes, stop, n_lanes):
        for lane in range(n_lanes):
            v = d[start + lane]
            lanes[lane] = v if v < lanes[lane] else lanes[lane]
    for i in range(stop, count):
        v = d[i]
        lane = i - stop
        lanes[lane] = v if v < lanes[lane] else lanes[lane]


@njit(cache=True)
def _block_min(d, i):
    """min(d[i:i+16]) as a tree (independent comparisons)."""
    a0 = min(d[i], d[i + 1])
    a1 = min(d[i + 2], d[i + 3])
    a2 = min(d[i + 4], d[i + 5])
    a3 = min(d[i + 6], d[i + 7])
    a4 = min(d[i + 8], d[i + 9])
    a5 = min(d[i + 10], d[i + 11])
    a6 = min(d[i + 12], d[i + 13])
    a7 = min(d[i + 14], d[i + 15])
    return min(min(min(a0, a1), min(a2, a3)), min(min(a4, a5), min(a6, a7)))


@njit(cache=True)
def _scan_in_order(d, count, nk, idx_out, best, bound):
    """The nk smallest of d[:count] among the values <= bound (there must be nk), visiting values in
    index order, so that a strict comparison keeps ties in index order; blocks of 16 values that
    cannot enter are skipped."""
    found = 0
    last = bound  # what a value must not exceed to enter (then: be below, once the list is full)
    full = False
    i = 0
    while i < count:
        if i + 16 <= count:
            lo = _block_min(d, i)
            if lo > last or (full and lo >= last):
                i += 16
                continue
        stop = min(i + 16, count)
        while i < stop:
            di = d[i]
            if di > last or (full and di >= last):
                i += 1
                continue
            if found < nk:
                pos = found
                found += 1
            else:
                pos = nk - 1
            while pos > 0 and best[pos - 1] > di:
                best[pos] = best[pos - 1]
                idx_out[pos] = idx_out[pos - 1]
                pos -= 1
            best[pos] = di
            idx_out[pos] = i
            if found == nk:
                full = True
                last = best[nk - 1]
            i += 1


@njit(cache=True)
def _scan_from_seeds(d, count, nk, idx_out, best, seen):
    """Complete a full list of nk seeds (placed, marked in ``seen``) to the nk smallest of d[:count]:
    each value not seen is placed if it ranks before the list's last by (value, index)."""
    i = 0
    while i < count:
        if i + 16 <= count:
            if _block_min(d, i) > best[nk - 1]:
                i += 16
                continue
        stop = min(i + 16, count)
        while i < stop:
            di = d[i]
            if (di < best[nk - 1] or (di == best[nk - 1] and i < idx_out[nk - 1])) and not seen[i]:
                place(best, idx_out, nk, nk, di, i)
            i += 1


@njit(cache=True)
def kth_smallest(values, n, k):
    """The k-th smallest of values[:n] (k <= n), by keeping the k smallest in order."""
    top = np.empty(k)
    found = 0
    for i in range(n):
        v = values[i]
        if found < k:
            pos = found
            found += 1
        elif v < top[k - 1]:
            pos = k - 1
        else:
            continue
        while pos > 0 and top[pos - 1] > v:
            top[pos] = top[pos - 1]
            pos -= 1
        top[pos] = v
    return top[k - 1]


@njit(cache=True)
def smallest(d, count, k, idx_out, best, seed, n_seed, seen, lanes):
    """The min(k, count) smallest of d[:count], ordered by (value, index): ties go to the lower
    index, as in a stable sort. Indices go to ``idx_out``, values to ``best``; returns how many.

    A bound on the k-th smallest value first, then one pass that skips every block of 16 values
    above it (cheap) and places the rest. The bound comes from ``seed[:n_seed]``, distinct indices
    of values expected to be small (the neighbours of a nearby point searched before): they fill
    the list, and each other value is placed if it ranks before the list's last; ``seen`` (count,)
    marks the seeds (all False before and after). Without enough seeds, from the minima of L
    interleaved lanes (L = len(lanes), at least 2k): L distinct values, so the k-th smallest of them
    is at least the k-th smallest overall (a few dozen of 2000 values lie below it). Small arrays
    are scanned without a bound. The result never depends on the seeds.
    """
    nk = min(k, count)
    if nk <= 0:
        return 0
    found = 0
    for h in range(n_seed):
        i = seed[h]
        if 0 <= i < count and not seen[i]:
            seen[i] = True
            found = place(best, idx_out, found, nk, d[i], i)
    if found == nk:
        _scan_from_seeds(d, count, nk, idx_out, best, seen)
    for h in range(n_seed):
        i = seed[h]
        if 0 <= i < count:
            seen[i] = False
    if found == nk:
        return nk
    bound = np.inf
    n_lanes = lanes.shape[0]
    if count >= 4 * n_lanes and n_lanes >= nk:
        lane_minima(d, count, n_lanes, lanes)
        bound = kth_smallest(lanes, n_lanes, nk)
    _scan_in_order(d, count, nk, idx_out, best, bound)
    return nk


@njit(cache=True)
def jacobi_eigh(G, evals, evecs):
    """Eigen-decomposition G = evecs diag(evals) evecs^T of a small symmetric matrix (p, p) by cyclic
    Jacobi rotations (evals unsorted; G is overwritten). For p <= 4 this is twice as fast as
    LAPACK through numpy.linalg.eigh, and accurate for the small eigenvalues the cutoff tests."""
    p = G.shape[0]
    for a in range(p):
        for b in range(p):
            evecs[a, b] = 1.0 if a == b else 0.0
    for sweep in range(50):
        off = 0.0
        scale = 0.0
        for a in range(p):
            scale += G[a, a] * G[a, a]
            for b in range(a + 1, p):
                off += G[a, b] * G[a, b]
        if off <= 1e-30 * scale:
            break
        for a in range(p - 1):
            for b in range(a + 1, p):
                gab = G[a, b]
                if gab == 0.0:
                    continue
                theta = (G[b, b] - G[a, a]) / (2.0 * gab)
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(p):
                    gka = G[k, a]
                    gkb = G[k, b]
                    G[k, a] = c * gka - s * gkb
                    G[k, b] = s * gka + c * gkb
                for k in range(p):
                    gak = G[a, k]
                    gbk = G[b, k]
                    G[a, k] = c * gak - s * gbk
                    G[b, k] = s * gak + c * gbk
                for k in range(p):
                    vka = evecs[k, a]
                    vkb = evecs[k, b]
                    evecs[k, a] = c * vka - s * vkb
                    evecs[k, b] = s * vka + c * vkb
    for a in range(p):
        evals[a] = G[a, a]

@njit(cache=True)
def fit(Xt, Y, idx, nk, xq, w, in_period, out_period, eig_cutoff, ridge, clip, beta_out, pred_out):
    """Affine least-squares fit to the neighbours ``idx[:nk]``, centred on and valid around ``xq``.

    The regressors are the weighted, wrapped offsets z_i = w * wrap(x_i - xq) plus a 1. The normal
    matrix G = A^T A (+ ridge on the slopes) is inverted through its eigen-decomposition, dropping
    eigenvalues below ``eig_cutoff * max`` (a truncated SVD of A with relative cutoff
    sqrt(eig_cutoff)); this gives the minimum-norm solution when the fit is under-determined.
    Periodic outputs are unwrapped around the nearest neighbour's output. Writes beta (m, n+1) in raw
    input units, with beta @ [xq; 1] == prediction, and the prediction (m,), clipped to the
    neighbours' output range when ``clip``.
    """
    n = Xt.shape[0]
    m = Y.shape[1]
    p = n + 1
    if nk == 0:
        beta_out[:, :] = 0.0
        pred_out[:] = 0.0
        return
    A = np.empty((nk, p))
    Yn = np.empty((nk, m))
    for a in range(nk):
        i = idx[a]
        for j in range(n):
            A[a, j] = w[j] * wrap(Xt[j, i] - xq[j], in_period[j])
        A[a, n] = 1.0
        for o in range(m):
            if out_period[o] > 0.0 and a > 0:
                Yn[a, o] = Yn[0, o] + wrap(Y[i, o] - Y[idx[0], o], out_period[o])
            else:
                Yn[a, o] = Y[i, o]
    G = A.T @ A
    for j in range(n):
        G[j, j] += ridge
    evals = np.empty(p)
    evecs = np.empty((p, p))
    jacobi_eigh(G, evals, evecs)
    top = evals.max()
    Ginv = np.zeros((p, p))
    for c in range(p):
        if evals[c] > eig_cutoff * top and evals[c] > 0.0:
            for a in range(p):
                for b in range(p):
                    Ginv[a, b] += evecs[a, c] * evecs[b, c] / evals[c]
    g = Ginv @ (A.T @ Yn)  # (p, m)
    for o in range(m):
        pred = g[n, o]
        if clip:
            lo = Yn[0, o]
            hi = Yn[0, o]
            for a in range(1, nk):
                lo = min(lo, Yn[a, o])
                hi = max(hi, Yn[a, o])
            pred = min(max(pred, lo), hi)
        offset = pred
        for j in range(n):
            beta_out[o, j] = g[j, o] * w[j]
            offset -= beta_out[o, j] * xq[j]
        beta_out[o, n] = offset
        pred_out[o] = pred


# -- state-level operations ---------------------------------------------------------------------

@njit(cache=True)
def _search(state, xq, k, idx_out, best, seed, n_seed):
    """The min(k, count) nearest samples to a canonical xq, by (distance, index), with their
    distances; remembers where it searched and the nearest sample (see ``insert``)."""
    count = state.meta[0]
    distances(state.Xt, 0, count, xq, state.weights, state.in_period, state.norm, state.dist)
    nk = smallest(state.dist, count, k, idx_out, best, seed, n_seed, state.seen, state.lanes)
    state.last_nearest = idx_out[0] if nk > 0 else -1
    state.last_point[:] = xq
    state.last_version = state.meta[2]
    return nk


@njit(cache=True)
def fit_at(state, xq, idx, nk, beta_out, pred_out):
    """The local model at a canonical xq from the neighbours ``idx[:nk]`` (see ``fit``)."""
    fit(state.Xt, state.Y, idx, nk, xq, state.weights, state.in_period, state.out_period,
        state.eig_cutoff, state.ridge, state.clip, beta_out, pred_out)


@njit(cache=True)
def query(state, x, idx_out, beta_out, pred_out):
    """Neighbour search and fit at ``x`` (shape (n,)); writes the neighbours (nearest first) to
    ``idx_out`` (K,), the local model to ``beta_out`` (m, n+1) and the prediction to ``pred_out``
    (m,); returns the number of neighbours found (-1: x not finite)."""
    if not np.all(np.isfinite(x)):
        return -1
    xq = np.empty(x.shape[0])
    canonical(x, state.in_period, xq)
    nk = _search(state, xq, state.n_neighbours, idx_out, state.best, idx_out, 0)
    fit_at(state, xq, idx_out, nk, beta_out, pred_out)
    return nk


@njit(cache=True)
def neighbours(state, xq, idx_out):
    """K(xq) for a canonical xq (periodic entries in [-period/2, period/2)): the nearest samples,
    nearest first, written to ``idx_out`` (K,); returns how many."""
    return _search(state, xq, state.n_neighbours, idx_out, state.best, idx_out, 0)


@njit(cache=True)
def candidates(state, xq, idx_out, dist_out, seed, n_seed):
    """The min(K+1, count) nearest samples to a canonical xq, nearest first, with their distances
    (``idx_out``, ``dist_out``: shape (K+1,)); returns how many. The first min(K, count) are K(xq),
    and the list can be carried across one insertion with ``refresh``. ``seed[:n_seed]``: distinct
    samples likely near xq (e.g. such a list of a point close by), to search faster; n_seed = 0
    for none. The result does not depend on them."""
    return _search(state, xq, state.n_neighbours + 1, idx_out, dist_out, seed, n_seed)


@njit(cache=True)
def refresh(state, xq, idx, dist, n, slot):
    """Carry the neighbour list ``idx[:n]`` of a canonical xq (from ``candidates``, or from an
    earlier ``refresh``), with distances ``dist[:n]``, across one insertion into ``slot``; returns
    how many of its entries are now exact (at least min(K, count)).

    Every other sample kept its distance and every sample outside the list lies beyond all of it.
    So the replaced sample leaves the list and the new one is placed by its distance; the list is
    then exact except, when the replaced sample was in it, for a new sample that ranks last (a
    sample outside the list may lie before it), which is dropped.
    """
    capacity = idx.shape[0]
    distances(state.Xt, slot, slot + 1, xq, state.weights, state.in_period, state.norm,
              state.dist)
    kept = 0
    for a in range(n):
        if idx[a] != slot:
            idx[kept] = idx[a]
            dist[kept] = dist[a]
            kept += 1
    removed = kept < n
    outsiders = state.meta[0] > n  # samples that were not in the list
    n = place(dist, idx, kept, capacity, state.dist[slot], slot)
    if removed and outsiders and n == kept + 1 and idx[kept] == slot:
        n = kept
    return n


@njit(cache=True)
def insert(state, x, y, nearest):
    """Store [x | y]; returns its slot (-1: x or y not finite, nothing stored).

    ``nearest`` is the slot of the stored input closest to x (used by the 'nearest' replacement
    policy once the memory is full; -1 to find it: from the last search if that was made at x on
    the memory as it is, else by a search). Under 'redundancy' K(x) is searched and the sample
    stored by ``insert_among``."""
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        return -1
    meta = state.meta
    if state.replacement == REPLACE_REDUNDANCY:
        xq = np.empty(x.shape[0])
        canonical(x, state.in_period, xq)
        idx = np.empty(state.n_neighbours, dtype=np.int64)
        nk = _search(state, xq, state.n_neighbours, idx, state.best, idx, 0)
        return insert_among(state, x, y, idx, nk)
    one = np.empty(1, dtype=np.int64)
    if meta[0] >= state.Y.shape[0] and state.replacement == REPLACE_NEAREST:
        if nearest < 0:
            xq = np.empty(x.shape[0])
            canonical(x, state.in_period, xq)
            if (state.last_version == meta[2] and state.last_nearest >= 0
                    and np.all(state.last_point == xq)):
                nearest = state.last_nearest
            else:
                one_d = np.empty(1)
                distances(state.Xt, 0, meta[0], xq, state.weights, state.in_period, state.norm,
                          state.dist)
                smallest(state.dist, meta[0], 1, one, one_d, one, 0, state.seen, state.lanes)
                nearest = one[0]
        one[0] = nearest
        return insert_among(state, x, y, one, 1)
    return insert_among(state, x, y, one, 0)


@njit(cache=True)
def distance_to(state, i, xq):
    """The weighted distance of sample i to a canonical xq: the 1-norm, or the 2-norm (not its
    square, which the search uses), of w * wrap(x_i - xq)."""
    d = 0.0
    for j in range(xq.shape[0]):
        e = state.weights[j] * wrap(state.Xt[j, i] - xq[j], state.in_period[j])
        d += abs(e) if state.norm == 1 else e * e
    return d if state.norm == 1 else np.sqrt(d)


@njit(cache=True)
def misfits(state, xq, y, idx, nk, out):
    """Squared misfits of the new sample [xq | y] (xq canonical) and of its neighbours
    ``idx[:nk]`` under one local model: the affine fit (``fit``, unclipped) to these nk + 1
    samples at xq. out[0] is the new sample's, out[1 + a] that of idx[a]; each is
    sum_o wrap(y_o - y_hat_o)^2 with y_hat = pred + beta_x wrap(x - xq)."""
    n = xq.shape[0]
    m = y.shape[0]
    Xt2 = np.empty((n, nk + 1))
    Y2 = np.empty((nk + 1, m))
    for j in range(n):
        Xt2[j, 0] = xq[j]
    Y2[0, :] = y
    for a in range(nk):
        i = idx[a]
        for j in range(n):
            Xt2[j, a + 1] = state.Xt[j, i]
        Y2[a + 1, :] = state.Y[i, :]
    rows = np.arange(nk + 1)
    beta = np.empty((m, n + 1))
    pred = np.empty(m)
    fit(Xt2, Y2, rows, nk + 1, xq, state.weights, state.in_period, state.out_period,
        state.eig_cutoff, state.ridge, False, beta, pred)
    for a in range(nk + 1):
        e2 = 0.0
        for o in range(m):
            y_hat = pred[o]
            for j in range(n):
                y_hat += beta[o, j] * wrap(Xt2[j, a] - xq[j], state.in_period[j])
            r = wrap(Y2[a, o] - y_hat, state.out_period[o])
            e2 += r * r
        out[a] = e2


@njit(cache=True)
def score(state, xq, y, idx, nk):
    """Update the redundancy scores of the neighbours ``idx[:nk]`` of a new sample [xq | y] (xq
    canonical) and return the new sample's own score (``LLRMemory`` documents the equations):
    rho_i <- (1 - eta) rho_i + eta c_i with c_i = -d(x_i, xq) ('distance') or -e_i^2
    ('misfit'); the new sample's is rho_* = (1 - eta) mean_i rho_i + eta c_*, the mean over the
    updated neighbours, with c_* = -min_i d(x_i, xq), resp. -e_*^2 (0 with no neighbours)."""
    rho = state.redundancy
    eta = state.smoothing
    if nk <= 0:
        return 0.0
    own = 0.0
    if state.measure == MEASURE_DISTANCE:
        for a in range(nk):
            i = idx[a]
            d = distance_to(state, i, xq)
            if a == 0:
                own = -d
            rho[i] = (1.0 - eta) * rho[i] - eta * d
    else:
        e2 = np.empty(nk + 1)
        misfits(state, xq, y, idx, nk, e2)
        for a in range(nk):
            i = idx[a]
            rho[i] = (1.0 - eta) * rho[i] - eta * e2[a + 1]
        own = -e2[0]
    mean = 0.0
    for a in range(nk):
        mean += rho[idx[a]]
    return (1.0 - eta) * (mean / nk) + eta * own


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
    Xt, meta = state.Xt, state.meta
    count = meta[0]
    xq = np.empty(x.shape[0])
    canonical(x, state.in_period, xq)
    own = 0.0
    if state.replacement == REPLACE_REDUNDANCY:
        own = score(state, xq, y, idx, nk)
    if count < state.Y.shape[0]:
        slot = count
        meta[0] = count + 1
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
    state.Y[slot, :] = y
    state.stamp[slot] = meta[1]
    if state.replacement == REPLACE_REDUNDANCY:
        state.redundancy[slot] = own
    meta[1] += 1
    meta[2] += 1
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
    traces ``weights``, Algorithm 2 line 27); weights has at least ``meta[0]`` entries."""
    Y = state.Y
    for i in range(state.meta[0]):
        for o in range(Y.shape[1]):
            Y[i, o] += delta[o] * weights[i]
