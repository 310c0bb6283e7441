"""The trust region's dense small-network kernels against the sparse ones, and its
Cholesky certificate against the eigenvalues (network/trust_kernels.py, network/trust.py)."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.network.builders import paper_network
from continuum_vs_network.network.constraints import Problem, clamp_tensions
from continuum_vs_network.network.lagrangian import Frame
from continuum_vs_network.network.trust import _CURVATURE, _positive_factor, null_basis
from continuum_vs_network.network.trust_kernels import DenseKernels, SparseKernels


@pytest.mark.parametrize("mode", ["none", "exact", "rod", "pinned"])
def test_dense_kernels_agree_with_sparse_ones(mode):
    """Gradient, scaled Lagrangian Hessian, reduced bending force and energy change by
    dense incidence products equal the gather/scatter kernels' to round-off."""
    rng = np.random.default_rng(3)
    net = paper_network(rng)
    clamped = None if mode in ("none", "pinned") else {4: 7.0, 11: 3.0}
    pinned = [0, 5] if mode == "pinned" else None
    clamp = "rod" if mode == "rod" else "exact"
    problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp=clamp)
    if mode != "pinned":
        problem = problem.with_free(np.ones_like(problem.free))
    frame = Frame(net, problem.free)
    inv_root = rng.uniform(0.1, 1.0, frame.n)
    x = net.positions + rng.normal(scale=0.5, size=net.positions.shape)
    y = x + rng.normal(scale=0.3, size=x.shape) * problem.free
    dense, sparse = DenseKernels(problem, frame, inv_root), SparseKernels(problem, frame, inv_root)
    g = sparse.gradient(x)
    np.testing.assert_allclose(dense.gradient(x), g, rtol=1e-12, atol=1e-12 * np.abs(g).max())
    mu = np.empty(0)
    if problem.exact:
        A = problem.clamp_jacobian(x, frame.coords, dense=True)
        mu = clamp_tensions(A, g, problem.scale[frame.coords])
        assert np.abs(mu).max() > 0  # the multiplier terms are exercised
    W = sparse.hessian(mu)
    np.testing.assert_allclose(dense.hessian(mu), W, atol=1e-12 * np.abs(W).max())
    basis = null_basis(rng.normal(size=(3, frame.n))) * inv_root[:, None]
    dense.set_basis(basis)
    sparse.set_basis(basis)
    p = rng.normal(size=basis.shape[1])
    b = sparse.reduced_bending(p, basis @ p)
    np.testing.assert_allclose(dense.reduced_bending(p, basis @ p), b, atol=1e-12 * np.abs(b).max())
    change = sparse.energy_change(y)
    assert dense.energy_change(y) == pytest.approx(change, rel=1e-12)


@pytest.mark.parametrize("lowest", [-1e-3, 0.5e-8, 2e-8, 0.3])
def test_cholesky_certificate_matches_the_lowest_eigenvalue(lowest):
    """The Cholesky factor certifies exactly the matrices whose lowest eigenvalue exceeds
    1e-8 (a saddle or a nearly singular minimum is not certified), and its Newton step
    solves H p = -g."""
    rng = np.random.default_rng(1)
    vecs = np.linalg.qr(rng.normal(size=(9, 9)))[0]
    vals = np.concatenate([[lowest], rng.uniform(0.5, 3.0, 8)])
    H = vecs @ np.diag(vals) @ vecs.T
    H = 0.5 * (H + H.T)
    g = rng.normal(size=9)
    factor, step, length = _positive_factor(H, g)
    assert (factor is not None) == (lowest > _CURVATURE)
    if factor is not None:
        np.testing.assert_allclose(H @ step, -g, atol=1e-9 * np.abs(g).max() / lowest)
        assert length == pytest.approx(np.linalg.norm(step))
