"""Local Linear Regression memories (section 4): fits, neighbours, memory management, back ends."""

import numpy as np
import pytest

from rmac_mj.approximators import LLRMemory

BACKENDS = ("numba", "numpy")
TWO_PI = 2 * np.pi


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("conditioning", ["svd", "none"])
def test_recovers_affine_function_exactly(backend, conditioning):
    rng = np.random.default_rng(0)
    A = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 4.0]])
    b = np.array([0.7, -1.2])
    X = rng.uniform(-1, 1, size=(50, 3))
    memory = LLRMemory(
        3, 2, 100, 10, input_weights=[1, 0.5, 2], conditioning=conditioning, backend=backend
    ).fit(X, X @ A.T + b)
    for xq in rng.uniform(-1, 1, size=(5, 3)):
        pred, beta, idx = memory.query(xq)
        np.testing.assert_allclose(pred, A @ xq + b, atol=1e-10)
        np.testing.assert_allclose(beta, np.c_[A, b], atol=1e-10)
        assert len(idx) == 10


@pytest.mark.parametrize("backend", BACKENDS)
def test_minimum_norm_with_one_and_two_samples(backend):
    w = np.array([1.0, 0.1])
    xq = np.array([0.2, 3.0])
    for X, Y in (
        (np.array([[0.5, 1.0]]), np.array([[2.0]])),
        (np.array([[0.5, 1.0], [-0.1, 7.0]]), np.array([[2.0], [-1.0]])),
    ):
        memory = LLRMemory(2, 1, 10, 5, input_weights=w, conditioning="none", backend=backend).fit(
            X, Y
        )
        pred, beta, idx = memory.query(xq)
        assert len(idx) == len(X)
        # The minimum-norm solution of the under-determined fit in centred, weighted coordinates.
        A = np.c_[(X - xq) * w, np.ones(len(X))]
        g = np.linalg.lstsq(A, Y, rcond=None)[0]
        np.testing.assert_allclose(pred, g[-1], atol=1e-12)
        np.testing.assert_allclose(beta @ np.r_[xq, 1.0], pred, atol=1e-12)
        np.testing.assert_allclose(beta[0, :2], g[:2, 0] * w, atol=1e-12)
        # The fit passes through every sample (it is under-determined).
        np.testing.assert_allclose(beta @ np.c_[X, np.ones(len(X))].T, Y.T, atol=1e-10)


def test_empty_memory_predicts_zero_with_zero_beta():
    memory = LLRMemory(2, 3, 10, 4)
    pred, beta, idx = memory.query([1.0, 2.0])
    assert pred.shape == (3,) and beta.shape == (3, 3) and idx.shape == (0,)
    assert not pred.any() and not beta.any()


def _brute_force_neighbours(X, xq, w, period, k, norm):
    d = np.zeros(len(X))
    for i, x in enumerate(X):
        diff = x - xq
        for j, p in enumerate(period):
            if p > 0:
                diff[j] = (diff[j] + p / 2) % p - p / 2
        d[i] = np.sum(np.abs(w * diff)) if norm == 1 else np.sqrt(np.sum((w * diff) ** 2))
    return sorted(range(len(X)), key=lambda i: (d[i], i))[:k]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("norm", [1, 2])
def test_neighbours_match_brute_force_with_weights_and_periodic_input(backend, norm):
    rng = np.random.default_rng(1)
    w, period = np.array([1.0, 0.1]), np.array([TWO_PI, 0.0])
    X = np.c_[rng.uniform(-np.pi, np.pi, 300), rng.uniform(-20, 20, 300)]
    memory = LLRMemory(
        2, 1, 300, 15, input_weights=w, input_period=period, norm=norm, backend=backend
    ).fit(X, np.zeros((300, 1)))
    for xq in np.r_[[[np.pi - 0.01, 0.0], [-np.pi, 5.0]], rng.uniform(-3, 3, size=(20, 2))]:
        expected = _brute_force_neighbours(X, xq, w, period, 15, norm)
        np.testing.assert_array_equal(memory.neighbours(xq), expected)


