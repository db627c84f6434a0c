"""Tile coding: hand-computed tiles, periodic wrap, offsets, clipping, back ends agree."""

import numpy as np
import pytest

from rmac_mj.approximators.tile_coding import (
    LinearTileApproximator,
    TileCoder,
    TileCodingConfig,
    tiling_offsets,
)

PI = np.pi


def pendulum_coder(num_tilings=2, backend="numba", offsets="uniform"):
    """phi periodic over [-pi, pi), phi_dot in [-10, 10]; 7 tiles each (7 x 8 per tiling)."""
    return TileCoder(
        [-PI, -10.0],
        [PI, 10.0],
        [True, False],
        TileCodingConfig(num_tilings=num_tilings, tiles=7, offsets=offsets),
        backend,
    )


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize(
    "x, expected",
    [
        # Tile coordinates c = floor((x - low) * 7 / range + j / 2); index = j * 56 + c_phi * 8 + c_vel.
        ((-3.0, -9.9), [0 * 8 + 0, 56 + 0 * 8 + 0]),  # s = (0.158, 0.035)
        ((2.0, 5.0), [5 * 8 + 5, 56 + 6 * 8 + 5]),  # s = (5.728, 5.25): phi's tiling 1 moves up
        ((0.1, 1.0), [3 * 8 + 3, 56 + 4 * 8 + 4]),  # s = (3.611, 3.85)
        ((3.0, 9.0), [6 * 8 + 6, 56 + 0 * 8 + 7]),  # s = (6.842, 6.65): tiling 1 wraps phi to 0
    ],
)
def test_active_tiles_hand_computed(backend, x, expected):
    coder = pendulum_coder(backend=backend)
    assert coder.sizes.tolist() == [7, 8] and coder.num_features == 2 * 56
    np.testing.assert_array_equal(coder.active_tiles(np.array(x)), expected)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_periodic_wrap(backend):
    coder = pendulum_coder(backend=backend)
    eps = 1e-6
    below, above = coder.active_tiles([PI - eps, 0.3]), coder.active_tiles([-PI + eps, 0.3])
    # Tiling 0's edge lies at +-pi; tiling 1 (shifted by half a tile) has one tile across +-pi.
    assert below[0] != above[0]
    assert below[1] == above[1]
    for phi in (-PI, 0.4, 2.9):
        ref = coder.active_tiles([phi, 0.3])
        for turns in (-3, -1, 1, 2):
            np.testing.assert_array_equal(coder.active_tiles([phi + 2 * PI * turns, 0.3]), ref)
    np.testing.assert_array_equal(coder.active_tiles([PI, 0.3]), coder.active_tiles([-PI, 0.3]))


def test_offsets():
    np.testing.assert_allclose(
        tiling_offsets(4, 2, "uniform"), [[0, 0], [0.25, 0.25], [0.5, 0.5], [0.75, 0.75]]
    )
    grid = tiling_offsets(16, 2, "grid")
    assert grid.shape == (16, 2)
    assert {tuple(row) for row in grid} == {(a / 4, b / 4) for a in range(4) for b in range(4)}
    with pytest.raises(ValueError, match="num_tilings"):
        tiling_offsets(12, 2, "grid")
    # A shift of j/T of a tile: moving x by a tile / T along one dimension changes exactly one
    # tiling's tile along that dimension.
    coder = TileCoder([0.0], [1.0], [False], TileCodingConfig(num_tilings=4, tiles=1))
    width = 1.0
    tiles = [coder.active_tiles([x]) % coder.tiling_size for x in (0.1, 0.1 + width / 4)]
    assert np.count_nonzero(tiles[0] != tiles[1]) == 1


@pytest.mark.parametrize("offsets", ["uniform", "grid"])
def test_one_active_tile_per_tiling(offsets):
    rng = np.random.default_rng(0)
    coder = TileCoder(
        [-PI, -60.0, 0.0],
        [PI, 60.0, 1.0],
        [True, False, False],
        TileCodingConfig(num_tilings=8, tiles=(7, 5, 3), offsets=offsets),
    )
    assert coder.sizes.tolist() == [7, 6, 4] and coder.num_features == 8 * 7 * 6 * 4
    for x in rng.uniform([-10, -100, -1], [10, 100, 2], size=(200, 3)):
        tiles = coder.active_tiles(x)
        assert tiles.shape == (8,) and len(set(tiles.tolist())) == 8
        np.testing.assert_array_equal(tiles // coder.tiling_size, np.arange(8))


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_clipping_at_bounds(backend):
    coder = pendulum_coder(num_tilings=16, backend=backend)
    np.testing.assert_array_equal(coder.active_tiles([0.5, 1e3]), coder.active_tiles([0.5, 10.0]))
    np.testing.assert_array_equal(coder.active_tiles([0.5, -1e3]), coder.active_tiles([0.5, -10.0]))
    assert not np.array_equal(coder.active_tiles([0.5, 10.0]), coder.active_tiles([0.5, 8.0]))
    assert coder.active_tiles([0.5, 1e3]).max() < coder.num_features


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [0.0], [0.0, 0.0, 0.0]])
def test_bad_states_raise(bad):
    for backend in ("numba", "numpy"):
        with pytest.raises(ValueError, match="x must"):
            pendulum_coder(backend=backend).active_tiles(bad)


def test_backends_agree():
    rng = np.random.default_rng(1)
    fast, ref = (
        TileCoder([-PI, -60.0], [PI, 60.0], [True, False], TileCodingConfig(), b)
        for b in ("numba", "numpy")
    )
    for x in rng.uniform([-20, -80], [20, 80], size=(2000, 2)):
        np.testing.assert_array_equal(fast.active_tiles(x), ref.active_tiles(x))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"num_tilings": 0}, "num_tilings"),
        ({"num_tilings": 2.5}, "num_tilings"),
        ({"tiles": 0}, "tiles"),
        ({"tiles": (7, -1)}, "tiles"),
        ({"offsets": "random"}, "offsets"),
    ],
)
def test_config_validation(kwargs, name):
    with pytest.raises(ValueError, match=name):
        TileCodingConfig(**kwargs)


def test_coder_validation():
    with pytest.raises(ValueError, match="low < high"):
        TileCoder([0.0], [0.0], [False])
    with pytest.raises(ValueError, match="one shape"):
        TileCoder([0.0, 0.0], [1.0], [False])
    with pytest.raises(ValueError, match="dimensions"):
        TileCoder([0.0], [1.0], [False], TileCodingConfig(tiles=(3, 3)))
    with pytest.raises(ValueError, match="backend"):
        TileCoder([0.0], [1.0], [False], backend="cuda")


def test_linear_approximator():
    coder = pendulum_coder(num_tilings=16)
    f = LinearTileApproximator(coder, output_dim=2, initial_value=-1.0)
    x, far = np.array([0.2, 1.0]), np.array([-2.5, -8.0])
    np.testing.assert_allclose(f(x), [-1.0, -1.0])
    np.testing.assert_array_equal(f.gradient(x), coder.active_tiles(x))
    f.update(x, [0.1, -0.2])  # a step per active weight moves f(x) by num_tilings times it
    np.testing.assert_allclose(f(x), [-1.0 + 1.6, -1.0 - 3.2])
    np.testing.assert_allclose(f(far), [-1.0, -1.0])
