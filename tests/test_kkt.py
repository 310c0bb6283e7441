"""The KKT module: solutions satisfy both block equations; inertia matches eigenvalues."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.typing import NDArray

import continuum_vs_network as cvn
from continuum_vs_network.linalg import kkt as kkt_module
from continuum_vs_network.linalg import spd as spd_module
from continuum_vs_network.linalg.kkt import (
    Factor,
    Inertia,
    factor_kkt,
    factor_spd,
    factor_spd_or_curvature,
    schur_solve,
    sparse_backend,
)


def _laplacian_2d(side: int) -> sp.csr_matrix:
    """SPD 5-point Laplacian on a side x side grid (Dirichlet), n = side^2."""
    t = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(side, side))
    eye = sp.identity(side)
    return (sp.kron(t, eye) + sp.kron(eye, t)).tocsr()


def _dense_inertia(W, A) -> Inertia:
    n, m = W.shape[0], A.shape[0]
    K = np.zeros((n + m, n + m))
    K[:n, :n] = W.toarray() if sp.issparse(W) else W
    K[n:, :n] = A.toarray() if sp.issparse(A) else A
    K[:n, n:] = K[n:, :n].T
    ev = np.linalg.eigvalsh(K)
    tiny = 1e-10 * np.abs(ev).max()
    return Inertia(int((ev > tiny).sum()), int((ev < -tiny).sum()), int((abs(ev) <= tiny).sum()))


def _check_solution(kkt, W, A, rng):
    n, m = W.shape[0], A.shape[0]
    b, c = rng.standard_normal(n), rng.standard_normal(m)
    x, y = kkt.solve(b, c)
    scale = np.abs(b).max() + np.abs(c).max()
    np.testing.assert_allclose(W @ x + A.T @ y, b, atol=1e-9 * scale * max(1, abs(y).max()))
    np.testing.assert_allclose(A @ x, c, atol=1e-9 * scale * max(1, abs(x).max()))
    # several right-hand sides at once give the same columns
    B = rng.standard_normal((n, 3))
    X, _ = kkt.solve(B, np.zeros((m, 3)))
    np.testing.assert_allclose(X[:, 1], kkt.solve(B[:, 1])[0], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("side", [6, 24])  # dense (36) and sparse (576) paths
@pytest.mark.parametrize("sparse_a", [False, True])
def test_positive_definite_w_range_space(side, sparse_a):
    rng = np.random.default_rng(side)
    W = _laplacian_2d(side)
    A = rng.standard_normal((3, W.shape[0]))
    A = sp.csr_matrix(A) if sparse_a else A
    kkt = factor_kkt(W, A)
    assert kkt.range_space and kkt.inertia == Inertia(W.shape[0], 3, 0) and kkt.is_minimum
    _check_solution(kkt, W, A, rng)


@pytest.mark.parametrize("side", [5, 22])
def test_indefinite_w_with_positive_reduced_hessian_is_a_minimum(side):
    """W has one negative eigenvalue along e_0; a constraint x_0 = 0 removes it."""
    rng = np.random.default_rng(1)
    W = _laplacian_2d(side).tolil()
    W[0, 0] = -5.0
    W = W.tocsr()
    n = W.shape[0]
    assert factor_spd(W) is None
    A = sp.csr_matrix(([1.0], ([0], [0])), shape=(1, n))
    kkt = factor_kkt(W, A)
    assert not kkt.range_space
    if kkt.inertia is not None:  # the sparse path may not reveal it
        assert kkt.inertia == _dense_inertia(W, A) == Inertia(n, 1, 0)
    _check_solution(kkt, W, A, rng)


def test_saddle_is_reported_by_the_inertia():
    rng = np.random.default_rng(2)
    W = np.diag([1.0, -2.0, 3.0, 4.0])
    A = np.array([[1.0, 0.0, 0.0, 1.0]])  # leaves the negative direction e_1 free
    kkt = factor_kkt(W, A)
    # a minimum would be (4, 1, 0); the free negative direction adds one negative
    assert kkt.inertia == _dense_inertia(W, A) == Inertia(3, 2, 0)
    assert kkt.is_minimum is False
    _check_solution(kkt, W, A, rng)


def test_without_constraints_and_singular_inputs():
    W = _laplacian_2d(4)
    x, y = factor_kkt(W).solve(np.ones(16))
    np.testing.assert_allclose(W @ x, np.ones(16), atol=1e-12)
    assert y.shape == (0,)
    A = np.zeros((1, 16))  # a zero constraint row: rank deficient
    with pytest.raises(np.linalg.LinAlgError):
        factor_kkt(W, A)
    with pytest.raises(ValueError, match="A must have 16 columns"):
        factor_kkt(W, np.ones((1, 3)))


def test_schur_reuse_for_a_subset_of_rows_matches_a_fresh_factorisation():
    """Z and S formed once for 5 rows solve the KKT system of any 3 of them."""
    rng = np.random.default_rng(3)
    W = _laplacian_2d(22)  # 484 unknowns: the sparse path
    n = W.shape[0]
    A = sp.csr_matrix(rng.standard_normal((5, n)))
    factor = factor_spd(W)
    Z = factor.solve(A.T.toarray())
    S = A @ Z
    rows = np.array([4, 0, 2])
    b, c = rng.standard_normal(n), rng.standard_normal(3)
    x, y = schur_solve(factor.solve(b), A[rows], Z[:, rows], S[np.ix_(rows, rows)], c)
    x_ref, y_ref = factor_kkt(W, A[rows]).solve(b, c)
    np.testing.assert_allclose(x, x_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(y, y_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(A[rows] @ x, c, atol=1e-10)


def test_uncertified_factor_solves_the_same_but_does_not_detect_indefiniteness():
    W = _laplacian_2d(22).tolil()
    b = np.arange(W.shape[0], dtype=float)
    spd = factor_spd(W.tocsr(), certify=False, sparse_solver="superlu")
    np.testing.assert_allclose(
        spd.solve(b), factor_spd(W.tocsr(), sparse_solver="superlu").solve(b), rtol=1e-12
    )
    W[0, 0] = -5.0  # one negative eigenvalue
    assert factor_spd(W.tocsr(), sparse_solver="superlu") is None
    assert factor_spd(W.tocsr(), certify=False, sparse_solver="superlu") is not None


def test_a_rough_factor_is_float32_from_its_size_and_still_refuses_indefinite_w(monkeypatch):
    """``rough=True`` from ROUGH_MIN rows: SuperLU in float32, whose solution is off by
    float32 round-off times the condition number (not float64's); below, the float64
    factor. Like the float64 one it refuses a W with a negative eigenvalue."""
    side = 40
    rng = np.random.default_rng(0)
    order = rng.permutation(side * side)
    W = _laplacian_2d(side)[order][:, order].tocsr()  # a wide band: SuperLU, not banded
    b = rng.standard_normal(W.shape[0])
    exact = factor_spd(W, sparse_solver="superlu").solve(b)
    monkeypatch.setattr(spd_module, "ROUGH_MIN", W.shape[0] + 1)
    np.testing.assert_array_equal(
        factor_spd(W, rough=True, sparse_solver="superlu").solve(b), exact
    )
    monkeypatch.setattr(spd_module, "ROUGH_MIN", W.shape[0])
    _assert_float32_solution(
        factor_spd(W, rough=True, sparse_solver="superlu").solve(b), exact, side
    )
    bad = _with_a_negative_pivot(W)
    assert factor_spd(bad, rough=True, sparse_solver="superlu") is None
    # a direction of negative curvature off the float32 factor proves it: no float64 one
    dtypes = []
    superlu = spd_module.sparse_lu
    monkeypatch.setattr(
        spd_module, "sparse_lu", lambda M, **kw: dtypes.append(M.dtype) or superlu(M, **kw)
    )
    factor, directions = factor_spd_or_curvature(bad, rough=True, sparse_solver="superlu")
    assert factor is None and dtypes == [np.float32]
    assert np.all(np.einsum("ij,ij->j", directions, bad @ directions) < 0)
    # float64 only: a diagonal over eight decades (not tried in float32); a nearly floating
    # grid (grounded by 1e-9: condition ~1e12) that float32 cannot solve to ROUGH_RESIDUAL
    decades = 10.0 ** rng.uniform(0, 8, 2 * side * (side - 1))
    for weights, ground in ((decades, 1.0), (np.ones_like(decades), 1e-9)):
        M = _weighted_grid_laplacian(side, weights, ground)[order][:, order].tocsr()
        dtypes.clear()
        factor = factor_spd(M, rough=True, sparse_solver="superlu")
        assert dtypes[-1] == np.float64 and len(dtypes) == (1 if ground == 1.0 else 2)
        np.testing.assert_array_equal(
            factor.solve(b), factor_spd(M, sparse_solver="superlu").solve(b)
        )


def _assert_float32_solution(solution: NDArray, exact: NDArray, side: int) -> None:
    """``solution`` (float64) is off ``exact`` by float32 round-off times the condition of
    the side x side 5-point Laplacian (eigenvalues 4 - 2 cos(i pi / (side + 1)) - 2 cos(j
    ...)), not by float64's."""
    assert solution.dtype == np.float64
    error = np.linalg.norm(solution - exact) / np.linalg.norm(exact)
    condition = (1 + np.cos(np.pi / (side + 1))) / (1 - np.cos(np.pi / (side + 1)))
    assert 1e-12 < error < np.finfo(np.float32).eps * condition


def _with_a_negative_pivot(W: sp.csr_matrix) -> sp.csr_matrix:
    """``W`` with its diagonal entry 300 set to -3: a negative eigenvalue."""
    bad = W.tolil()
    bad[300, 300] = -3.0
    return bad.tocsr()


def _weighted_grid_laplacian(side: int, weights: NDArray, ground: float) -> sp.csr_matrix:
    """Laplacian of a side x side grid with the given edge weights (2 side (side - 1),),
    node 0 tied to the ground by ``ground``: positive definite."""
    ids = np.arange(side * side).reshape(side, side)
    edges = np.concatenate(
        [np.c_[ids[:, :-1].ravel(), ids[:, 1:].ravel()], np.c_[ids[:-1].ravel(), ids[1:].ravel()]]
    )
    n, m = side * side, len(edges)
    D = sp.csr_matrix(
        (np.r_[np.ones(m), -np.ones(m)], (np.r_[np.arange(m), np.arange(m)], edges.T.ravel())),
        shape=(m, n),
    )
    tie = sp.csr_matrix(([ground], ([0], [0])), shape=(n, n))
    return (D.T @ sp.diags(weights) @ D + tie).tocsr()


def test_sparse_solver_choice_is_checked():
    """The ``sparse_solver`` argument: a name of SPARSE_SOLVERS (checked at every size),
    "auto" meaning PARDISO where pypardiso imports and SuperLU elsewhere."""
    with pytest.raises(ValueError, match="sparse_solver must be one of"):
        sparse_backend("umfpack")
    with pytest.raises(ValueError, match="sparse_solver must be one of"):
        factor_spd(np.eye(3), sparse_solver="umfpack")
    with pytest.raises(ValueError, match="sparse_solver must be one of"):
        factor_kkt(_laplacian_2d(22), sparse_solver="umfpack")
    assert sparse_backend("superlu") == "superlu"
    have_pardiso = spd_module._pardiso() is not None
    assert sparse_backend() == sparse_backend("auto") == ("pardiso" if have_pardiso else "superlu")
    if not have_pardiso:
        with pytest.raises(ImportError, match="pypardiso"):
            factor_spd(_laplacian_2d(22), sparse_solver="pardiso")


def test_pardiso_agrees_with_superlu_and_refuses_indefinite_matrices():
    """Solutions of both backends agree; both refuse a matrix with one negative eigenvalue;
    more live factorisations of one structure than PARDISO keeps slots still solve right."""
    pytest.importorskip("pypardiso")
    from continuum_vs_network.linalg import pardiso

    rng = np.random.default_rng(3)
    W = _laplacian_2d(30)
    B = rng.standard_normal((W.shape[0], 2))
    reference = factor_spd(W, sparse_solver="superlu").solve(B)
    np.testing.assert_allclose(
        factor_spd(W, sparse_solver="pardiso").solve(B), reference, rtol=1e-10
    )
    bad = W.tolil()
    bad[7, 7] = -1.0
    assert factor_spd(bad.tocsr(), sparse_solver="pardiso") is None
    shifted = [W + s * sp.identity(W.shape[0], format="csr") for s in range(pardiso.MAXFCT + 3)]
    factors = [factor_spd(M, sparse_solver="pardiso") for M in shifted]
    for M, f in zip(shifted, factors, strict=True):
        np.testing.assert_allclose(M @ f.solve(B), B, atol=1e-9)


def test_failed_factorisation_returns_directions_of_negative_curvature():
    W = _laplacian_2d(22).tolil()
    factor, directions = factor_spd_or_curvature(W.tocsr(), sparse_solver="superlu")
    assert factor is not None and directions is None
    b = np.arange(W.shape[0], dtype=float)
    np.testing.assert_allclose(W.tocsr() @ factor.solve(b), b, rtol=1e-9, atol=1e-9)
    W[100, 100] = -3.0  # indefinite: Rayleigh quotient of e_100 is negative
    W = W.tocsr()
    factor, directions = factor_spd_or_curvature(W, sparse_solver="superlu")
    assert factor is None
    assert directions is not None and directions.shape[0] == W.shape[0]
    curvature = np.einsum("ij,ij->j", directions, W @ directions)
    assert np.all(curvature < 0)
    # a negative Rayleigh quotient bounds the smallest eigenvalue from above
    lowest = np.linalg.eigvalsh(W.toarray())[0]
    norms = np.einsum("ij,ij->j", directions, directions)
    assert np.all(lowest <= curvature / norms + 1e-12)


def test_banded_cholesky_matches_superlu_and_refuses_an_indefinite_band():
    """A narrow-band W (a grid Laplacian in natural order, bandwidth = side) goes to the
    banded Cholesky: same solution as SuperLU to round-off; one negative eigenvalue and
    it returns None, and factor_spd_or_curvature still finds the negative direction."""
    W = _laplacian_2d(24)  # 576 unknowns, lower bandwidth 24
    assert kkt_module.banded_pays(W.shape[0], 24)
    assert not kkt_module.banded_pays(W.shape[0], W.shape[0] - 1)  # an unordered matrix
    b = np.sin(np.arange(W.shape[0], dtype=float))
    lu = kkt_module.sparse_lu(W, ordering="NATURAL")
    np.testing.assert_allclose(
        factor_spd(W, sparse_solver="superlu").solve(b), lu.solve(b), rtol=1e-11
    )
    bad = W.tolil()
    bad[300, 300] = -3.0
    bad = bad.tocsr()
    assert factor_spd(bad, sparse_solver="superlu") is None
    assert np.linalg.eigvalsh(bad.toarray())[0] < 0
    factor, directions = factor_spd_or_curvature(bad, sparse_solver="superlu")
    assert factor is None and directions is not None
    assert np.all(np.einsum("ij,ij->j", directions, bad @ directions) < 0)


def test_the_kept_band_layout_follows_each_matrix_structure():
    """The banded Cholesky keeps where a structure's entries go in the band, per
    ``indptr``. A grid whose vertical edges are twisted by one column has the grid's row
    counts (the same ``indptr``) but other columns; it, the grid again and a copy of the
    grid with every entry stored twice (not canonical) each solve their own system, to
    float64 and float32 round-off, against dense solves (1024 rows: from
    ``ROUGH_BANDED_MIN`` a rough factor is float32)."""
    side = 32
    n = side * side
    ids = np.arange(n).reshape(side, side)
    across = np.c_[ids[:, :-1].ravel(), ids[:, 1:].ravel()]

    def laplacian(up: NDArray) -> sp.csr_matrix:
        """Grid Laplacian with vertical edges ``(r, c) - (r + 1, up[c])``, plus 4 I."""
        edges = np.concatenate([across, np.c_[ids[:-1].ravel(), ids[1:, up].ravel()]])
        rows, cols = np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]
        A = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
        return sp.csr_matrix(sp.diags(np.asarray(A.sum(axis=1)).ravel() + 4.0) - A)

    grid = laplacian(np.arange(side))
    twisted = laplacian((np.arange(side) + 1) % side)
    np.testing.assert_array_equal(twisted.indptr, grid.indptr)
    assert not np.array_equal(twisted.indices, grid.indices)
    twice = np.repeat(np.arange(grid.nnz), 2)  # every entry stored twice, halved
    doubled = sp.csr_matrix(
        (grid.data[twice] / 2, grid.indices[twice], 2 * grid.indptr), shape=grid.shape
    )
    assert not doubled.has_canonical_format
    b = np.sin(np.arange(n, dtype=float))
    for matrix in (grid, twisted, grid, doubled, twisted):
        assert factor_spd(matrix, certify=True, sparse_solver="superlu") is not None
        exact = np.linalg.solve(matrix.toarray(), b)
        np.testing.assert_allclose(
            factor_spd(matrix, sparse_solver="superlu").solve(b), exact, rtol=1e-10
        )
        rough = factor_spd(matrix, rough=True, sparse_solver="superlu")
        assert rough.approximate
        error = np.linalg.norm(rough.solve(b) - exact) / np.linalg.norm(exact)
        assert 1e-12 < error < 1e-5


