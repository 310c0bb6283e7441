"""The one length-Jacobian kernel (clamps, learning rows): dense and sparse forms agree, and
both are the derivative of the spring lengths (central differences)."""

import numpy as np

from continuum_vs_network.network.length_jacobian import dense_jacobian_pays, length_jacobian


def _lengths(x, pairs):
    d = x[pairs[:, 1]] - x[pairs[:, 0]]
    return np.hypot(d[:, 0], d[:, 1])


def test_dense_and_sparse_length_jacobians_are_the_derivative_of_the_lengths():
    rng = np.random.default_rng(4)
    n_nodes = 7
    x = rng.random((n_nodes, 2)) * 2
    pairs = np.array([[0, 1], [1, 2], [3, 2], [4, 6], [5, 0]])
    free = np.ones(2 * n_nodes, dtype=bool)
    free[[2, 3, 9]] = False  # node 1 pinned, node 4's y pinned
    column = np.full(2 * n_nodes, -1)
    column[np.flatnonzero(free)] = rng.permutation(int(free.sum()))
    n = int(free.sum())
    dense = length_jacobian(x, pairs, column, n, dense=True)
    sparse = length_jacobian(x, pairs, column, n, dense=False)
    np.testing.assert_array_equal(sparse.toarray(), dense)
    h = 1e-6
    for flat in np.flatnonzero(free):
        e = np.zeros(2 * n_nodes)
        e[flat] = h
        step = e.reshape(n_nodes, 2)
        slope = (_lengths(x + step, pairs) - _lengths(x - step, pairs)) / (2 * h)
        np.testing.assert_allclose(dense[:, column[flat]], slope, atol=1e-8)


def test_dense_jacobians_only_while_small():
    assert dense_jacobian_pays(13, 2045)  # a learning task's clamps at 1e3 nodes
    assert dense_jacobian_pays(1000, 400)  # a dense-size problem
    assert not dense_jacobian_pays(13, 2_000_000)  # 1e6 nodes: 200 MB dense
