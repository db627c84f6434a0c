"""Local Linear Regression (section 4): :class:`LLRMemory` and its compiled interface.

A query x_q fits y = beta [x; 1] to its K nearest samples K(x_q) and predicts beta [x_q; 1]; the
choices the paper leaves open are :class:`LLRMemory` parameters. Compiled learners use
``LLRMemory.kernel_state`` with the ``llr_*`` functions.
"""

from __future__ import annotations

import dataclasses
from numbers import Integral, Real
from typing import Any, ClassVar

import numpy as np

from rmac_mj.approximators import _llr_kernels as _k
from rmac_mj.approximators._llr_kernels import LLR_STATE_TYPE, LLRState, LocalFit
from rmac_mj.approximators._llr_redundancy import MEASURE_DISTANCE, MEASURE_MISFIT
from rmac_mj.approximators.llr_numpy import (
    FitSettings,
    distance_numpy,
    fit_numpy,
    misfit_numpy,
    search_numpy,
    wrap,
)
from rmac_mj.constraints import (
    WEIGHTS,
    Boolean,
    Field,
    Interval,
    Options,
    TupleOf,
    check,
    check_config,
)

#: The compiled interface: the functions take an LLRState first (``_llr_kernels`` has the details);
#: ``wrap_scalar(d, period)`` is ``wrap`` for one number, for compiled callers.
llr_nearest = _k.nearest
llr_local_fit = _k.local_fit
llr_query = _k.query
llr_fit_at = _k.fit_at
llr_insert = _k.insert
llr_insert_among = _k.insert_among
llr_move_outputs = _k.move_outputs
llr_add_weighted = _k.add_weighted
llr_size = _k.size
llr_canonical = _k.canonical
wrap_scalar = _k.wrap

__all__ = [
    "LLRConfig",
    "LLRMemory",
    "LLRState",
    "LLR_STATE_TYPE",
    "LocalFit",
    "SHARED_CONSTRAINTS",
    "llr_add_weighted",
    "llr_canonical",
    "llr_fit_at",
    "llr_insert",
    "llr_insert_among",
    "llr_local_fit",
    "llr_move_outputs",
    "llr_nearest",
    "llr_query",
    "llr_size",
    "shared_settings",
    "with_memory_defaults",
    "wrap",
    "wrap_scalar",
]

_CONDITIONINGS = ("svd", "ridge", "none")
_REPLACEMENTS = {
    "oldest": _k.REPLACE_OLDEST,
    "nearest": _k.REPLACE_NEAREST,
    "redundancy": _k.REPLACE_REDUNDANCY,
}
_MEASURES = {"distance": MEASURE_DISTANCE, "misfit": MEASURE_MISFIT}
_BACKENDS = ("numba", "numpy")
#: Relative eigenvalue cutoff of G = A^T A used for 'none' and 'ridge' (a singular value ratio of
#: about 3e-7): only numerically singular directions are dropped.
_NUMERICAL_EIG_CUTOFF = 1e-13