def test_a_rough_banded_factor_is_float32_and_still_refuses_indefinite_w(monkeypatch):
    """``rough=True`` on a narrow band: LAPACK's Cholesky in float32, its solution off by
    float32 round-off times the condition number; a negative eigenvalue is refused and its
    direction still found. A diagonal over eight decades, or a condition number float32
    cannot solve to ROUGH_RESIDUAL (a grid grounded by 1e-9), gets the float64 factor.
    (576 rows: float32 from any size here, ``ROUGH_BANDED_MIN`` lowered.)"""
    monkeypatch.setattr(spd_module, "ROUGH_BANDED_MIN", 0)
    side = 24
    W = _laplacian_2d(side)  # natural order: lower bandwidth 24
    b = np.sin(np.arange(W.shape[0], dtype=float))
    exact = factor_spd(W, sparse_solver="superlu").solve(b)
    rough = factor_spd(W, rough=True, sparse_solver="superlu")
    _assert_float32_solution(rough.solve(b), exact, side)
    np.testing.assert_array_equal(rough.precondition(b), rough.solve(b))
    bad = _with_a_negative_pivot(W)
    assert factor_spd(bad, rough=True, sparse_solver="superlu") is None
    factor, directions = factor_spd_or_curvature(bad, rough=True, sparse_solver="superlu")
    assert factor is None and np.all(np.einsum("ij,ij->j", directions, bad @ directions) < 0)
    calls = []
    float32 = spd_module._banded_float32
    monkeypatch.setattr(
        spd_module, "_banded_float32", lambda *a: calls.append(float32(*a)) or calls[-1]
    )
    decades = 10.0 ** np.random.default_rng(0).uniform(0, 8, 2 * side * (side - 1))
    for weights, ground, tried in ((decades, 1.0, 0), (np.ones_like(decades), 1e-9, 1)):
        calls.clear()
        M = _weighted_grid_laplacian(side, weights, ground)
        factor = factor_spd(M, rough=True, sparse_solver="superlu")
        assert len(calls) == tried and not any(calls)  # not tried, or tried and refused
        np.testing.assert_array_equal(
            factor.solve(b), factor_spd(M, sparse_solver="superlu").solve(b)
        )


