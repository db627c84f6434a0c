"""Tile coding (Sutton and Barto 1998, 8.3.2) and a linear approximator on it (section 6.1).

A tiling (the paper's partition) is a uniform grid of ``tiles[d]`` tiles per dimension, shifted per
tiling (``TileCodingConfig.offsets``); a state activates one tile per tiling, and the value is the
sum of the active weights. Back ends numpy and numba.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from numbers import Integral
from typing import ClassVar, Literal

import numba
import numpy as np

from rmac_mj._cache import say_when_compiling
from rmac_mj.constraints import Interval, Options, TupleOf, check, check_config, finite_vector

say_when_compiling()  # the first compilation in a process says so (tile coding's kernel)

Backend = Literal["numba", "numpy"]


@dataclasses.dataclass(frozen=True)
class TileCodingConfig:
    """Layout of the tilings (paper section 6.1: 16 tilings of 7 x 7 tiles).

    Attributes:
      num_tilings: number of tilings (the paper's partitions), T. Paper: 16.
      tiles: tiles per dimension of one tiling; an int applies to every dimension. Paper: 7.
      offsets: ``"uniform"`` (tiling j shifted by j/T of a tile along each dimension, Sutton and
        Barto 1998) or ``"grid"`` (a T**(1/n)-per-dimension grid of shifts; needs T to be an n-th power).
    """

    num_tilings: int = 16
    tiles: int | tuple[int, ...] = 7
    offsets: Literal["uniform", "grid"] = "uniform"

    parameter_constraints: ClassVar[dict[str, list]] = {
        "num_tilings": [Interval(Integral, 1, None)],
        "tiles": [Interval(Integral, 1, None), TupleOf(Interval(Integral, 1, None))],
        "offsets": [Options("uniform", "grid")],
    }

    def __post_init__(self) -> None:
        check_config(self)

    def tiles_for(self, dim: int) -> np.ndarray:
        """ndarray of int of shape (dim,): tiles per dimension of one tiling."""
        if np.isscalar(self.tiles):
            return np.full(dim, int(self.tiles), dtype=np.int64)
        tiles = np.asarray(self.tiles, dtype=np.int64)
        if tiles.shape != (dim,):
            raise ValueError(
                f"TileCodingConfig.tiles has {tiles.shape[0]} entries but the state has {dim} dimensions"
            )
        return tiles


def feature_count(periodic: Sequence[bool], config: TileCodingConfig) -> int:
    """Tiles of all tilings (a linear approximator's weights) on a state whose dimensions are
    ``periodic`` as given: ``num_tilings`` times the product of each dimension's tiles (one more
    where bounded), computed exactly without building the coder (nothing is allocated)."""
    dim = len(periodic)
    tiles = [config.tiles] * dim if np.isscalar(config.tiles) else list(config.tiles)
    if len(tiles) != dim:
        raise ValueError(
            f"TileCodingConfig.tiles has {len(tiles)} entries but the state has {dim} dimensions"
        )
    return int(config.num_tilings) * math.prod(
        int(t) + (0 if wraps else 1) for t, wraps in zip(tiles, periodic)
    )


def tiling_offsets(num_tilings: int, dim: int, kind: str = "uniform") -> np.ndarray:
    """Shift of each tiling, in tile widths.

    Returns:
      ndarray of shape (num_tilings, dim), entries in [0, 1).
    """
    if kind == "uniform":
        return np.repeat((np.arange(num_tilings) / num_tilings)[:, None], dim, axis=1)
    if kind == "grid":
        per_dim = int(round(num_tilings ** (1.0 / dim)))
        if per_dim**dim != num_tilings:
            raise ValueError(
                f"offsets='grid' needs num_tilings to be a {dim}-th power, got num_tilings={num_tilings}"
            )
        shifts = np.stack(np.unravel_index(np.arange(num_tilings), (per_dim,) * dim), axis=1)
        return shifts / per_dim
    raise ValueError(f"offsets must be 'uniform' or 'grid', got {kind!r}")


@numba.njit(cache=True)
def _active_tiles_numba(x, low, high, periodic, scale, offsets, sizes, strides, tiling_size, out):
    """Compiled twin of :meth:`TileCoder._active_tiles_numpy` (see it for the formula).

    Returns False (and leaves ``out`` undefined) if ``x`` is not finite.
    """
    num_tilings, dim = offsets.shape
    for d in range(dim):
        if not np.isfinite(x[d]):
            return False
    for j in range(num_tilings):
        index = j * tiling_size
        for d in range(dim):
            xd = x[d]
            if periodic[d]:
                period = high[d] - low[d]
                xd = low[d] + ((xd - low[d]) % period)
            else:
                xd = min(max(xd, low[d]), high[d])
            c = int(np.floor((xd - low[d]) * scale[d] + offsets[j, d]))
            if periodic[d]:
                c = c % sizes[d]
            elif c >= sizes[d]:  # guards against rounding at x == high
                c = sizes[d] - 1
            index += c * strides[d]
        out[j] = index
    return True


class TileCoder:
    """Maps a state to the indices of its active tiles, one per tiling.

    Args:
      low, high: array-like of shape (n,), the range of each dimension (one period for a periodic one).
      periodic: array-like of bool of shape (n,), True where the dimension wraps around.
      config: the tiling layout.
      backend: ``"numba"`` or ``"numpy"``; both give identical indices.

    Attributes:
      num_features: total number of tiles (weights of a linear approximator).
      sizes: ndarray of int of shape (n,), tiles per dimension of one tiling including the extra
        tile of a bounded dimension.
      offsets: ndarray of shape (num_tilings, n), shift of each tiling in tile widths.

    Range: a periodic dimension (an angle) wraps onto one period ``[low, high)``, and its
    ``tiles[d]`` tiles cover it exactly (the shifted grid wraps too). A bounded dimension is clipped
    to ``[low, high]`` (states outside are not an error) and gets ``tiles[d] + 1`` tiles per tiling,
    so that the shifted grids still cover the whole range. Non-finite states raise ``ValueError``.
    """

    def __init__(
        self,
        low: Sequence[float],
        high: Sequence[float],
        periodic: Sequence[bool],
        config: TileCodingConfig = TileCodingConfig(),
        backend: Backend = "numba",
    ) -> None:
        self.low = np.asarray(low, dtype=float).reshape(-1)
        self.high = np.asarray(high, dtype=float).reshape(-1)
        self.periodic = np.asarray(periodic, dtype=bool).reshape(-1)
        if not (self.low.shape == self.high.shape == self.periodic.shape):
            raise ValueError(
                f"TileCoder: low, high and periodic must have one shape, got {self.low.shape}, "
                f"{self.high.shape} and {self.periodic.shape}"
            )
        if not (
            np.all(np.isfinite(self.low))
            and np.all(np.isfinite(self.high))
            and np.all(self.high > self.low)
        ):
            raise ValueError(
                f"TileCoder: need finite low < high, got low={self.low}, high={self.high}"
            )
        check("TileCoder", {"backend": [Options("numba", "numpy")]}, {"backend": backend})
        self.config = config
        self.backend = backend
        self.dim = self.low.shape[0]
        self._shape = (self.dim,)
        self.num_tilings = int(config.num_tilings)
        self.tiles = config.tiles_for(self.dim)
        self.scale = self.tiles / (self.high - self.low)  # tiles per state unit
        self.sizes = np.where(self.periodic, self.tiles, self.tiles + 1).astype(np.int64)
        # Row-major strides within one tiling; the last dimension varies fastest.
        self.strides = np.ones(self.dim, dtype=np.int64)
        for d in range(self.dim - 2, -1, -1):
            self.strides[d] = self.strides[d + 1] * self.sizes[d + 1]
        self.tiling_size = int(np.prod(self.sizes))
        self.num_features = self.num_tilings * self.tiling_size
        self.offsets = tiling_offsets(self.num_tilings, self.dim, config.offsets)

    def check_state(self, x: np.ndarray, name: str = "x") -> np.ndarray:
        """``x`` as a float ndarray of shape (n,); raises ValueError if the shape is wrong or non-finite."""
        return finite_vector(x, self.dim, name)

    def active_tiles(self, x: np.ndarray) -> np.ndarray:
        """Indices of the active tiles of state ``x``.

        Args:
          x: array-like of shape (n,), finite; bounded dimensions are clipped to [low, high].
        Returns:
          ndarray of int64 of shape (num_tilings,); entry j lies in
          [j * tiling_size, (j + 1) * tiling_size).
        """
        if self.backend == "numba":
            return self.active_tiles_into(x, np.empty(self.num_tilings, dtype=np.int64))
        return self._active_tiles_numpy(self.check_state(x))

    def active_tiles_into(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Compiled :meth:`active_tiles` writing into ``out`` (int64, shape (num_tilings,)).

        The fast path of a control loop: a float64 ndarray of shape (n,) is passed straight to the
        kernel, which also checks finiteness; anything else goes through :meth:`check_state`.
        """
        if not (type(x) is np.ndarray and x.dtype == np.float64 and x.shape == self._shape):
            x = self.check_state(x)
        if not _active_tiles_numba(
            x,
            self.low,
            self.high,
            self.periodic,
            self.scale,
            self.offsets,
            self.sizes,
            self.strides,
            self.tiling_size,
            out,
        ):
            self.check_state(x)  # raises the ValueError naming the non-finite state
        return out

    def _active_tiles_numpy(self, x: np.ndarray) -> np.ndarray:
        """Reference: tile coordinate c[j, d] = floor((x[d] - low[d]) / width[d] + offset[j, d])."""
        wrapped = self.low + np.mod(x - self.low, self.high - self.low)
        x = np.where(self.periodic, wrapped, np.clip(x, self.low, self.high))
        coords = np.floor((x - self.low) * self.scale + self.offsets).astype(np.int64)
        coords = np.where(self.periodic, coords % self.sizes, np.minimum(coords, self.sizes - 1))
        return (
            np.arange(self.num_tilings, dtype=np.int64) * self.tiling_size + coords @ self.strides
        )


class LinearTileApproximator:
    """f(x) = sum over the active tiles of x of ``weights[tile]``: tile coding with linear weights.

    The gradient of f(x) with respect to the weights is 1 on the active tiles of x and 0 elsewhere,
    so a gradient step touches ``num_tilings`` weights (or rows, for a vector output).

    Args:
      coder: the tile coder.
      output_dim: number of outputs m; the weights have shape (num_features, m).
      initial_value: every output starts at this value (split evenly over the tilings).
    """

    def __init__(self, coder: TileCoder, output_dim: int = 1, initial_value: float = 0.0) -> None:
        if int(output_dim) != output_dim or output_dim < 1:
            raise ValueError(f"output_dim must be a positive integer, got {output_dim!r}")
        self.coder = coder
        self.output_dim = int(output_dim)
        self.weights_ = np.full(
            (coder.num_features, self.output_dim), float(initial_value) / coder.num_tilings
        )

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """f(x), ndarray of shape (m,)."""
        return self.weights_[self.coder.active_tiles(x)].sum(axis=0)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """d f / d weights for one output: the active tile indices, ndarray of int of shape (T,)."""
        return self.coder.active_tiles(x)

    def update(self, x: np.ndarray, step: np.ndarray) -> None:
        """weights[active(x)] += step: a gradient step of size ``step`` (shape (m,)) per active tile."""
        self.weights_[self.coder.active_tiles(x)] += np.asarray(step, dtype=float).reshape(1, -1)
