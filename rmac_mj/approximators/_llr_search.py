"""Numba kernels of LLR's geometry: periodic wrapping, weighted distances, the K nearest.

The fast path of ``search_numpy`` (:mod:`rmac_mj.approximators.llr_numpy`), step by step. Inputs are
stored by dimension (``Xt``, (n, N)); the K-th distance is bounded first and every block of 16
distances above it skipped.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rmac_mj._cache import say_when_compiling

say_when_compiling()  # the first compilation in a process says so (the LLR memories' kernels)


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
    i = np.int64(0)  # not a literal 0: numba would compile _block_min and place for it too
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
    i = np.int64(0)  # not a literal 0: numba would compile _block_min and place for it too
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
def smallest(d, count, k, idx_out, best, seed, seen, lanes):
    """The min(k, count) smallest of d[:count], ordered by (value, index): ties go to the lower
    index, as in a stable sort. Indices go to ``idx_out``, values to ``best``; returns how many.

    A bound on the k-th smallest value first, then one pass that skips every block of 16 values
    above it (cheap) and places the rest. The bound comes from ``seed`` (int64, possibly empty),
    distinct indices of values expected to be small (the neighbours of a nearby point searched
    before): they fill the list, and each other value is placed if it ranks before the list's last;
    ``seen`` (count,) marks the seeds (all False before and after). Without enough seeds, from the minima of L
    interleaved lanes (L = len(lanes), at least 2k): L distinct values, so the k-th smallest of them
    is at least the k-th smallest overall (a few dozen of 2000 values lie below it). Small arrays
    are scanned without a bound. The result never depends on the seeds.
    """
    nk = min(k, count)
    if nk <= 0:
        return 0
    found = np.int64(0)  # (see _scan_from_seeds)
    n_seed = seed.shape[0]
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