def test_a_ladder_rung_takes_a_failed_float32_pivot_as_final(monkeypatch):
    """2x2 blocks [[1, 1 - 1e-9], [1 - 1e-9, 1]] are positive definite (eigenvalue 1e-9)
    but singular in float32 (1 - 1e-9 rounds to 1: a zero pivot). A rough factorisation
    falls back to float64 and succeeds; as a rung of the Levenberg-Marquardt ladder
    (``rung=True``) it fails without factorising in float64. A well-conditioned rung still
    gets its float32 factor, and an inaccurate float32 factor (a pivot that passed) still
    gets the float64 one (forced: whether a given float32 factor passes its pivots but
    solves inaccurately depends on the machine's BLAS). (Float32 from any size here,
    ``ROUGH_BANDED_MIN`` lowered.)"""
    monkeypatch.setattr(spd_module, "ROUGH_BANDED_MIN", 0)
    blocks = 300  # 600 rows: above DENSE_MAX, lower bandwidth 1
    near = sp.block_diag([np.array([[1.0, 1.0 - 1e-9], [1.0 - 1e-9, 1.0]])] * blocks, "csr")
    assert isinstance(factor_spd(near, rough=True, sparse_solver="superlu"), Factor)
    calls = []
    cholesky = spd_module.sla.lapack.dpbtrf  # the float64 banded Cholesky
    monkeypatch.setattr(
        spd_module.sla.lapack, "dpbtrf", lambda *a, **k: calls.append(1) or cholesky(*a, **k)
    )
    assert factor_spd(near, rough=True, rung=True, sparse_solver="superlu") is None and not calls
    well = factor_spd(_laplacian_2d(24), rough=True, rung=True, sparse_solver="superlu")
    assert isinstance(well, Factor) and well.approximate and not calls
    monkeypatch.setattr(spd_module, "_banded_float32", lambda W, band: False)  # inaccurate
    side = 24
    grounded = _weighted_grid_laplacian(side, np.ones(2 * side * (side - 1)), 1e-9)
    b = np.sin(np.arange(side * side, dtype=float))
    fallback = factor_spd(grounded, rough=True, rung=True, sparse_solver="superlu")
    assert calls and np.allclose(
        fallback.solve(b), factor_spd(grounded, sparse_solver="superlu").solve(b), rtol=1e-12
    )