class LLRMemory:
    """A memory of at most ``capacity`` samples [x | y] with local linear regression queries.

    Args:
      input_dim, output_dim: n and m.
      capacity: N, the maximum number of samples (Table 2: 2000 critic/reference, 100 process).
      n_neighbours: K (Table 2: 20 critic/reference, 9 process); at most ``capacity``.
      input_weights: ndarray of shape (n,), >= 0, scaling each input in the distance (Table 2). Default
        ones.
      norm: 1 or 2.
      input_period, output_period: ndarrays of shape (n,) and (m,): period of each periodic dimension,
        0 elsewhere. Default: nothing periodic.
      conditioning: 'svd', 'ridge' or 'none'; rcond, ridge: their parameters.
      clip: clip predictions to the neighbours' output range.
      replacement: 'nearest', 'oldest' or 'redundancy'.
      redundancy: the score of 'redundancy' replacement, 'distance' or 'misfit' (below).
      redundancy_smoothing: eta in (0, 1], the exponential smoothing factor of the scores.
      backend: 'numba' (compiled kernels) or 'numpy' (the readable reference); same results.

    Learned state: ``X_`` (N, n), ``Y_`` (N, m) (the first ``n_samples_`` rows are valid),
    ``stamp_`` (N,), the insertion time of each sample, and ``redundancy_`` (N,), each sample's
    redundancy score (kept under 'redundancy' replacement only, 0 otherwise). ``kernel_state``
    names the same arrays for compiled code.

    Where the paper is silent (defaults in brackets):

    * ``norm`` [1]: 1- or 2-norm of the weighted input difference (the authors' group's code uses
      the 1-norm); only the ordering of neighbours depends on it.
    * ``input_period``: differences of periodic inputs are wrapped to [-period/2, period/2) in the
      distance and in the regression, so angles near +pi and -pi are neighbours and one affine model
      spans the seam. ``output_period``: the neighbours' outputs are unwrapped around the nearest
      one's before fitting, so predictions may leave the nominal range by up to half a period;
      callers wrap what they compare.
    * ``conditioning`` ['svd'], ``rcond`` [0.01]: neighbours along a past trajectory lie almost on a
      line, where a plain least-squares fit extrapolates wildly. The fit is made in the weighted,
      query-centred input space; 'svd' drops singular values below ``rcond`` times the largest,
      'ridge' adds ``ridge`` to the slopes' diagonal (as TU Delft's GRL does), 'none' is the
      pseudo-inverse.
    * ``clip`` [False]: clip each prediction to its neighbours' output range (GRL does this).
    * ``replacement`` ['nearest']: a full memory replaces the new sample's nearest neighbour (the
      most redundant with it), the oldest sample, or the sample of highest redundancy score.
    * A query on an empty memory predicts 0 with beta = 0 (Algorithm 2 line 2: V_0 = 0, beta^P = 0).

    Redundancy replacement (``redundancy``, ``redundancy_smoothing``), the scheme described of the
    authors' code, with its details our own choices. Every sample i carries a score rho_i (higher:
    more redundant). When [x_* | y_*] is inserted, with K(x_*) its K nearest stored samples, each
    neighbour's score is smoothed towards a measure c_i, rho_i <- (1 - eta) rho_i + eta c_i for i in
    K(x_*), and the new sample starts from its neighbourhood's level, rho_* = (1 - eta) mean_{i in
    K(x_*)} rho_i + eta c_* (0 on an empty memory). 'distance': c_i = -d(x_i, x_*), c_* = -min_i
    d(x_i, x_*); 'misfit': one affine model fitted at x_* to the new sample and its neighbours, c_j
    = -|wrap(y_j - y_hat(x_j))|^2 for all of them (a sample its neighbourhood's model predicts well
    is redundant). Once full, the new sample replaces the stored sample of highest score (first of
    equals), after the neighbours' scores are updated; the new sample itself is always stored.
    Scores change only on insertion (queries leave the memory unchanged); ``fit`` scores each sample
    by its own measure among the others. eta = 0.1 averages a score over roughly its last ten
    neighbourhood events.
    """

    def __init__(
        self,
        input_dim: int,
        output_dim: int,
        capacity: int,
        n_neighbours: int,
        input_weights: Any = None,
        norm: int = 1,
        input_period: Any = None,
        output_period: Any = None,
        conditioning: str = "svd",
        rcond: float = 0.01,
        ridge: float = 1e-3,
        clip: bool = False,
        replacement: str = "nearest",
        redundancy: str = "distance",
        redundancy_smoothing: float = 0.1,
        backend: str = "numba",
    ) -> None:
        self.input_dim = input_dim
        self.output_dim = output_dim
        self.capacity = capacity
        self.n_neighbours = n_neighbours
        self.input_weights = input_weights
        self.norm = norm
        self.input_period = input_period
        self.output_period = output_period
        self.conditioning = conditioning
        self.rcond = rcond
        self.ridge = ridge
        self.clip = clip
        self.replacement = replacement
        self.redundancy = redundancy
        self.redundancy_smoothing = redundancy_smoothing
        self.backend = backend
        self._validate()
        n, m, N = self.input_dim, self.output_dim, self.capacity
        self._Xt = np.zeros((n, N))  # inputs by dimension: see _llr_kernels
        self.Y_ = np.zeros((N, m))
        self.stamp_ = np.zeros(N, dtype=np.int64)
        self.redundancy_ = np.zeros(N)
        # [count, clock, version] (_llr_kernels.COUNT, CLOCK, VERSION): the version counts changes
        # to the inputs, which tells compiled code whether a neighbour list is still current.
        self._counters = np.zeros(3, dtype=np.int64)
        self._idx = np.empty(self.n_neighbours, dtype=np.int64)
        self._beta = np.empty((m, n + 1))
        self._pred = np.empty(m)
        self._state = self._new_kernel_state()

    @staticmethod
    def memory_estimate(input_dim: int, output_dim: int, capacity: int, n_neighbours: int) -> int:
        """Bytes of the arrays a memory of these sizes allocates (computed, nothing allocated):
        per sample its input (n floats), output (m), stamp, redundancy score, distance and search
        flag; per neighbour the kept lists and search buffers."""
        per_sample = 8 * (input_dim + output_dim + 3) + 1
        per_neighbour = 8 * (2 * _k.KEPT + 4)
        return int(capacity) * per_sample + (int(n_neighbours) + 1) * per_neighbour + 4096

    @staticmethod
    def state_estimate(input_dim: int, output_dim: int, capacity: int) -> int:
        """Bytes of one :meth:`state_dict` of a memory of these sizes."""
        return int(capacity) * 8 * (input_dim + output_dim + 2) + 16

    def _new_kernel_state(self) -> LLRState:
        arrays = _k.LLRArrays(
            Xt=self._Xt,
            Y=self.Y_,
            stamp=self.stamp_,
            counters=self._counters,
            redundancy=self.redundancy_,
            weights=self._w,
            in_period=self._pin,
            out_period=self._pout,
        )
        settings = _k.LLRSettings(
            n_neighbours=int(self.n_neighbours),
            norm=int(self.norm),
            clip=bool(self.clip),
            replacement=_REPLACEMENTS[self.replacement],
            eig_cutoff=self._eig_cutoff,
            ridge=self._ridge,
            measure=_MEASURES[self.redundancy],
            smoothing=float(self.redundancy_smoothing),
        )
        return _k.new_state(arrays, settings)

    def __getstate__(self) -> dict[str, Any]:
        # The structref is a view of the arrays pickled here; it is made anew when unpickled.
        return {k: v for k, v in self.__dict__.items() if k != "_state"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._state = self._new_kernel_state()

    # -- configuration ------------------------------------------------------------------------------
    parameter_constraints: dict[str, list] = {
        "input_dim": [Interval(Integral, 1, None)],
        "output_dim": [Interval(Integral, 1, None)],
        "capacity": [Interval(Integral, 1, None)],
        "n_neighbours": [Interval(Integral, 1, Field("capacity"))],
        "input_weights": [TupleOf(Interval(Real, 0, None), length=Field("input_dim")), None],
        "norm": [Options(1, 2)],
        "input_period": [TupleOf(Interval(Real, 0, None), length=Field("input_dim")), None],
        "output_period": [TupleOf(Interval(Real, 0, None), length=Field("output_dim")), None],
        "conditioning": [Options(*_CONDITIONINGS)],
        "rcond": [Interval(Real, 0, 1, closed="left")],
        "ridge": [Interval(Real, 0, None)],
        "clip": [Boolean()],
        "replacement": [Options(*_REPLACEMENTS)],
        "redundancy": [Options(*_MEASURES)],
        "redundancy_smoothing": [Interval(Real, 0, 1, closed="right")],
        "backend": [Options(*_BACKENDS)],
    }

    def _validate(self) -> None:
        """Check the constructor's arguments against :attr:`parameter_constraints`; derive the
        arrays and numbers the kernels take."""
        values = check(
            "LLRMemory",
            self.parameter_constraints,
            {name: getattr(self, name) for name in self.parameter_constraints},
        )
        n, m = self.input_dim, self.output_dim
        self._w = self._vector(values["input_weights"], n, 1.0)
        self._pin = self._vector(values["input_period"], n, 0.0)
        self._pout = self._vector(values["output_period"], m, 0.0)
        if self.conditioning == "svd":
            self._eig_cutoff = max(float(self.rcond) ** 2, _NUMERICAL_EIG_CUTOFF)
        else:
            self._eig_cutoff = _NUMERICAL_EIG_CUTOFF
        self._ridge = float(self.ridge) if self.conditioning == "ridge" else 0.0
        self._fit_settings = FitSettings(
            self._w, self._pin, self._pout, self._eig_cutoff, self._ridge
        )

    @staticmethod
    def _vector(value: tuple | None, size: int, default: float) -> np.ndarray:
        """A checked per-dimension setting as a contiguous float vector (``default`` for None)."""
        if value is None:
            return np.full(size, default)
        return np.ascontiguousarray(value, dtype=float)

    def _check(self, name: str, value: Any, size: int, finite: bool = True) -> np.ndarray:
        """value as a float vector of shape (size,); checked finite unless ``finite`` is False (the
        numba kernels check that themselves, at no cost)."""
        v = (
            value
            if type(value) is np.ndarray and value.dtype == np.float64
            else np.asarray(value, dtype=float)
        )
        if v.shape != (size,):
            v = v.reshape(-1)
            if v.shape != (size,):
                raise ValueError(
                    f"LLRMemory: {name} must have shape ({size},), got {np.shape(value)}"
                )
        if finite and not np.all(np.isfinite(v)):
            self._not_finite(name, value)
        return v

    @staticmethod
    def _not_finite(name: str, value: Any) -> None:
        raise ValueError(f"LLRMemory: {name} must be finite, got {value!r}")

    @property
    def kernel_state(self) -> LLRState:
        """The memory as compiled code takes it: its own arrays and settings, named (see
        ``_llr_kernels``). Compiled updates through it change this memory."""
        return self._state

    @property
    def X_(self) -> np.ndarray:
        """Stored inputs, ndarray of shape (N, n) (a view; periodic inputs in [-period/2, period/2))."""
        return self._Xt.T

    def _canonical(self, x: np.ndarray) -> np.ndarray:
        return wrap(x, self._pin)

    # -- state --------------------------------------------------------------------------------------
    @property
    def n_samples_(self) -> int:
        return int(self._counters[_k.COUNT])

    def reset(self) -> None:
        """Forget every sample."""
        self._counters[:2] = 0
        self._counters[_k.VERSION] += 1
        self.stamp_[:] = 0
        self.redundancy_[:] = 0.0

    def fit(self, X: Any, Y: Any) -> LLRMemory:
        """Initialise the memory from given samples (prior knowledge, section 7).

        X: array of shape (s, n), Y: (s, m), s <= capacity. Replaces all current samples.
        """
        X = np.asarray(X, dtype=float)
        Y = np.asarray(Y, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.input_dim:
            raise ValueError(
                f"LLRMemory.fit: X must have shape (s, {self.input_dim}), got {X.shape}"
            )
        if Y.shape != (X.shape[0], self.output_dim):
            raise ValueError(
                f"LLRMemory.fit: Y must have shape ({X.shape[0]}, {self.output_dim}), got {Y.shape}"
            )
        if X.shape[0] > self.capacity:
            raise ValueError(f"LLRMemory.fit: {X.shape[0]} samples exceed capacity={self.capacity}")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
            raise ValueError("LLRMemory.fit: X and Y must be finite")
        s = X.shape[0]
        self.reset()
        self.X_[:s] = self._canonical(X)
        self.Y_[:s] = Y
        self.stamp_[:s] = np.arange(s)
        self._counters[:2] = (s, s)
        self._counters[_k.VERSION] += 1
        if self.replacement == "redundancy":
            # Each sample scored as if inserted last, among the others (LLRMemory's docstring).
            X_, Y_ = self.X_[:s], self.Y_[:s]
            for i in range(s):
                others = np.delete(np.arange(s), i)
                idx = others[
                    search_numpy(
                        X_[others], X_[i], self._w, self._pin, self.norm, self.n_neighbours
                    )
                ]
                self.redundancy_[i] = -self._measures(X_[i], Y_[i], idx)[0]
        return self

    def _measures(self, x: np.ndarray, y: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """-c of the new sample [x | y] (x canonical) and of its neighbours idx (nearest first):
        shape (1 + len(idx),); distances under 'distance' (the new sample's: to its nearest), squared
        misfits under 'misfit'. All zero without neighbours."""
        if len(idx) == 0:
            return np.zeros(1)
        if self.redundancy == "distance":
            d = distance_numpy(self.X_[idx], x, self._w, self._pin, self.norm)
            return np.r_[d[0], d]
        return misfit_numpy(
            np.vstack([x, self.X_[idx]]), np.vstack([y, self.Y_[idx]]), x, self._fit_settings
        )

    def state_dict(self, prefix: str = "") -> dict[str, np.ndarray]:
        """Samples and bookkeeping as numeric arrays, keys prefixed with ``prefix``."""
        return {
            prefix + "X": self.X_.copy(),
            prefix + "Y": self.Y_.copy(),
            prefix + "stamp": self.stamp_.copy(),
            prefix + "meta": self._counters[:2].copy(),
            prefix + "redundancy": self.redundancy_.copy(),
        }

    def check_state_dict(self, state: dict[str, np.ndarray], prefix: str = "") -> None:
        """ValueError naming the entry unless ``state`` holds a state dict of this memory under
        ``prefix``: the keys, shapes, finite numbers, the sample count within the capacity and the
        clock past it, every stored input in its period. A state saved before the redundancy scores
        existed (no ``redundancy`` key) is accepted."""
        for key, arr in self.state_dict(prefix).items():
            if key not in state:
                if key == prefix + "redundancy":
                    continue
                raise ValueError(f"LLRMemory: the state dict lacks {key!r}")
            value = np.asarray(state[key])
            if value.dtype != arr.dtype or value.shape != arr.shape:
                raise ValueError(
                    f"LLRMemory: state {key!r} must be {arr.dtype} of shape "
                    f"{arr.shape}, got {value.dtype} of shape {value.shape}"
                )
            if value.dtype.kind == "f" and not np.all(np.isfinite(value)):
                raise ValueError(f"LLRMemory: state {key!r} must be finite")
        count, clock = (int(v) for v in state[prefix + "meta"])
        if not (0 <= count <= self.capacity and clock >= count):
            raise ValueError(
                f"LLRMemory: state {prefix + 'meta'!r} = [count {count}, clock "
                f"{clock}] needs 0 <= count <= {self.capacity} (the capacity) and "
                f"clock >= count"
            )
        X = np.asarray(state[prefix + "X"])[:count]
        if np.any((self._pin > 0) & (np.abs(X) > self._pin * (0.5 + 1e-9))):
            raise ValueError(
                f"LLRMemory: state {prefix + 'X'!r} holds periodic inputs outside "
                f"[-period/2, period/2)"
            )

    def load_state_dict(self, state: dict[str, np.ndarray], prefix: str = "") -> None:
        """Restore a ``state_dict`` (checked first: :meth:`check_state_dict`)."""
        self.check_state_dict(state, prefix)
        if prefix + "redundancy" not in state:
            state = dict(state, **{prefix + "redundancy": np.zeros(self.capacity)})
        for key, arr in (
            ("X", self.X_),
            ("Y", self.Y_),
            ("stamp", self.stamp_),
            ("meta", self._counters[:2]),
            ("redundancy", self.redundancy_),
        ):
            arr[...] = state[prefix + key]
        self._counters[_k.VERSION] += 1

    # -- queries ------------------------------------------------------------------------------------
    def neighbours(self, x: Any) -> np.ndarray:
        """K(x): indices (int64, shape (min(K, n_samples_),)) of the nearest samples, nearest first."""
        xq = self._check("x", x, self.input_dim)
        return self._neighbours(self._canonical(xq)).copy()

    def _neighbours(self, xq: np.ndarray) -> np.ndarray:
        """Unvalidated K(xq) for a canonical xq (periodic entries in [-period/2, period/2))."""
        count = int(self._counters[_k.COUNT])
        if self.backend == "numba":
            return self._idx[: _k.neighbours(self._state, xq, self._idx)]
        return search_numpy(self.X_[:count], xq, self._w, self._pin, self.norm, self.n_neighbours)

    def neighbour_distances(self, x: Any) -> np.ndarray:
        """Weighted distances (float, shape (min(K, n_samples_),)) from x to K(x), nearest first.

        In the memory's norm (``norm``) of the weighted, wrapped input difference, the quantity that
        orders the neighbours (for the 2-norm the distance itself, not its square).
        """
        xq = self._canonical(self._check("x", x, self.input_dim))
        idx = self._neighbours(xq)
        return distance_numpy(self.X_[idx], xq, self._w, self._pin, self.norm)

    def query(self, x: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """LLR at x (shape (n,)).

        Returns:
          prediction: ndarray of shape (m,).
          beta: ndarray of shape (m, n+1), the local affine model [beta_x beta_b], with
            beta @ [x; 1] == prediction (for periodic inputs: valid for wrapped offsets from x).
          neighbours: int64 ndarray of shape (min(K, n_samples_),), nearest first.
        """
        fast = self.backend == "numba"
        xq = self._check("x", x, self.input_dim, finite=not fast)
        pred, beta, idx = self._query(xq)
        if fast and len(idx) == 0 and not np.all(np.isfinite(xq)):
            self._not_finite("x", x)
        return pred.copy(), beta.copy(), idx.copy()

    def _query(self, xq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unvalidated query; returned arrays may be internal buffers (copy before keeping)."""
        if self.backend == "numba":
            nk = _k.query(self._state, xq, self._idx, self._beta, self._pred)
            return self._pred, self._beta, self._idx[: max(nk, 0)]
        xq = self._canonical(xq)
        idx = self._neighbours(xq)
        pred, beta = fit_numpy(self.X_[idx], self.Y_[idx], xq, self._fit_settings, bool(self.clip))
        return pred, beta, idx

    def predict(self, X: Any) -> np.ndarray:
        """Predictions for a batch of queries X of shape (q, n); returns shape (q, m)."""
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.input_dim:
            raise ValueError(
                f"LLRMemory.predict: X must have shape (q, {self.input_dim}), got {X.shape}"
            )
        if not np.all(np.isfinite(X)):
            raise ValueError("LLRMemory.predict: X must be finite")
        return np.array([self._query(x)[0].copy() for x in X]).reshape(X.shape[0], self.output_dim)

    # -- updates ------------------------------------------------------------------------------------
    def insert(self, x: Any, y: Any, nearest: int | None = None) -> int:
        """Store the sample [x | y] and return its slot.

        When the memory is full the replacement policy chooses the slot. ``nearest``, if given, is the
        slot of the stored input nearest to x (saves a search under 'nearest' replacement; unused
        under 'redundancy', which searches K(x) to update the scores).
        """
        fast = self.backend == "numba"
        xv = self._check("x", x, self.input_dim, finite=not fast)
        yv = self._check("y", y, self.output_dim, finite=not fast)
        slot = self._insert(xv, yv, -1 if nearest is None else int(nearest))
        if slot < 0:
            self._not_finite("x" if not np.all(np.isfinite(xv)) else "y", (x, y))
        return slot

    def _insert(self, x: np.ndarray, y: np.ndarray, nearest: int = -1) -> int:
        if self.backend == "numba":
            return int(_k.insert(self._state, x, y, nearest))
        count = int(self._counters[_k.COUNT])
        x = self._canonical(x)
        own = 0.0
        if self.replacement == "redundancy":
            # rho_i <- (1 - eta) rho_i + eta c_i over K(x) (LLRMemory's docstring).
            idx = search_numpy(self.X_[:count], x, self._w, self._pin, self.norm, self.n_neighbours)
            neg_c = self._measures(x, y, idx)
            eta = float(self.redundancy_smoothing)
            for a, i in enumerate(idx):  # in the compiled kernel's order
                self.redundancy_[i] = (1.0 - eta) * self.redundancy_[i] - eta * neg_c[1 + a]
            # rho_* = (1 - eta) mean rho_i + eta c_*, over the updated neighbours
            # (summed in order, as the compiled kernel does)
            own = (
                (1.0 - eta) * (sum(float(self.redundancy_[i]) for i in idx) / len(idx))
                - eta * neg_c[0]
                if len(idx)
                else 0.0
            )
        if count < self.capacity:
            slot = count
            self._counters[_k.COUNT] += 1
        elif self.replacement == "nearest":
            slot = (
                nearest
                if nearest >= 0
                else int(search_numpy(self.X_, x, self._w, self._pin, self.norm, 1)[0])
            )
        elif self.replacement == "redundancy":
            slot = int(np.argmax(self.redundancy_[:count]))
        else:
            slot = int(np.argmin(self.stamp_))
        self.X_[slot] = x
        self.Y_[slot] = y
        self.stamp_[slot] = self._counters[_k.CLOCK]
        if self.replacement == "redundancy":
            self.redundancy_[slot] = own
        self._counters[_k.CLOCK] += 1
        self._counters[_k.VERSION] += 1
        return slot

    def adjust(self, indices: Any, delta: Any) -> None:
        """Add ``delta`` (shape (m,) or (len(indices), m)) to the outputs of the given samples."""
        idx = self._indices("adjust", indices)
        delta = np.asarray(delta, dtype=float)
        if not np.all(np.isfinite(delta)):
            raise ValueError("LLRMemory.adjust: delta must be finite")
        self.Y_[idx] += delta

    def move_outputs(self, indices: Any, target: Any, rate: float) -> None:
        """Move the outputs of the given (distinct) samples towards ``target`` (shape (m,)) by ``rate``:
        y_i += rate * wrap(target - y_i), then periodic outputs are wrapped to one period (RMAC's
        reference update, Algorithm 2 line 20)."""
        idx = self._indices("move_outputs", indices)
        target = self._check("target", target, self.output_dim)
        if not np.isfinite(rate):
            raise ValueError(f"LLRMemory.move_outputs: rate must be finite, got {rate!r}")
        if self.backend == "numba":
            _k.move_outputs(self._state, idx, len(idx), target, float(rate))
            return
        Y, period = self.Y_, self._pout
        Y[idx] += rate * wrap(target - Y[idx], period)
        Y[idx] = wrap(Y[idx], period)

    def add_weighted(self, weights: Any, delta: Any) -> None:
        """y_i += delta * weights_i for every stored sample i (a TD(lambda) update with eligibility
        traces ``weights``, Algorithm 2 line 27).

        weights: shape (capacity,) or (n_samples_,); entries past ``n_samples_`` are ignored.
        delta: shape (m,).
        """
        count = self.n_samples_
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape not in ((self.capacity,), (count,)):
            raise ValueError(
                f"LLRMemory.add_weighted: weights must have shape ({self.capacity},) "
                f"or ({count},), got {np.shape(weights)}"
            )
        delta = self._check("delta", delta, self.output_dim)
        if not np.all(np.isfinite(w[:count])):
            raise ValueError("LLRMemory.add_weighted: weights must be finite")
        if self.backend == "numba":
            _k.add_weighted(self._state, np.ascontiguousarray(w), delta)
            return
        self.Y_[:count] += w[:count, None] * delta

    def _indices(self, method: str, indices: Any) -> np.ndarray:
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if np.any((idx < 0) | (idx >= self._counters[_k.COUNT])):
            raise ValueError(
                f"LLRMemory.{method}: indices must be in [0, {self.n_samples_}), got {indices!r}"
            )
        return idx

    def outputs(self, indices: Any) -> np.ndarray:
        """The stored outputs of the given samples, shape (len(indices), m)."""
        return self.Y_[np.asarray(indices, dtype=np.int64).reshape(-1)].copy()

    def __repr__(self) -> str:
        return (
            f"LLRMemory(input_dim={self.input_dim}, output_dim={self.output_dim}, "
            f"capacity={self.capacity}, n_neighbours={self.n_neighbours}, "
            f"n_samples_={self.n_samples_}, backend={self.backend!r})"
        )


@dataclasses.dataclass(frozen=True)
class LLRConfig:
    """The settings of one of a learner's LLR memories (section 4), e.g. ``RMACConfig.critic``;
    the settings all its memories share (norm, conditioning, back end) are the learner's own.

    A learner's config declares one field per memory, its default that memory's settings
    (:func:`with_memory_defaults` fills a setting left None from it, so ``critic=LLRConfig(capacity=
    60)`` changes the size alone), and Table 2's sizes and K in its ``task_units`` (e.g.
    ``"critic.capacity": ("states", 2000)``: None is resolved on the task); :meth:`memory` builds
    it."""

    capacity: int | None = None
    """Samples the memory holds; None: the learner's default for the task (Table 2 at n = 2, grown
    with the dimension of what the memory holds)."""
    neighbours: int | None = None
    """Nearest neighbours K of a local fit, at most ``capacity``; None: the learner's default for the
    task."""
    weights: tuple[float, ...] | None = None
    """Input weighting, one entry per input dimension (x, or [x, u] for a process model); None: the
    task's (``StateSpace.input_weights``, then ``ActionSpace.input_weights``)."""
    clip: bool | None = None
    """Clip a prediction to the range of its neighbours' outputs. None here and in the next two
    settings: the learner's for this memory (its config's field default)."""
    replacement: str | None = None
    """Which sample a full memory drops for a new one: 'nearest' (the one most redundant with the new
    sample), 'oldest', or 'redundancy' (the highest smoothed redundancy score; see ``redundancy``)."""
    redundancy: str | None = None
    """What the redundancy score measures under replacement='redundancy': 'distance' (a sample close
    to new samples is redundant) or 'misfit' (a sample its local model predicts well is redundant)."""

    parameter_constraints: ClassVar[dict[str, list]] = {
        "capacity": [*LLRMemory.parameter_constraints["capacity"], None],
        "neighbours": [Interval(Integral, 1, Field("capacity")), None],
        "weights": [WEIGHTS, None],
        "clip": [*LLRMemory.parameter_constraints["clip"], None],
        "replacement": [*LLRMemory.parameter_constraints["replacement"], None],
        "redundancy": [*LLRMemory.parameter_constraints["redundancy"], None],
    }

    def __post_init__(self) -> None:
        check_config(self)

    def memory(
        self,
        input_dim: int,
        output_dim: int,
        shared: dict[str, Any],
        input_period: Any = None,
        output_period: Any = None,
    ) -> LLRMemory:
        """An empty :class:`LLRMemory` with these settings (capacity and K resolved) and the
        learner's ``shared`` ones (:func:`shared_settings`)."""
        return LLRMemory(
            input_dim,
            output_dim,
            self.capacity,
            self.neighbours,
            input_weights=self.weights,
            input_period=input_period,
            output_period=output_period,
            clip=self.clip,
            replacement=self.replacement,
            redundancy=self.redundancy,
            **shared,
        )

    def estimate(self, input_dim: int, output_dim: int) -> tuple[int, int]:
        """(bytes of the arrays, bytes of one state dict) of :meth:`memory`, nothing allocated."""
        return (
            LLRMemory.memory_estimate(input_dim, output_dim, self.capacity, self.neighbours),
            LLRMemory.state_estimate(input_dim, output_dim, self.capacity),
        )


#: The settings every memory of a learner shares, as LLRMemory checks them.
SHARED_CONSTRAINTS = {
    name: LLRMemory.parameter_constraints[name]
    for name in ("norm", "conditioning", "rcond", "ridge", "redundancy_smoothing")
}


def with_memory_defaults(config: Any) -> None:
    """Fill, in place (a frozen config's ``__post_init__``), the ``clip``, ``replacement`` and
    ``redundancy`` left None in each of ``config``'s :class:`LLRConfig` fields from that field's
    default: the learner's settings of that memory."""
    for field in dataclasses.fields(config):
        memory = getattr(config, field.name)
        if not isinstance(memory, LLRConfig) or not isinstance(field.default, LLRConfig):
            continue
        unset = {
            name: getattr(field.default, name)
            for name in ("clip", "replacement", "redundancy")
            if getattr(memory, name) is None
        }
        if unset:
            object.__setattr__(config, field.name, dataclasses.replace(memory, **unset))


def shared_settings(config: Any) -> dict[str, Any]:
    """The settings a learner's ``config`` gives all its memories (:data:`SHARED_CONSTRAINTS` and
    its back end), as :class:`LLRMemory` keywords."""
    return {name: getattr(config, name) for name in (*SHARED_CONSTRAINTS, "backend")}
