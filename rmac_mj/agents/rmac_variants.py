"""RMAC's options beyond Algorithm 2 (``RMACConfig.reachable_rule``): the rules that score candidate
actions instead of the paper's vertices of the reachable set.

'grid' scores ``reachable_grid`` evenly spaced values per action dimension, 'exact' (m = 1) refines
the best grid point by golden-section search to :data:`EXACT_TOLERANCE`; 'vertices' (the paper,
line 16 of Algorithm 2) is in :mod:`rmac_mj.agents.rmac`. The compiled step
(:mod:`rmac_mj.agents._rmac_kernels`) runs the same rules on the arrays built here.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

#: Absolute tolerance, in action units, of the golden-section refinement of reachable_rule='exact'.
EXACT_TOLERANCE = 1e-6
#: 1 / golden ratio, the shrink factor of one golden-section step.
INV_PHI = (5.0**0.5 - 1.0) / 2.0

#: A candidate action's score and the state it reaches: u -> (-P |u|^2 + gamma V(x'(u)), x'(u)).
Score = Callable[[np.ndarray], tuple[float, np.ndarray]]


def candidate_actions(
    rule: str, grid: int, low: np.ndarray, high: np.ndarray, vertices: np.ndarray
) -> np.ndarray:
    """The candidate actions of the reachable rule, shape (c, m): the vertices for 'vertices', for
    'grid' and 'exact' the product of ``grid`` evenly spaced values per action dimension."""
    if rule not in ("grid", "exact"):
        return vertices.copy()
    return np.array(
        list(itertools.product(*[np.linspace(lo, hi, grid) for lo, hi in zip(low, high)])),
        dtype=float,
    )


def refine_steps(rule: str, grid: int, low: np.ndarray, high: np.ndarray) -> int:
    """Golden-section steps of 'exact': a bracket of two grid spacings shrinks to EXACT_TOLERANCE;
    0 for the other rules."""
    span = 2.0 * float(np.max(high - low)) / (grid - 1)
    if rule != "exact" or span <= EXACT_TOLERANCE:
        return 0
    return int(np.ceil(np.log(EXACT_TOLERANCE / span) / np.log(INV_PHI)))


def best_scored(
    score: Score,
    candidates: np.ndarray,
    steps: int,
    low: float,
    high: float,
    grid: int,
) -> np.ndarray:
    """x_r of the rules other than 'vertices': the state reached by the candidate action with the
    highest score (first of equals), refined for 'exact' (``steps`` > 0, m = 1, bounds ``low`` and
    ``high``) by golden-section search between the best grid point's neighbours."""
    best_score, x_r, u_best = -np.inf, None, None
    for u in candidates:
        value, x_next = score(u)
        if value > best_score:
            best_score, x_r, u_best = value, x_next, u
    if x_r is None:  # no score above -inf (the critic's values overflow): the first candidate
        u_best = candidates[0]
        x_r = score(u_best)[1]
    if not steps:
        return x_r
    h = (high - low) / (grid - 1)
    a, b = max(low, float(u_best[0]) - h), min(high, float(u_best[0]) + h)
    f = lambda v: score(np.array([v]))  # noqa: E731
    c, d = b - INV_PHI * (b - a), a + INV_PHI * (b - a)
    (fc, xc), (fd, xd) = f(c), f(d)
    for _ in range(steps):
        if fc >= fd:  # the maximum lies in [a, d]
            b, d, fd, xd = d, c, fc, xc
            c = b - INV_PHI * (b - a)
            fc, xc = f(c)
        else:  # in [c, b]
            a, c, fc, xc = c, d, fd, xd
            d = a + INV_PHI * (b - a)
            fd, xd = f(d)
    value, x_next = (fc, xc) if fc >= fd else (fd, xd)
    return x_next if value > best_score else x_r