def test_a_small_bands_rough_factor_is_float64():
    """Below ``ROUGH_BANDED_MIN`` rows a rough banded factor is the float64 one, and it
    preconditions with its own solve (exact to float64 round-off); from it, float32."""
    from continuum_vs_network.linalg.spd import ROUGH_BANDED_MIN

    for side, small in ((24, True), (32, False)):
        W = _laplacian_2d(side)
        assert (W.shape[0] < ROUGH_BANDED_MIN) == small
        b = np.sin(np.arange(W.shape[0], dtype=float))
        exact = np.linalg.solve(W.toarray(), b)
        rough = factor_spd(W, rough=True, sparse_solver="superlu")
        error = np.linalg.norm(rough.precondition(b) - exact) / np.linalg.norm(exact)
        assert rough.approximate != small
        assert (error < 1e-13) if small else (1e-12 < error < 1e-5)


def test_band_order_reports_the_assembled_bandwidth():
    """The Hessian pattern of a lattice in band_order's row order has exactly the lower
    bandwidth band_order reports: one row of the lattice and a node (2 (side + 1) + 1
    coordinates), where reverse Cuthill-McKee from a corner sweeps by diagonals, about
    1.4x wider."""
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    import continuum_vs_network as cvn
    from continuum_vs_network.network.energy import HessianPattern
    from continuum_vs_network.network.ordering import _bandwidth, band_order, coordinate_order

    side = 20
    net = cvn.triangular_lattice(side, side, noise=0.1, rng=np.random.default_rng(1))
    free = ~cvn.default_pins(net)
    coords, width = band_order(net.springs, net.n_nodes, free, net.positions)
    np.testing.assert_array_equal(np.sort(coords), np.flatnonzero(free.ravel()))
    pattern = HessianPattern(net.springs, net.n_nodes, coords=coords)
    W = pattern.assemble(np.tile(np.eye(2), (net.n_springs, 1, 1))).tocoo()
    assert int(np.max(W.row - W.col)) == width
    assert width <= 2 * (side + 1) + 1
    adj = sp.coo_matrix(
        (np.ones(2 * net.n_springs), (net.springs.ravel(), net.springs[:, ::-1].ravel()))
    ).tocsr()
    rcm = coordinate_order(reverse_cuthill_mckee(adj, symmetric_mode=True), free)
    assert _bandwidth(rcm, net.springs, net.n_nodes) > 1.3 * width


def test_relax_passes_its_sparse_solver_to_every_factorisation(monkeypatch):
    """``relax(sparse_solver=...)`` reaches every sparse factorisation of the solve (no
    process-global choice): besides the floppiness check's certificate, nothing asks for
    "auto"; a name outside SPARSE_SOLVERS is refused naming the argument."""
    from continuum_vs_network.linalg import spd

    net = cvn.triangular_lattice(40, 40, noise=0.05, rng=np.random.default_rng(1))
    mid = net.n_springs // 2
    asked = []
    backend = spd.sparse_backend

    def spy(name="auto"):
        asked.append(name)
        return backend(name)

    monkeypatch.setattr(spd, "sparse_backend", spy)
    eq = cvn.relax(net, clamped={mid: 1.3 * net.rest_length[mid]}, sparse_solver="superlu")
    assert eq.converged
    assert asked.count("superlu") >= 2 and asked.count("auto") <= 1
    with pytest.raises(ValueError, match="sparse_solver"):
        cvn.relax(net, sparse_solver="umfpack")
