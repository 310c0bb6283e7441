"""The trust region's dense small-network kernels against the sparse ones, and its
Cholesky certificate against the eigenvalues (network/trust_kernels.py,
network/trust_model.py)."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.network.builders import paper_network
from continuum_vs_network.network.constraints import Problem, clamp_tensions
from continuum_vs_network.network.lagrangian import Frame
from continuum_vs_network.network.trust_kernels import DenseKernels, SparseKernels
from continuum_vs_network.network.trust_model import CURVATURE, Model, null_basis


@pytest.mark.parametrize("mode", ["none", "exact", "rod", "pinned"])
def test_dense_kernels_agree_with_sparse_ones(mode):
    """Gradient, reduced scaled Lagrangian Hessian (from the length and rotation
    Jacobians), reduced bending force and energy change by dense
    incidence products equal the gather/scatter kernels' to round-off."""
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
    W = sparse.reduced_hessian(mu, None)
    np.testing.assert_allclose(dense.reduced_hessian(mu, None), W, atol=1e-12 * np.abs(W).max())
    p = rng.normal(size=frame.n)
    b = sparse.reduced_bending(p, p * inv_root)
    np.testing.assert_allclose(
        dense.reduced_bending(p, p * inv_root), b, atol=1e-12 * np.abs(b).max()
    )
    basis = null_basis(rng.normal(size=(3, frame.n))) * inv_root[:, None]
    H = sparse.reduced_hessian(mu, basis)
    np.testing.assert_allclose(dense.reduced_hessian(mu, basis), H, atol=1e-12 * np.abs(H).max())
    p = rng.normal(size=basis.shape[1])
    b = sparse.reduced_bending(p, basis @ p)
    np.testing.assert_allclose(dense.reduced_bending(p, basis @ p), b, atol=1e-12 * np.abs(b).max())
    change = sparse.energy_change(y)
    assert dense.energy_change(y) == pytest.approx(change, rel=1e-12)


@pytest.mark.parametrize("lowest", [-1e-3, 0.5e-8, 2e-8, 0.3])
def test_cholesky_certificate_matches_the_lowest_eigenvalue(lowest):
    """A model certifies exactly the Hessians whose lowest eigenvalue exceeds 1e-8 (a
    saddle or a nearly singular minimum is not), before and after its spectrum is known;
    its Cholesky factor exists exactly for positive-definite ones, and its Newton step
    solves H p = -g."""
    rng = np.random.default_rng(1)
    vecs = np.linalg.qr(rng.normal(size=(9, 9)))[0]
    vals = np.concatenate([[lowest], rng.uniform(0.5, 3.0, 8)])
    H = vecs @ np.diag(vals) @ vecs.T
    H = 0.5 * (H + H.T)
    g = rng.normal(size=9)
    model = Model(np.zeros((5, 2)), H, g, None, np.ones(9), None)
    assert model.certified == (lowest > CURVATURE)
    assert (model.factor is not None) == (lowest > 0)
    if model.factor is not None:
        step = model.newton
        np.testing.assert_allclose(H @ step, -g, atol=1e-9 * np.abs(g).max() / lowest)
        assert model.newton_length == pytest.approx(np.linalg.norm(step))
    fresh = Model(np.zeros((5, 2)), H, g, None, np.ones(9), None)
    fresh.eigen()
    assert fresh.certified == (lowest > CURVATURE)


def test_model_newton_step_is_the_same_from_its_eigenvalues():
    """The Newton step of a certified model by Cholesky and from its spectrum (the one the
    subproblem returns when it fits) lift to the same move."""
    rng = np.random.default_rng(5)
    net = paper_network(rng)
    problem = Problem.build(net, pinned=[0, 5])
    frame = Frame(net, problem.free)
    inv_root = rng.uniform(0.1, 1.0, frame.n)
    terms = DenseKernels(problem, frame, inv_root)
    x = net.positions + rng.normal(scale=0.3, size=net.positions.shape)
    g = terms.gradient(x)
    basis = null_basis(rng.normal(size=(2, frame.n))) * inv_root[:, None]
    H = terms.reduced_hessian(np.empty(0), basis)
    H = H + (1.0 - np.linalg.eigvalsh(H)[0]) * np.eye(H.shape[0])  # positive definite
    model = Model(x, H, basis.T @ g, basis, inv_root, terms)
    assert model.certified
    move = model.lift(model.newton)
    spectrum = model.eigen()
    assert model.certified and spectrum.lowest == pytest.approx(1.0)
    eigen_move = model.lift(model.vecs @ spectrum.newton)
    np.testing.assert_allclose(eigen_move, move, atol=1e-10 * np.abs(move).max())
    assert spectrum.newton_length == pytest.approx(model.newton_length, rel=1e-10)


def test_dense_reduced_hessian_of_a_collapsed_spring_matches_the_sparse_one():
    """A spring at zero length has no direction: its block is ``t I`` (the sparse
    kernels' Lagrangian blocks), which the length/rotation form cannot express; the dense
    kernels must give the same reduced Hessian there."""
    rng = np.random.default_rng(7)
    net = paper_network(rng)
    problem = Problem.build(net).with_free(np.ones((net.n_nodes, 2), dtype=bool))
    frame = Frame(net, problem.free)
    inv_root = rng.uniform(0.1, 1.0, frame.n)
    x = net.positions.copy()
    a, b = net.springs[0]
    x[b] = x[a]  # spring 0 collapsed
    dense, sparse = DenseKernels(problem, frame, inv_root), SparseKernels(problem, frame, inv_root)
    dense.gradient(x)
    sparse.gradient(x)
    basis = null_basis(rng.normal(size=(3, frame.n))) * inv_root[:, None]
    H = sparse.reduced_hessian(np.empty(0), basis)
    assert np.abs(H).max() > 1e100  # the collapsed spring's tangential term dominates
    np.testing.assert_allclose(dense.reduced_hessian(np.empty(0), basis), H, rtol=1e-12)
