"""The projection of stiff springs back onto their linearly predicted lengths
(``StiffSprings.restore``): it meets reachable lengths to round-off and gives up at once on
lengths no placement of the nodes can have."""

import numpy as np

from continuum_vs_network.network.stiff_springs import StiffSprings


def _springs(springs, n_nodes):
    index = np.arange(2 * n_nodes)  # every coordinate free, natural order
    return StiffSprings(np.asarray(springs), index, 2 * n_nodes)


def _lengths(x, springs):
    d = x[springs[:, 1]] - x[springs[:, 0]]
    return np.hypot(d[:, 0], d[:, 1])


def test_a_triangle_turned_by_a_linear_step_gets_its_predicted_lengths_back():
    springs = np.array([[0, 1], [1, 2], [2, 0]])
    x = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.8]])
    # a rotation by 0.4 rad taken linearly: it stretches every side to second order
    turn = 0.4 * np.array([[0.0, -1.0], [1.0, 0.0]])
    dx = (x @ turn.T).ravel()
    y = x + dx.reshape(x.shape)
    stiff = _springs(springs, 3)
    z = stiff.restore(y, x, dx)
    assert z is not None
    u0, r0 = stiff.geometry(x)
    target = r0 + stiff.lengthening(u0, dx)  # the lengths the linear model predicts: r0
    np.testing.assert_allclose(_lengths(z, springs), target, rtol=0, atol=1e-13)
    assert np.max(np.abs(_lengths(y, springs) - target)) > 1e-2  # the step had stretched them


def test_lengths_no_placement_can_have_are_refused_quickly():
    # a braced square: 6 lengths on 4 nodes (5 shape coordinates), so the second-order
    # lengths of a large linear step are in general not reachable
    springs = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]])
    x = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    rng = np.random.default_rng(3)
    dx = 0.3 * rng.standard_normal(8)
    stiff = _springs(springs, 4)
    calls = []
    geometry = stiff.geometry
    stiff.geometry = lambda z: calls.append(1) or geometry(z)
    assert stiff.restore(x + dx.reshape(4, 2), x, dx) is None
    assert len(calls) <= 5  # it stops once Gauss-Newton stalls, not after 12 iterations


def _dense_jacobian(x, springs, index, n):
    """J (s, n) written out entry by entry: row s has -u and u on its end nodes' free
    coordinates (``index`` -1 where pinned)."""
    J = np.zeros((len(springs), n))
    for row, (a, b) in enumerate(springs):
        d = x[b] - x[a]
        u = d / np.hypot(*d)
        for node, sign in ((a, -1.0), (b, 1.0)):
            for c in range(2):
                col = index[2 * node + c]
                if col >= 0:
                    J[row, col] += sign * u[c]
    return J


def test_the_array_jacobian_and_gram_matrix_equal_the_written_out_ones():
    rng = np.random.default_rng(7)
    n_nodes = 9
    x = rng.random((n_nodes, 2)) * 3
    springs = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [0, 4], [1, 5], [5, 6], [6, 2],
                        [7, 8], [8, 0], [7, 3], [5, 8]])  # fmt: skip
    free = np.ones(2 * n_nodes, dtype=bool)
    free[[0, 1, 15]] = False  # node 0 pinned, node 7's y pinned
    index = np.full(2 * n_nodes, -1)
    rows = rng.permutation(int(free.sum()))  # a move vector's rows in any order
    index[np.flatnonzero(free)] = rows
    n = int(free.sum())
    stiff = StiffSprings(springs, index, n)
    J = _dense_jacobian(x, springs, index, n)
    u, r = stiff.geometry(x)
    np.testing.assert_allclose(r, _lengths(x, springs), rtol=1e-15)
    v, w = rng.standard_normal(n), rng.standard_normal(len(springs))
    np.testing.assert_allclose(stiff.lengthening(u, v), J @ v, rtol=0, atol=1e-14)
    np.testing.assert_allclose(stiff.spread(u, w), J.T @ w, rtol=0, atol=1e-14)
    gram = stiff._gram.matrix(u).toarray()
    np.testing.assert_allclose(gram, J @ J.T + 1e-12 * np.eye(len(springs)), rtol=0, atol=1e-14)


def test_threads_relaxing_one_stiff_network_get_the_serial_answers():
    """The projection's ``J J^T`` buffer is kept with the network: threads that relax one
    network at once must not fill each other's values (with a fine switch interval a shared
    buffer gave wrong positions in 55 of 72 runs)."""
    import sys
    from concurrent.futures import ThreadPoolExecutor

    import continuum_vs_network as cvn
    from continuum_vs_network.network.builders import triangular_lattice

    rng = np.random.default_rng(0)
    net = triangular_lattice(10, 10, noise=0.1, rng=rng)
    net = net.with_stiffness(10 ** rng.uniform(-3, 6, net.n_springs))
    mid = net.positions[net.springs].mean(axis=1)
    c = int(np.argmin(np.linalg.norm(mid - net.positions.mean(0), axis=1)))
    clamps = [{c: float(net.lengths()[c] * s)} for s in (0.7, 0.8, 1.2, 1.3)]
    serial = [cvn.relax(net, clamped=q).positions for q in clamps]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        with ThreadPoolExecutor(4) as pool:
            threaded = list(pool.map(lambda q: cvn.relax(net, clamped=q).positions, clamps * 3))
    finally:
        sys.setswitchinterval(interval)
    for i, x in enumerate(threaded):
        np.testing.assert_array_equal(x, serial[i % 4])
