"""The local fits of an LLR memory cached at its samples, for many fast queries (a planner's model).

:class:`LocalFits` keeps, for every sample i of an :class:`~rmac_mj.approximators.llr.LLRMemory`,
its K nearest samples (itself first, as the memory orders them) and the LLR fit there: the local
affine model y_i + B_i (x - x_i) that a query at x_i would fit (section 4). A query z is answered
by the model of its nearest sample i, evaluated at z (periodic offsets wrapped), and comes with an
uncertainty, d(z, x_i) / r_i, where r_i is the distance from x_i to its K-th nearest sample: below
1 where z lies inside the data's neighbourhoods, above 1 where the model extrapolates.

The nearest sample is found exactly by a k-d tree over the memory's weighted inputs
(:func:`nearest_tree`, periodic dimensions included; a scan, :func:`nearest_scan`, is the
reference). The cache follows the memory's insertions (its stamps tell what changed), refits only
the samples whose neighbours changed, and rebuilds the tree when anything did.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rmac_mj.approximators._llr_fit import fit
from rmac_mj.approximators._llr_search import distances, place, wrap
from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.approximators.llr_numpy import distance_numpy, fit_numpy, search_numpy
from rmac_mj.approximators.llr_numpy import wrap as wrap_array


@njit(cache=True)
def _neighbours_of(state, i, count, k, scratch, idx_out, dist_out):
    """The min(k, count) nearest samples of sample i (itself included), by (distance, index)."""
    n = state.Xt.shape[0]
    x = np.empty(n)
    for j in range(n):
        x[j] = state.Xt[j, i]
    distances(state.Xt, 0, count, x, state.weights, state.in_period, state.norm, scratch)
    found = 0
    for s in range(count):
        if found < k or scratch[s] < dist_out[k - 1]:  # (ties cannot enter: s grows)
            found = place(dist_out, idx_out, found, k, scratch[s], s)
    for a in range(found, k):
        idx_out[a] = -1
        dist_out[a] = np.inf
    return found


@njit(cache=True)
def _refit(state, i, nbr, origin, slope, low, high):
    """The LLR fit at sample i from its neighbours ``nbr[i]``: its value there (``origin[i]``), its
    slopes (``slope[i]``) and its neighbours' output range (``low[i]``, ``high[i]``)."""
    n = state.Xt.shape[0]
    m = state.Y.shape[1]
    nk = 0
    while nk < nbr.shape[1] and nbr[i, nk] >= 0:
        nk += 1
    x = np.empty(n)
    for j in range(n):
        x[j] = state.Xt[j, i]
    beta = np.empty((m, n + 1))
    pred = np.empty(m)
    fit(
        state.Xt,
        state.Y,
        nbr[i],
        nk,
        x,
        state,
        False,  # the range is applied where the model is evaluated (``predict_at``)
        beta,
        pred,
    )
    for o in range(m):
        origin[i, o] = pred[o]
        lo = hi = state.Y[nbr[i, 0], o]
        for a in range(1, nk):
            y = state.Y[nbr[i, 0], o] + wrap(
                state.Y[nbr[i, a], o] - state.Y[nbr[i, 0], o], state.out_period[o]
            )
            lo = min(lo, y)
            hi = max(hi, y)
        low[i, o] = lo
        high[i, o] = hi
        for j in range(n):
            slope[i, o, j] = beta[o, j]


@njit(cache=True)
def refresh(state, stamp, nbr, nbr_d, origin, slope, low, high, fresh, only_inserts):
    """Bring the cache up to date with the memory: the samples whose stamp changed (inserted or
    replaced) get their neighbour lists, every list that held a replaced sample is searched again,
    every other list takes a new sample it should hold, and every changed list is refitted.
    ``only_inserts``: nothing but insertions changed the memory since the last call (else every
    list is searched again). Returns the number of fits made."""
    count = state.counters[0]
    N, k = nbr.shape
    scratch = np.empty(N)
    changed = np.zeros(N, dtype=np.bool_)
    n_changed = 0
    for i in range(count):
        if stamp[i] != state.stamp[i]:
            changed[i] = True
            n_changed += 1
    for i in range(count, N):
        stamp[i] = -1
    if n_changed == 0 and only_inserts:
        return 0
    research = np.zeros(N, dtype=np.bool_)
    if 4 * n_changed > count or not only_inserts:  # a load, a fit, much changed: every list again
        research[:count] = True
    else:
        for i in range(count):
            if changed[i]:
                continue
            for a in range(k):
                if nbr[i, a] >= 0 and changed[nbr[i, a]]:
                    research[i] = True
                    break
        n = state.Xt.shape[0]
        x = np.empty(n)
        for c in range(count):
            if not changed[c]:
                continue
            for j in range(n):
                x[j] = state.Xt[j, c]
            distances(state.Xt, 0, count, x, state.weights, state.in_period, state.norm, scratch)
            for i in range(count):
                if changed[i] or research[i]:
                    continue
                if nbr[i, k - 1] >= 0 and (
                    scratch[i] > nbr_d[i, k - 1]
                    or (scratch[i] == nbr_d[i, k - 1] and c > nbr[i, k - 1])
                ):
                    continue  # a full list that c does not enter
                found = 0
                while found < k and nbr[i, found] >= 0:
                    found += 1
                found = place(nbr_d[i], nbr[i], found, k, scratch[i], c)
                for a in range(found):
                    if nbr[i, a] == c:  # c entered the list
                        fresh[i] = False
                        break
    fits = 0
    for i in range(count):
        if changed[i] or research[i]:
            _neighbours_of(state, i, count, k, scratch, nbr[i], nbr_d[i])
            fresh[i] = False
            stamp[i] = state.stamp[i]
        if not fresh[i]:
            _refit(state, i, nbr, origin, slope, low, high)
            fresh[i] = True
            fits += 1
    return fits


