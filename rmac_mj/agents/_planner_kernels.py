"""Numba kernels of the sampling planner (:mod:`rmac_mj.agents.sampling_planner`): a population of
action sequences scored in the learned model in one call, and the update of the sampling
distribution. Each follows the numpy reference there, step by step."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rmac_mj.approximators.local_fits import nearest_scan, nearest_tree, predict_at
from rmac_mj.approximators.tile_coding import _active_tiles_numba

#: ``method`` codes.
MPPI, CEM = 0, 1


@njit(cache=True)
def tile_sum(weights, x, coder, tiles):
    """sum of ``weights`` (F,) or (F, m) rows over the active tiles of x: V(x) or pi(x) unclipped
    (``coder``: low, high, periodic, scale, offsets, sizes, strides, tiling_size)."""
    low, high, periodic, scale, offsets, sizes, strides, tiling_size = coder
    _active_tiles_numba(x, low, high, periodic, scale, offsets, sizes, strides, tiling_size, tiles)
    s = 0.0
    for t in tiles:
        s += weights[t]
    return s


@njit(cache=True)
def _policy(actor, x, coder, tiles, a_low, a_high, out):
    """pi(x) saturated, into ``out`` (m,)."""
    low, high, periodic, scale, offsets, sizes, strides, tiling_size = coder
    _active_tiles_numba(x, low, high, periodic, scale, offsets, sizes, strides, tiling_size, tiles)
    for i in range(out.shape[0]):
        s = 0.0
        for t in tiles:
            s += actor[t, i]
        out[i] = min(max(s, a_low[i]), a_high[i])


@njit(cache=True)
def score_population(
    memory,
    fits,
    box,
    critic,
    actor,
    coder,
    action_box,
    x0,
    sequences,
    policy_rows,
    gamma,
    trust,
    bonus,
    potential,
    visits,
    tree,
    scores,
):
    """Roll every sequence of ``sequences`` (P, H, m) out from x0 in the learned model and score it:
    sum_t gamma^t r_t + gamma^H V(x_H), the model's rewards and the critic's terminal value.

    ``memory``: the model's LLRState over [x, u] -> [x', r]; ``fits``: its LocalFits arrays (nbr,
    nbr_d, origin, slope, low, high); ``box``: (state low, state high, period) of x'. A rollout
    stops trusting the model at the first step whose query lies more than ``trust`` neighbourhood
    radii from data (0: never) and takes V there; ``bonus`` per unit of that ratio (capped at
    ``trust``) is added to the reward (optimism; 0 in greedy trials). The first ``policy_rows``
    rows are the actor's closed-loop rollouts: their actions are pi(x_t), written back into
    ``sequences``. ``potential`` > 0 adds optimism to the terminal value: ``potential`` x the mean
    over the active tiles of 1 / sqrt(1 + ``visits``[tile]) (the learner's real visits). ``tree``: the fits' k-d tree, which finds each query's nearest sample (an empty
    tuple: a scan, the reference). Writes ``scores`` (P,).
    """
    P, H, m = sequences.shape
    n = x0.shape[0]
    s_low, s_high, period = box
    nbr, nbr_d, origin, slope, low, high = fits
    a_low, a_high = action_box
    tiles = np.empty(coder[4].shape[0], dtype=np.int64)
    z = np.empty(n + m)
    out = np.empty(origin.shape[1])
    x = np.empty(n)
    for p in range(P):
        x[:] = x0
        total = 0.0
        discount = 1.0
        for t in range(H):
            if p < policy_rows:
                _policy(actor, x, coder, tiles, a_low, a_high, sequences[p, t])
            for j in range(n):
                z[j] = x[j]
            for i in range(m):
                z[n + i] = sequences[p, t, i]
            if len(tree) > 0:
                near, distance = nearest_tree(
                    memory, tree[0], tree[1], tree[2], tree[3], tree[4], z
                )
            else:
                near, distance = nearest_scan(memory, z)
            ratio = predict_at(memory, nbr_d, origin, slope, low, high, near, distance, z, out)
            if trust > 0.0 and ratio > trust and t > 0:
                break  # the model knows nothing here: V at the last trusted state
            reward = out[n]
            if bonus > 0.0:
                reward += bonus * min(ratio, trust)
            total += discount * reward
            discount *= gamma
            for j in range(n):
                v = out[j]
                if period[j] > 0.0:
                    v = v - period[j] * math.floor(v / period[j] + 0.5)
                else:
                    v = min(max(v, s_low[j]), s_high[j])
                x[j] = v
        value = tile_sum(critic, x, coder, tiles)
        if potential > 0.0:
            novelty = 0.0
            for t in tiles:
                novelty += 1.0 / math.sqrt(1.0 + visits[t])
            value += potential * novelty / tiles.shape[0]
        scores[p] = total + discount * value


@njit(cache=True)
def update_distribution(sequences, scores, elites, temperature, method, min_std, mean, std):
    """The next mean and std (H, m) from the ``elites`` best sequences: MPPI weights
    exp((S - S_max) / (temperature * (S_max - S_elite))) or, for CEM, equal weights."""
    P, H, m = sequences.shape
    order = np.argsort(-scores, kind="mergesort")
    top = scores[order[0]]
    spread = max(top - scores[order[elites - 1]], 1e-12)
    weights = np.empty(elites)
    total = 0.0
    for e in range(elites):
        weights[e] = (
            1.0 if method == CEM else math.exp((scores[order[e]] - top) / (temperature * spread))
        )
        total += weights[e]
    for t in range(H):
        for i in range(m):
            mu = 0.0
            for e in range(elites):
                mu += weights[e] * sequences[order[e], t, i]
            mu /= total
            var = 0.0
            for e in range(elites):
                d = sequences[order[e], t, i] - mu
                var += weights[e] * d * d
            mean[t, i] = mu
            std[t, i] = max(math.sqrt(var / total), min_std[i])
    return order[0]