@pytest.mark.parametrize("norm", [1, 2])
def test_compiled_search_orders_ties_like_a_stable_sort(norm):
    # Inputs on a coarse grid: many equal distances. The compiled search (bounded by lane minima
    # when unseeded, by the last list when seeded) must return what a stable argsort returns.
    from rmac_mj.approximators.llr import llr_nearest, search_numpy

    rng = np.random.default_rng(7)
    X = np.c_[rng.integers(-6, 6, 700) * 0.5, rng.integers(-10, 10, 700) * 2.0]
    memory = LLRMemory(
        2, 1, 700, 20, input_weights=[1.0, 0.25], input_period=[TWO_PI, 0.0], norm=norm
    ).fit(X, np.zeros((700, 1)))
    for xq in np.c_[rng.integers(-6, 6, 40) * 0.5, rng.integers(-10, 10, 40) * 2.0]:
        # (queries inside one period, so already wrapped, as llr_nearest wants them)
        expected = search_numpy(
            memory.X_, xq, np.array([1.0, 0.25]), np.array([TWO_PI, 0.0]), norm, 20
        )
        np.testing.assert_array_equal(memory.neighbours(xq), expected)
        idx, k = llr_nearest(memory.kernel_state, xq)  # seeded with the list searched before
        np.testing.assert_array_equal(idx[:k], expected)


def test_angles_near_plus_and_minus_pi_are_neighbours():
    X = np.array([[-np.pi + 0.01, 0.0], [0.5, 0.0], [np.pi - 0.3, 0.0]])
    memory = LLRMemory(2, 1, 10, 1, input_period=[TWO_PI, 0]).fit(X, np.zeros((3, 1)))
    assert memory.neighbours([np.pi - 0.01, 0.0])[0] == 0
    flat = LLRMemory(2, 1, 10, 1).fit(X, np.zeros((3, 1)))
    assert flat.neighbours([np.pi - 0.01, 0.0])[0] == 2


@pytest.mark.parametrize("backend", BACKENDS)
def test_periodic_fit_spans_the_seam(backend):
    # y = wrapped angle shifted by 0.1 (a next-state-like periodic output), queried at the seam.
    phis = np.linspace(np.pi - 0.2, np.pi + 0.2, 9)
    X = ((phis + np.pi) % TWO_PI - np.pi)[:, None]
    Y = ((phis + 0.1 + np.pi) % TWO_PI - np.pi)[:, None]
    memory = LLRMemory(
        1, 1, 20, 9, input_period=[TWO_PI], output_period=[TWO_PI], backend=backend
    ).fit(X, Y)
    pred, beta, _ = memory.query([np.pi - 0.05])
    assert abs(((pred[0] - (np.pi + 0.05)) + np.pi) % TWO_PI - np.pi) < 1e-10
    np.testing.assert_allclose(beta[0, 0], 1.0, atol=1e-10)


@pytest.mark.parametrize("backend", BACKENDS)
def test_truncated_svd_tames_nearly_collinear_neighbours(backend):
    # Neighbours along a trajectory: on a line in (phi, phi_dot) with tiny scatter across it.
    rng = np.random.default_rng(2)
    t = np.linspace(-0.5, 0.5, 20)
    X = np.c_[t, 10 * t] + rng.normal(0, 1e-4, size=(20, 2))
    Y = (-100 + 5 * t + rng.normal(0, 1.0, 20))[:, None]
    xq = np.array([0.0, 3.0])  # off the line
    kwargs = dict(input_weights=[1, 0.1], backend=backend)
    wild = LLRMemory(2, 1, 20, 20, conditioning="none", **kwargs).fit(X, Y).query(xq)[0][0]
    tame = LLRMemory(2, 1, 20, 20, conditioning="svd", rcond=0.01, **kwargs).fit(X, Y).query(xq)[0]
    ridge = LLRMemory(2, 1, 20, 20, conditioning="ridge", ridge=1e-3, **kwargs).fit(X, Y)
    assert abs(wild + 100) > 50  # the plain fit extrapolates along the noise direction
    assert Y.min() - 5 < tame[0] < Y.max() + 5
    assert Y.min() - 5 < ridge.query(xq)[0][0] < Y.max() + 5
    clipped = LLRMemory(2, 1, 20, 20, conditioning="none", clip=True, **kwargs).fit(X, Y)
    assert Y.min() <= clipped.query(xq)[0][0] <= Y.max()