@njit(cache=True)
def _distance(state, i, z):
    """The memory's distance from z to sample i (for the 2-norm the distance, not its square)."""
    d = 0.0
    for j in range(z.shape[0]):
        e = state.weights[j] * wrap(state.Xt[j, i] - z[j], state.in_period[j])
        d += abs(e) if state.norm == 1 else e * e
    return d if state.norm == 1 else np.sqrt(d)


@njit(cache=True)
def nearest_scan(state, z):
    """(the nearest sample to z, its distance): one scan of the memory; (-1, inf) when empty."""
    count = state.counters[0]
    best, best_d = -1, np.inf
    for i in range(count):
        d = _distance(state, i, z)
        if d < best_d:
            best, best_d = i, d
    return best, best_d


@njit(cache=True)
def predict_at(state, nbr_d, origin, slope, low, high, i, distance, z, out):
    """The model of sample i evaluated at z into ``out`` (m,); returns the uncertainty
    d(z, x_i) / r_i (r_i: the distance to i's K-th neighbour; inf when it has no other)."""
    m = out.shape[0]
    n = z.shape[0]
    for o in range(m):
        v = origin[i, o]
        for j in range(n):
            v += slope[i, o, j] * wrap(z[j] - state.Xt[j, i], state.in_period[j])
        if state.clip:
            v = min(max(v, low[i, o]), high[i, o])
        out[o] = v
    k = nbr_d.shape[1]
    radius = np.inf
    for a in range(k - 1, 0, -1):
        if nbr_d[i, a] < np.inf:
            radius = nbr_d[i, a] if state.norm == 1 else np.sqrt(nbr_d[i, a])
            break
    if radius == np.inf or radius <= 0.0:
        return 0.0 if distance == 0.0 else np.inf
    return distance / radius


# --------------------------------------------------------------------------------------------------
# A k-d tree over the memory's weighted inputs: the exact nearest sample in O(log N).

#: Samples per leaf of the tree.
LEAF = 8


@njit(cache=True)
def _gap(q, lo, hi, period):
    """The distance along one (weighted) dimension from q to the interval [lo, hi], periodic with
    ``period`` (0: not)."""
    g = max(0.0, lo - q, q - hi)
    if period > 0.0 and g > 0.0:
        g = min(g, max(0.0, lo - (q + period), (q + period) - hi))
        g = min(g, max(0.0, lo - (q - period), (q - period) - hi))
    return g


