"""Energy, gradient and sparse Hessian against finite differences and torch autograd."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.energy import HessianPattern, spring_bending, spring_gradient


def _random_network(rng, n=12):
    x = rng.uniform(0, 3, size=(n, 2))
    pairs = {(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < 0.4}
    springs = np.array(sorted(pairs))
    r = np.linalg.norm(x[springs[:, 1]] - x[springs[:, 0]], axis=1)
    return cvn.SpringNetwork(
        x, springs, rng.uniform(0.1, 5, len(springs)), r * rng.uniform(0.5, 1.5, len(springs))
    )


def test_energy_closed_form_single_spring():
    net = cvn.SpringNetwork([[0, 0], [3, 4]], [[0, 1]], [2.0], [4.0])
    assert cvn.energy(net.positions, net) == pytest.approx(0.5 * 2.0 * (5.0 - 4.0) ** 2)
    # Hooke (Eq. 9): a stretched spring pulls node 1 back toward node 0 with |F| = k (r - L)
    np.testing.assert_allclose(cvn.forces(net.positions, net)[1], -2.0 * 1.0 * np.array([3, 4]) / 5)


def test_gradient_matches_central_differences():
    rng = np.random.default_rng(1)
    net = _random_network(rng)
    x = net.positions + 0.1 * rng.standard_normal(net.positions.shape)
    g = cvn.gradient(x, net)
    h = 1e-6
    fd = np.zeros_like(x)
    for idx in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[idx] += h
        xm[idx] -= h
        fd[idx] = (cvn.energy(xp, net) - cvn.energy(xm, net)) / (2 * h)
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6 * np.abs(g).max())


def test_hessian_matches_differences_of_gradient_and_is_symmetric():
    rng = np.random.default_rng(2)
    net = _random_network(rng)
    x = net.positions + 0.1 * rng.standard_normal(net.positions.shape)
    H = cvn.hessian(x, net).toarray()
    np.testing.assert_allclose(H, H.T, atol=1e-12)
    h = 1e-6
    fd = np.zeros_like(H)
    for col in range(x.size):
        xp, xm = x.copy().ravel(), x.copy().ravel()
        xp[col] += h
        xm[col] -= h
        fd[:, col] = (
            cvn.gradient(xp.reshape(x.shape), net) - cvn.gradient(xm.reshape(x.shape), net)
        ).ravel() / (2 * h)
    np.testing.assert_allclose(H, fd, rtol=1e-5, atol=1e-5 * np.abs(H).max())


def test_hessian_and_gradient_match_torch_autograd():
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(3)
    net = _random_network(rng, n=9)
    x = net.positions + 0.1 * rng.standard_normal(net.positions.shape)
    s = torch.tensor(net.springs)
    k = torch.tensor(net.stiffness)
    L = torch.tensor(net.rest_length)

    def energy(flat):
        p = flat.reshape(-1, 2)
        r = torch.linalg.norm(p[s[:, 1]] - p[s[:, 0]], dim=1)
        return 0.5 * torch.sum(k * (r - L) ** 2)

    xt = torch.tensor(x.ravel(), dtype=torch.float64, requires_grad=True)
    g_t = torch.autograd.grad(energy(xt), xt)[0].numpy()
    H_t = torch.autograd.functional.hessian(energy, xt).numpy()
    np.testing.assert_allclose(cvn.gradient(x, net).ravel(), g_t, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(cvn.hessian(x, net).toarray(), H_t, rtol=1e-10, atol=1e-10)


def test_pattern_restricted_to_free_coordinates_equals_slice():
    rng = np.random.default_rng(4)
    net = _random_network(rng)
    free = rng.random((net.n_nodes, 2)) > 0.3
    pattern = HessianPattern(net.springs, net.n_nodes, free)
    H_free = cvn.hessian(net.positions, net, pattern).toarray()
    keep = np.flatnonzero(free.ravel())
    H_full = cvn.hessian(net.positions, net).toarray()
    np.testing.assert_allclose(H_free, H_full[np.ix_(keep, keep)], atol=1e-13)


def test_gradient_follows_a_changed_springs_array_behind_a_read_only_view():
    """The cached scatter indices are only kept for arrays that own their data: a read-only
    view of an array that is later changed must give the changed network's gradient."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=(5, 2))
    base = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])
    view = base[:]
    view.setflags(write=False)
    k, L = np.ones(4), np.full(4, 0.5)
    first = spring_gradient(x, view, k, L)
    base[:] = [[0, 2], [2, 4], [4, 1], [1, 3]]
    fresh = base.copy()
    fresh.setflags(write=False)
    changed = spring_gradient(x, view, k, L)
    assert np.array_equal(changed, spring_gradient(x, fresh, k, L))
    assert not np.allclose(changed, first)


def test_spring_bending_is_the_force_of_the_lengths_second_derivative_along_a_step():
    """``spring_bending`` is ``J^T (k r'')``: each spring's second derivative of length along
    the step (central differences of the lengths), times k, along the spring."""
    rng = np.random.default_rng(3)
    net = _random_network(rng)
    x = net.positions
    step = rng.standard_normal(x.shape)
    h = 1e-4
    r = [net.lengths(x + t * step) for t in (-h, 0.0, h)]
    second = (r[0] - 2 * r[1] + r[2]) / h**2  # (s,)
    d = x[net.springs[:, 1]] - x[net.springs[:, 0]]
    t = (net.stiffness * second / r[1])[:, None] * d
    expected = np.zeros_like(x)
    np.add.at(expected, net.springs[:, 1], t)
    np.add.at(expected, net.springs[:, 0], -t)
    got = spring_bending(x, step, net.springs, net.stiffness)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-6 * np.abs(expected).max())
