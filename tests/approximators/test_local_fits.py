"""LocalFits: the LLR fits cached at a memory's samples answer queries as the memory's own fit at
the nearest sample would, through insertions and replacements, found by an exact k-d tree."""

import numpy as np
import pytest

from rmac_mj.approximators.llr import LLRMemory
from rmac_mj.approximators.local_fits import LocalFits, nearest_scan, nearest_tree

TWO_PI = 2 * np.pi


def _memory(norm, period, capacity=150, clip=False):
    return LLRMemory(
        3,
        3,
        capacity,
        9,
        input_weights=[1.0, 0.1, 1.0],
        input_period=[period, 0.0, 0.0],
        output_period=[period, 0.0, 0.0],
        norm=norm,
        conditioning="ridge",
        clip=clip,
    )


def _target(x):
    return np.array([np.sin(x[0]) + 0.1 * x[1], x[1] * x[2], x[2] ** 2])


@pytest.mark.parametrize("norm", [1, 2])
@pytest.mark.parametrize("period", [0.0, TWO_PI])
@pytest.mark.parametrize("clip", [False, True])
def test_a_query_is_the_fit_at_the_nearest_sample_through_inserts_and_replacements(
    norm, period, clip
):
    rng = np.random.default_rng(0)
    memory = _memory(norm, period, clip=clip)
    cached, reference = LocalFits(memory), LocalFits(memory, backend="numpy")
    for t in range(400):  # the memory fills at 150, then replaces
        x = rng.uniform([-3, -20, -3], [3, 20, 3])
        memory.insert(x, _target(x))
        if t % 41 == 7 or t > 390:
            for z in rng.uniform([-4, -25, -4], [4, 25, 4], size=(4, 3)):
                got, want = cached.query(z), reference.query(z)
                assert got[2] == want[2]  # the same nearest sample
                np.testing.assert_allclose(got[0], want[0], rtol=1e-9, atol=1e-9)
                assert got[1] == pytest.approx(want[1], rel=1e-12)


def test_the_cache_kept_up_to_date_equals_one_built_afresh():
    rng = np.random.default_rng(1)
    memory = _memory(1, TWO_PI)
    kept = LocalFits(memory)
    for _ in range(300):
        x = rng.uniform(-3, 3, 3)
        memory.insert(x, _target(x))
        kept.refresh()
    fresh = LocalFits(memory)
    fresh.refresh()
    for name in ("nbr", "nbr_d", "origin", "slope", "low", "high"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(fresh, name), err_msg=name)


def test_the_cache_follows_a_memory_loaded_from_a_state_dict():
    rng = np.random.default_rng(2)
    a, b = _memory(1, 0.0), _memory(1, 0.0)
    for memory in (a, b):
        for x in rng.uniform(-3, 3, (60, 3)):
            memory.insert(x, _target(x))
    fits = LocalFits(a)
    z = np.array([0.5, 1.0, -0.5])
    fits.query(z)
    a.load_state_dict(b.state_dict())
    got = fits.query(z)
    want = LocalFits(a, backend="numpy").query(z)
    assert got[2] == want[2]
    np.testing.assert_allclose(got[0], want[0], atol=1e-9)


@pytest.mark.parametrize("norm", [1, 2])
def test_the_tree_finds_the_nearest_sample_across_the_periodic_seam(norm):
    rng = np.random.default_rng(3)
    memory = LLRMemory(
        4, 1, 500, 5, input_weights=[1, 0.3, 2, 1], input_period=[TWO_PI, 0, 0, TWO_PI], norm=norm
    )
    walk = np.cumsum(rng.normal(0, 0.2, (500, 4)), axis=0)  # trajectories, as real data lie
    for x in walk:
        memory.insert(x, [0.0])
    fits = LocalFits(memory)
    fits.refresh()
    state = memory.kernel_state
    queries = walk[rng.integers(500, size=300)] + rng.normal(0, 0.5, (300, 4))
    queries[:20, 0] = np.pi - 1e-9  # on the seam
    for z in memory._canonical(queries):
        assert nearest_tree(state, *fits.tree, z) == nearest_scan(state, z)


def test_uncertainty_is_below_one_among_the_data_and_grows_away_from_it():
    rng = np.random.default_rng(4)
    memory = _memory(1, 0.0)
    for x in rng.uniform(-1, 1, (150, 3)):
        memory.insert(x, _target(x))
    fits = LocalFits(memory)
    inside = [fits.query(z)[1] for z in rng.uniform(-0.8, 0.8, (20, 3))]
    assert max(inside) < 1.0
    away = [fits.query(np.array([1.0 + d, 0.0, 0.0]))[1] for d in (0.5, 1.0, 2.0, 4.0)]
    assert all(a < b for a, b in zip(away, away[1:])) and away[0] > 1.0