@njit(cache=True)
def build_tree(state, perm, node_range, node_split, node_lo, node_hi):
    """A k-d tree over the memory's first ``count`` inputs, weighted (w_j x_j): ``perm`` (N,) the
    samples in tree order, per node ``node_range`` (start, end) of ``perm``, ``node_split`` (dim,
    left child; -1: a leaf) and its bounding box ``node_lo``/``node_hi`` (n,). Splits the widest
    dimension at its median. Returns the number of nodes."""
    count = state.counters[0]
    n = state.Xt.shape[0]
    w = state.weights
    for i in range(count):
        perm[i] = i
    nodes = 1
    node_range[0, 0] = 0
    node_range[0, 1] = count
    stack = np.empty(64, dtype=np.int64)
    stack[0] = 0
    top = 1
    values = np.empty(count)
    while top > 0:
        top -= 1
        k = stack[top]
        start, end = node_range[k, 0], node_range[k, 1]
        for j in range(n):
            lo, hi = np.inf, -np.inf
            for a in range(start, end):
                v = w[j] * state.Xt[j, perm[a]]
                lo = min(lo, v)
                hi = max(hi, v)
            node_lo[k, j] = lo
            node_hi[k, j] = hi
        if end - start <= LEAF:
            node_split[k, 0] = -1
            continue
        dim = 0
        for j in range(1, n):
            if node_hi[k, j] - node_lo[k, j] > node_hi[k, dim] - node_lo[k, dim]:
                dim = j
        # Median split by an in-place quickselect on perm[start:end] by coordinate dim.
        for a in range(start, end):
            values[a] = state.Xt[dim, perm[a]]
        mid = (start + end) // 2
        left, right = start, end - 1
        while left < right:
            pivot = values[(left + right) // 2]
            a, b = left, right
            while a <= b:
                while values[a] < pivot:
                    a += 1
                while values[b] > pivot:
                    b -= 1
                if a <= b:
                    values[a], values[b] = values[b], values[a]
                    perm[a], perm[b] = perm[b], perm[a]
                    a += 1
                    b -= 1
            if mid <= b:
                right = b
            elif mid >= a:
                left = a
            else:
                break
        node_split[k, 0] = dim
        node_split[k, 1] = nodes
        node_range[nodes, 0], node_range[nodes, 1] = start, mid
        node_range[nodes + 1, 0], node_range[nodes + 1, 1] = mid, end
        stack[top] = nodes
        stack[top + 1] = nodes + 1
        top += 2
        nodes += 2
    return nodes


@njit(cache=True)
def nearest_tree(state, perm, node_range, node_split, node_lo, node_hi, z):
    """(the nearest sample to z, its distance), exactly, by (distance, index) as
    :func:`nearest_scan`; (-1, inf) on an empty memory."""
    n = z.shape[0]
    w = state.weights
    q = np.empty(n)
    wp = np.empty(n)
    for j in range(n):
        q[j] = w[j] * z[j]
        wp[j] = w[j] * state.in_period[j]
    best, best_d = -1, np.inf
    if state.counters[0] == 0:
        return best, best_d
    stack = np.empty(128, dtype=np.int64)
    bounds = np.empty(128)
    stack[0] = 0
    bounds[0] = 0.0
    top = 1
    two = state.norm != 1
    while top > 0:
        top -= 1
        k = stack[top]
        if bounds[top] > best_d:
            continue
        if node_split[k, 0] < 0:
            for a in range(node_range[k, 0], node_range[k, 1]):
                i = perm[a]
                d = _distance(state, i, z)
                if d < best_d or (d == best_d and i < best):
                    best, best_d = i, d
            continue
        c = node_split[k, 1]
        b0 = 0.0
        b1 = 0.0
        for j in range(n):
            g0 = _gap(q[j], node_lo[c, j], node_hi[c, j], wp[j])
            g1 = _gap(q[j], node_lo[c + 1, j], node_hi[c + 1, j], wp[j])
            b0 += g0 * g0 if two else g0
            b1 += g1 * g1 if two else g1
        if two:
            b0, b1 = np.sqrt(b0), np.sqrt(b1)
        # Push the farther child first, so that the nearer is searched first.
        if b0 <= b1:
            stack[top], bounds[top] = c + 1, b1
            stack[top + 1], bounds[top + 1] = c, b0
        else:
            stack[top], bounds[top] = c, b0
            stack[top + 1], bounds[top + 1] = c + 1, b1
        top += 2
    return best, best_d


class LocalFits:
    """The fits of ``memory`` cached at its samples (see the module docstring).

    Args:
      memory: the LLR memory whose queries this answers; it is read, never changed.
      backend: 'numba' (the cache and the graph walk) or 'numpy' (the readable reference: an exact
        scan, the memory's own neighbour search and fit at the nearest sample, nothing cached).

    Arrays for compiled callers (``kernel_arrays``): ``nbr`` (N, K) each sample's neighbours (-1:
    none), ``nbr_d`` (N, K) their distances in the memory's search units, ``origin`` (N, m) the fit's
    value at the sample, ``slope`` (N, m, n), ``low``/``high`` (N, m) the neighbours' output range;
    ``tree``: the k-d tree's arrays (``perm``, ``node_range``, ``node_split``, ``node_lo``,
    ``node_hi``, see :func:`build_tree`).
    """

    def __init__(self, memory: LLRMemory, backend: str = "numba") -> None:
        if backend not in ("numba", "numpy"):
            raise ValueError(f"LocalFits: backend must be 'numba' or 'numpy', got {backend!r}")
        self.memory = memory
        self.backend = backend
        N, k = memory.capacity, memory.n_neighbours
        n, m = memory.input_dim, memory.output_dim
        self.stamp = np.full(N, -1, dtype=np.int64)
        self.nbr = np.full((N, k), -1, dtype=np.int64)
        self.nbr_d = np.full((N, k), np.inf)
        self.origin = np.zeros((N, m))
        self.slope = np.zeros((N, m, n))
        self.low = np.zeros((N, m))
        self.high = np.zeros((N, m))
        self.fresh = np.zeros(N, dtype=np.bool_)
        nodes = 2 * N + 1
        self.tree = (
            np.zeros(N, dtype=np.int64),
            np.zeros((nodes, 2), dtype=np.int64),
            np.full((nodes, 2), -1, dtype=np.int64),
            np.zeros((nodes, n)),
            np.zeros((nodes, n)),
        )
        self._tree_version: tuple[int, int, int] | None = None
        self._seen = (-1, -1)  # the memory's (version, clock) at the last refresh

    @staticmethod
    def memory_estimate(input_dim: int, output_dim: int, capacity: int, n_neighbours: int) -> int:
        """Bytes of the cache of a memory of these sizes."""
        per_sample = 8 * (1 + 2 * n_neighbours + output_dim * (input_dim + 3)) + 1
        per_node = 8 * (4 + 2 * input_dim)
        return int(capacity) * (per_sample + 2 * per_node + 8)

    def refresh(self) -> int:
        """Follow the memory's changes since the last call; returns the fits made."""
        if self.backend == "numpy":
            return 0
        state = self.memory.kernel_state
        counters = self.memory._counters
        version = (id(state), int(counters[2]), self.memory.n_samples_)
        if version != self._tree_version:
            build_tree(state, *self.tree)
            self._tree_version = version
        # An insertion moves the version and the clock by one each; a load, fit or reset does not.
        seen, self._seen = self._seen, (int(counters[2]), int(counters[1]))
        only_inserts = self._seen[0] - seen[0] == self._seen[1] - seen[1] >= 0
        return int(
            refresh(
                self.memory.kernel_state,
                self.stamp,
                self.nbr,
                self.nbr_d,
                self.origin,
                self.slope,
                self.low,
                self.high,
                self.fresh,
                only_inserts,
            )
        )

    @property
    def kernel_arrays(self) -> tuple[np.ndarray, ...]:
        """(nbr, nbr_d, origin, slope, low, high), after :meth:`refresh`."""
        return self.nbr, self.nbr_d, self.origin, self.slope, self.low, self.high

    def query(self, z: np.ndarray) -> tuple[np.ndarray, float, int]:
        """(the prediction (m,), its uncertainty, the nearest sample) at z (shape (n,)), by an
        exact scan; raises ValueError on an empty memory."""
        memory = self.memory
        z = np.asarray(z, dtype=float).reshape(-1)
        if z.shape != (memory.input_dim,) or not np.all(np.isfinite(z)):
            raise ValueError(f"LocalFits.query: z must be finite of shape ({memory.input_dim},)")
        if memory.n_samples_ == 0:
            raise ValueError("LocalFits.query: the memory is empty")
        zc = wrap_array(z, memory._pin)
        if self.backend == "numba":
            self.refresh()
            state = memory.kernel_state
            i, distance = nearest_tree(state, *self.tree, zc)
            out = np.empty(memory.output_dim)
            kappa = predict_at(
                state,
                self.nbr_d,
                self.origin,
                self.slope,
                self.low,
                self.high,
                i,
                distance,
                zc,
                out,
            )
            return out, float(kappa), int(i)
        return self._query_numpy(zc)

    def _query_numpy(self, z: np.ndarray) -> tuple[np.ndarray, float, int]:
        """The reference: the exact nearest sample, its LLR fit (the memory's own search and fit),
        evaluated at z."""
        memory = self.memory
        count = memory.n_samples_
        X, Y = memory.X_[:count], memory.Y_[:count]
        w, pin, pout = memory._w, memory._pin, memory._pout
        d = distance_numpy(X, z, w, pin, memory.norm)
        i = int(np.argmin(d))
        idx = search_numpy(X, X[i], w, pin, memory.norm, memory.n_neighbours)
        pred, beta = fit_numpy(X[idx], Y[idx], X[i], memory._fit_settings, False)
        out = pred + beta[:, :-1] @ wrap_array(z - X[i], pin)
        if memory.clip:
            Yn = Y[idx].copy()
            Yn[1:] = Y[idx[0]] + wrap_array(Y[idx[1:]] - Y[idx[0]], pout)
            out = np.clip(out, Yn.min(axis=0), Yn.max(axis=0))
        radius = distance_numpy(X[idx[-1:]], X[i], w, pin, memory.norm)[0] if len(idx) > 1 else 0.0
        kappa = d[i] / radius if radius > 0 else (0.0 if d[i] == 0 else np.inf)
        return out, float(kappa), i