@pytest.mark.parametrize("backend", BACKENDS)
def test_replace_oldest(backend):
    memory = LLRMemory(1, 1, 3, 1, replacement="oldest", backend=backend)
    for v in (0.0, 1.0, 2.0):
        memory.insert([v], [v])
    assert memory.insert([0.9], [9.0]) == 0  # slot of the first sample
    assert memory.insert([0.1], [9.0]) == 1
    np.testing.assert_array_equal(memory.X_[:, 0], [0.9, 0.1, 2.0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_replace_nearest(backend):
    memory = LLRMemory(2, 1, 3, 1, input_weights=[1, 0.01], replacement="nearest", backend=backend)
    for x in ([0.0, 0.0], [1.0, 0.0], [2.0, 0.0]):
        memory.insert(x, [0.0])
    assert memory.insert([1.1, 50.0], [7.0]) == 1  # nearest under the weighting
    assert memory.insert([2.2, 0.0], [7.0], nearest=0) == 0  # a given nearest slot is used
    np.testing.assert_array_equal(memory.X_, [[2.2, 0.0], [1.1, 50.0], [2.0, 0.0]])


@pytest.mark.parametrize("backend", BACKENDS)
def test_redundancy_by_distance_evicts_the_duplicate(backend):
    # K = 2, eta = 0.5, 1-norm; scores worked by hand: rho_i <- rho_i / 2 - d_i / 2 over K(x_*),
    # rho_* = mean_i rho_i / 2 - min d / 2. a 0 -> a 0; b 1 -> a -0.5, b -0.75;
    # c 3 -> b -1.375, a -1.75, c -1.78125; d 1 (b's duplicate) -> b -0.6875, a -1.375, d -0.515625.
    memory = LLRMemory(
        1,
        1,
        4,
        2,
        replacement="redundancy",
        redundancy="distance",
        redundancy_smoothing=0.5,
        backend=backend,
    )
    for v in (0.0, 1.0, 3.0, 1.0):
        memory.insert([v], [v])
    np.testing.assert_allclose(
        memory.redundancy_, [-1.375, -0.6875, -1.78125, -0.515625], atol=1e-12
    )
    # Full. 10 is nearest to c (which 'nearest' would replace) and 'oldest' would replace a; the
    # duplicate, at distance 0 from b when it came, is the most redundant (c -4.390625,
    # b -4.84375); the newcomer starts at -4.6171875 / 2 - 7 / 2.
    assert memory.insert([10.0], [0.0]) == 3
    np.testing.assert_allclose(
        memory.redundancy_, [-1.375, -4.84375, -4.390625, -5.80859375], atol=1e-12
    )
    np.testing.assert_array_equal(memory.X_[:, 0], [0.0, 1.0, 3.0, 10.0])


@pytest.mark.parametrize("backend", BACKENDS)
def test_redundancy_by_misfit_evicts_the_sample_on_the_line(backend):
    # y = 2 x plus noise (1, -1, 0, -1, 1) at x = -2..2: the noise is orthogonal to [x, 1], so the
    # affine fit of any of these sets is y = 2 x and the squared misfits are the noise squared; the
    # sample at x = 0 lies on the line and the local model predicts it exactly.
    X = np.arange(-2.0, 3.0)[:, None]
    Y = 2 * X + np.array([[1.0], [-1.0], [0.0], [-1.0], [1.0]])
    memory = LLRMemory(
        1,
        1,
        5,
        5,
        replacement="redundancy",
        redundancy="misfit",
        redundancy_smoothing=0.5,
        conditioning="none",
        backend=backend,
    )
    memory.fit(X, Y)  # each scored among the other four
    np.testing.assert_allclose(memory.redundancy_, [-1, -1, 0, -1, -1], atol=1e-12)
    # (3, 6) lies on the line too: the six-sample fit is still y = 2 x, so the neighbours keep
    # their scores. 'nearest' would replace x = 2 and 'oldest' x = -2; the sample on the line goes,
    # and the newcomer starts at the neighbours' mean -0.8 / 2 + its own -0 / 2.
    assert memory.insert([3.0], [6.0]) == 2
    np.testing.assert_allclose(memory.redundancy_, [-1, -1, -0.4, -1, -1], atol=1e-12)
    np.testing.assert_array_equal(memory.X_[:, 0], [-2.0, -1.0, 3.0, 1.0, 2.0])


def test_scores_are_kept_only_under_redundancy_replacement():
    memory = LLRMemory(1, 1, 3, 2)  # 'nearest'
    for v in (0.0, 1.0, 3.0, 1.0):
        memory.insert([v], [v])
    np.testing.assert_array_equal(memory.redundancy_, 0.0)


@pytest.mark.slow
def test_back_ends_agree_on_a_random_history():
    rng = np.random.default_rng(3)
    kwargs = dict(
        input_dim=3,
        output_dim=2,
        capacity=60,
        n_neighbours=9,
        input_weights=[1, 0.1, 1],
        input_period=[TWO_PI, 0, 0],
        output_period=[TWO_PI, 0],
        clip=True,
    )
    for replacement, measure in (
        ("nearest", "distance"),
        ("oldest", "distance"),
        ("redundancy", "distance"),
        ("redundancy", "misfit"),
    ):
        fast = LLRMemory(**kwargs, replacement=replacement, redundancy=measure, backend="numba")
        slow = LLRMemory(**kwargs, replacement=replacement, redundancy=measure, backend="numpy")
        for _ in range(200):
            x = np.r_[rng.uniform(-4, 4), rng.normal(0, 10), rng.uniform(-3, 3)]
            y = np.r_[rng.uniform(-np.pi, np.pi), rng.normal()]
            a, b = fast.query(x), slow.query(x)
            np.testing.assert_array_equal(a[2], b[2])
            np.testing.assert_allclose(a[0], b[0], atol=1e-9)
            np.testing.assert_allclose(a[1], b[1], atol=1e-8)
            assert fast.insert(x, y) == slow.insert(x, y)
            if len(a[2]):
                fast.adjust(a[2], 0.1)
                slow.adjust(b[2], 0.1)
        np.testing.assert_array_equal(fast.X_, slow.X_)
        np.testing.assert_allclose(fast.redundancy_, slow.redundancy_, rtol=1e-9, atol=1e-9)
        assert (replacement != "redundancy") == np.all(fast.redundancy_ == 0)


@pytest.mark.parametrize("backend", BACKENDS)
def test_move_outputs_takes_the_short_way_round_and_wraps(backend):
    memory = LLRMemory(1, 2, 5, 1, output_period=[TWO_PI, 0.0], backend=backend)
    for y in ([np.pi - 0.1, 1.0], [0.0, 2.0], [1.0, 3.0]):
        memory.insert([0.0], y)
    memory.move_outputs([0, 1], [-np.pi + 0.1, 5.0], 0.75)
    # Sample 0: 0.2 across the seam, three quarters of the way: pi - 0.1 + 0.15, wrapped.
    np.testing.assert_allclose(memory.Y_[0], [-np.pi + 0.05, 1.0 + 0.75 * 4.0], atol=1e-12)
    np.testing.assert_allclose(memory.Y_[1], [0.75 * (-np.pi + 0.1), 2.0 + 0.75 * 3.0], atol=1e-12)
    np.testing.assert_array_equal(memory.Y_[2], [1.0, 3.0])  # not moved
    with pytest.raises(ValueError, match="indices"):
        memory.move_outputs([3], [0.0, 0.0], 0.5)  # only 3 samples stored


@pytest.mark.parametrize("backend", BACKENDS)
def test_add_weighted_adds_delta_times_weight_to_stored_samples(backend):
    memory = LLRMemory(1, 1, 4, 1, backend=backend)
    for v in (1.0, 2.0, 3.0):
        memory.insert([v], [v])
    traces = np.array([1.0, 0.5, 0.0, 7.0])  # the 4th slot holds no sample: ignored
    memory.add_weighted(traces, [-2.0])
    np.testing.assert_array_equal(memory.Y_[:, 0], [-1.0, 1.0, 3.0, 0.0])
    memory.add_weighted(traces[:3], [1.0])
    np.testing.assert_array_equal(memory.outputs([0, 1, 2])[:, 0], [0.0, 1.5, 3.0])
    with pytest.raises(ValueError, match="weights"):
        memory.add_weighted(np.ones(2), [1.0])


def test_kernel_state_is_the_memory_itself():
    from rmac_mj.approximators.llr import llr_insert, llr_query

    memory = LLRMemory(2, 1, 10, 3, input_period=[TWO_PI, 0.0])
    slot = llr_insert(memory.kernel_state, np.array([4.0, 1.0]), np.array([5.0]), -1)
    assert slot == 0 and memory.n_samples_ == 1
    np.testing.assert_allclose(memory.X_[0], [4.0 - TWO_PI, 1.0])  # stored wrapped
    idx, beta, pred = np.empty(3, np.int64), np.empty((1, 3)), np.empty(1)
    assert llr_query(memory.kernel_state, np.array([4.0, 1.0]), idx, beta, pred) == 1
    assert pred[0] == 5.0 and idx[0] == 0
    memory.Y_[0] = -1.0  # Python's writes are seen by compiled code
    llr_query(memory.kernel_state, np.array([4.0, 1.0]), idx, beta, pred)
    assert pred[0] == -1.0


@pytest.mark.parametrize("replacement", ["nearest", "oldest", "redundancy"])
@pytest.mark.parametrize("norm", [1, 2])
def test_kept_neighbour_lists_stay_exact_across_insertions(replacement, norm):
    # What lets RMAC search a point once where Algorithm 2 asks for its neighbours before and after
    # insertions: a kept list, carried across every insertion since its search (the replaced sample
    # leaves, the new one is placed by its distance), is what a new search finds, ties and replaced
    # neighbours included. Inputs on a coarse grid make many distances equal; the queries come
    # back to the last few points after one to four insertions, as a learner's states do.
    from rmac_mj.approximators.llr import llr_insert, llr_nearest, search_numpy

    rng = np.random.default_rng(5)
    K = 4
    weights, period = np.array([1.0, 0.5]), np.array([TWO_PI, 0.0])
    memory = LLRMemory(
        2, 1, 25, K, input_weights=weights, input_period=period, norm=norm, replacement=replacement
    )
    state = memory.kernel_state
    points, replaced_a_neighbour = [], 0
    for step in range(600):
        if points and rng.random() < 0.6:  # back to a recent point
            xq = points[-int(rng.integers(1, min(len(points), 4) + 1))]
        else:
            xq = np.r_[rng.integers(-6, 6) * 0.5, rng.integers(-4, 4) * 0.5]
            points.append(xq)
        idx, k = llr_nearest(state, xq)
        before = idx[:k].copy()
        np.testing.assert_array_equal(
            before, search_numpy(memory.X_[: memory.n_samples_], xq, weights, period, norm, K)
        )
        if rng.random() < 0.7:
            x_new = xq + np.r_[rng.integers(-2, 3), rng.integers(-2, 3)] * 0.5
            slot = llr_insert(state, x_new, np.zeros(1), before[0] if step % 2 and k else -1)
            replaced_a_neighbour += slot in before
    assert memory.n_samples_ == 25 and replaced_a_neighbour > (
        5 if replacement == "redundancy" else 20
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_insert_after_a_query_at_the_same_point_replaces_the_same_sample(backend):
    # insert() may take the nearest sample from a query just made at the same point; it must be
    # the sample a search would find, and a change in between must not go unnoticed.
    rng = np.random.default_rng(6)
    kwargs = dict(input_weights=[1.0, 0.1], input_period=[TWO_PI, 0.0], backend=backend)
    a, b = LLRMemory(2, 1, 40, 5, **kwargs), LLRMemory(2, 1, 40, 5, **kwargs)
    for _ in range(300):
        x = np.r_[rng.uniform(-4, 4), rng.normal(0, 5)]
        a.query(x)
        if rng.random() < 0.3:  # the memory changes between the query and the insertion,
            other = x + rng.normal(0, 1e-3, 2)  # and its new nearest sample is this one
            assert a.insert(other, [1.0]) == b.insert(other, [1.0])
            other = np.r_[rng.uniform(-4, 4), rng.normal(0, 5)]
            assert a.insert(other, [1.0]) == b.insert(other, [1.0])
        assert a.insert(x, [0.0]) == b.insert(x, [0.0])
    np.testing.assert_array_equal(a.X_, b.X_)


def test_initialise_from_samples_and_state_dict_round_trip():
    rng = np.random.default_rng(4)
    X, Y = rng.normal(size=(30, 2)), rng.normal(size=(30, 1))
    memory = LLRMemory(2, 1, 50, 5).fit(X, Y)
    assert memory.n_samples_ == 30
    copy = LLRMemory(2, 1, 50, 5)
    copy.load_state_dict(memory.state_dict(prefix="c."), prefix="c.")
    for xq in rng.normal(size=(5, 2)):
        np.testing.assert_array_equal(memory.query(xq)[0], copy.query(xq)[0])
    for measure in ("distance", "misfit"):  # the redundancy scores are state too
        kwargs = dict(replacement="redundancy", redundancy=measure)
        memory = LLRMemory(2, 1, 25, 5, **kwargs).fit(X[:20], Y[:20])
        for x, y in zip(X[20:], Y[20:]):
            memory.insert(x, y)
        assert memory.n_samples_ == 25 and np.all(memory.redundancy_ < 0)
        copy = LLRMemory(2, 1, 25, 5, **kwargs)
        copy.load_state_dict(memory.state_dict())
        np.testing.assert_array_equal(copy.redundancy_, memory.redundancy_)
        assert copy.insert(X[0] + 0.1, [0.0]) == memory.insert(X[0] + 0.1, [0.0])
        np.testing.assert_array_equal(copy.redundancy_, memory.redundancy_)
    np.testing.assert_allclose(memory.predict(X[:3]), np.array([memory.query(x)[0] for x in X[:3]]))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(capacity=0), "capacity"),
        (dict(n_neighbours=0), "n_neighbours"),
        (dict(capacity=5, n_neighbours=6), "n_neighbours"),
        (dict(input_weights=[1.0]), "input_weights"),
        (dict(input_weights=[1.0, -0.1]), "input_weights"),
        (dict(norm=3), "norm"),
        (dict(conditioning="qr"), "conditioning"),
        (dict(rcond=1.5), "rcond"),
        (dict(replacement="random"), "replacement"),
        (dict(backend="kd_tree"), "backend"),
        (dict(redundancy="age"), "redundancy"),
        (dict(redundancy_smoothing=0.0), "redundancy_smoothing"),
        (dict(redundancy_smoothing=1.5), "redundancy_smoothing"),
        (dict(input_period=[1.0]), "input_period"),
    ],
)
def test_bad_configuration_names_the_parameter(kwargs, name):
    args = dict(input_dim=2, output_dim=1, capacity=10, n_neighbours=3)
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        LLRMemory(**args)


def test_non_finite_input_is_rejected():
    memory = LLRMemory(2, 1, 10, 3)
    with pytest.raises(ValueError, match="x"):
        memory.query([np.nan, 0.0])
    with pytest.raises(ValueError, match="y"):
        memory.insert([0.0, 0.0], [np.inf])
    with pytest.raises(ValueError, match="shape"):
        memory.insert([0.0], [1.0])
