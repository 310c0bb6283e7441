"""Linear rigidity of a spring network: rigidity matrix, zero modes and states of self-stress.

The rigidity (compatibility) matrix ``R`` maps node displacements to first-order spring
elongations: row ``j`` of a spring ``a -> b`` with unit vector ``u_j = (x_b - x_a) / r_j``
holds ``-u_j`` at node ``a`` and ``+u_j`` at node ``b``. The stiffness matrix of a
stress-free network is ``K = R^T diag(k) R``; so

* its zero modes (mechanisms and rigid motions) are the null space of ``R`` (springs with
  ``k > 0`` only), and a network is rigid when ``rank R = 2 N - 3``;
* its states of self-stress are the null space of ``R^T``: spring tensions that balance at
  every node with no external force. A spring that carries no state of self-stress has zero
  tension, hence zero strain, in every free (unloaded) equilibrium near the reference
  positions, whatever the rest lengths.

Ranks are numerical: a singular value of ``R`` (rows are unit vectors, so ``R`` has no unit)
counts as zero when it is below ``rtol`` times the largest one. Dense singular value
decompositions are used up to :data:`DENSE_LIMIT` coordinates (they cost O(n^3): about
0.2 s at 1000 coordinates and 2 s at 2000 on two idle cores, ten times more on a busy
machine); above it, rank counts use the singular values of ``R`` on the subspace of its
smallest ones, found by shift-invert iteration on ``R^T R`` (about 0.05 s at 2000
coordinates), and self-stress supports use sparse leverage scores. Before either, the
``"auto"`` counts certify full rank where they can by one sparse Cholesky factorisation of
``R^T R`` shifted by the threshold times a margin (a few ms at 2000 coordinates).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..linalg.spd import factor_spd, sparse_lu
from .constraints import default_pins, pin_mask
from .model import SpringNetwork, spring_vectors, vector_lengths

__all__ = [
    "DENSE_LIMIT",
    "count_zero_modes",
    "is_rigid",
    "rigidity_matrix",
    "self_stress_support",
    "self_stresses",
    "zero_modes",
]

DENSE_LIMIT = 600
"""Largest number of coordinates handled with dense SVD by the ``"auto"`` methods."""

#: The ``"auto"`` counts first try to certify full rank: every singular value above this
#: many times the threshold (:func:`_full_rank`); the margin covers the factorisation's
#: round-off, so a count near the threshold is always made by the singular values.
CERTIFY_MARGIN = 100.0
#: ... from this many free coordinates (below it the dense SVD is the cheaper count: 0.15
#: against 0.4 ms at 47, 0.55 against 0.43 ms at 95, 36 against 0.6 ms at 509)
CERTIFY_MIN = 80

Method = Literal["auto", "dense", "sparse"]
_CHOLESKY_LIMIT = 5000  # leverage scores: dense Cholesky of the pinned R^T R up to this size


def _positions(net: SpringNetwork, x: ArrayLike | None) -> NDArray:
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    if x is None:
        return net.positions
    return check.float_array("x", x, (net.n_nodes, 2))


def rigidity_matrix(net: SpringNetwork, x: ArrayLike | None = None) -> sp.csr_matrix:
    """The (n_springs, 2 n_nodes) sparse rigidity matrix at positions ``x``.

    Row ``j`` (spring ``a -> b``) holds ``-u_j`` in columns ``2a, 2a+1`` and ``+u_j`` in
    columns ``2b, 2b+1``, with ``u_j`` the unit vector from ``a`` to ``b``; coordinates are
    ordered ``x0, y0, x1, y1, ...`` (the ravel of a (n_nodes, 2) array). All springs are
    included, whatever their stiffness.

    Raises
    ------
    ValueError
        When a spring has zero length at ``x`` (its direction is undefined).
    """
    rows, cols, vals = _rigidity_entries(net, _positions(net, x))
    return sp.csr_matrix((vals, (rows, cols)), shape=(net.n_springs, 2 * net.n_nodes))


def _rigidity_entries(net: SpringNetwork, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Row, column and value (each (4 n_springs,)) of the rigidity matrix's entries at ``x``
    (n_nodes, 2); raises ValueError for a spring of zero length."""
    s = net.springs
    d = spring_vectors(x, s)
    r = vector_lengths(d)
    zero = np.flatnonzero(r == 0.0)
    if zero.size:
        raise ValueError(f"spring {zero[0]} has zero length at x; its direction is undefined")
    u = d / r[:, None]
    rows = np.repeat(np.arange(net.n_springs), 4)
    cols = np.stack([2 * s[:, 0], 2 * s[:, 0] + 1, 2 * s[:, 1], 2 * s[:, 1] + 1], axis=1).ravel()
    vals = np.stack([-u[:, 0], -u[:, 1], u[:, 0], u[:, 1]], axis=1).ravel()
    return rows, cols, vals


def _dense_rigidity(net: SpringNetwork, x: NDArray, rows: NDArray, cols: NDArray) -> NDArray:
    """The rigidity matrix's ``rows`` (springs) and ``cols`` (flat coordinates) as a dense
    array, built without scipy.sparse (whose construction and slicing cost ~10x the SVD of a
    small network's matrix)."""
    r, c, v = _rigidity_entries(net, x)
    R = np.zeros((net.n_springs, 2 * net.n_nodes))
    R[r, c] = v  # a spring's two nodes differ: no entry written twice
    return R[np.ix_(rows, cols)]


def _sparse_rigidity(net: SpringNetwork, x: NDArray, rows: NDArray, cols: NDArray):
    """The rigidity matrix's ``rows`` (springs) and ``cols`` (flat coordinates), CSR."""
    r, c, v = _rigidity_entries(net, x)
    row_of = np.full(net.n_springs, -1)
    row_of[rows] = np.arange(rows.size)
    col_of = np.full(2 * net.n_nodes, -1)
    col_of[cols] = np.arange(cols.size)
    keep = (row_of[r] >= 0) & (col_of[c] >= 0)
    return sp.csr_matrix(
        (v[keep], (row_of[r[keep]], col_of[c[keep]])), shape=(rows.size, cols.size)
    )


def _full_rank(R: sp.csr_matrix, rtol: float) -> bool:
    """True when every singular value of ``R`` (m, n) is certainly above ``rtol`` times the
    largest: ``R^T R - (CERTIFY_MARGIN rtol)^2 lam I`` is positive definite (it has a
    Cholesky factor, :func:`~..linalg.spd.factor_spd`), with ``lam`` Gershgorin's bound on the
    largest eigenvalue of ``R^T R``. One sparse factorisation, against the dense SVD's
    O(n^3) or the shift-invert iteration; False (count the modes) when it fails, within
    the margin of the threshold or of round-off, or with fewer rows than columns."""
    if R.shape[0] < R.shape[1] or CERTIFY_MARGIN * rtol >= 1.0:
        return False
    K = (R.T @ R).tocsr()
    lam = float(np.max(np.abs(K).sum(axis=1))) if K.nnz else 0.0
    if lam == 0.0:
        return False
    shift = (CERTIFY_MARGIN * rtol) ** 2 * lam
    return factor_spd(K - shift * sp.identity(K.shape[0], format="csr")) is not None


def _clamp_indices(net: SpringNetwork, clamped: Mapping[int, float] | Sequence[int]) -> NDArray:
    keys = list(clamped.keys()) if isinstance(clamped, Mapping) else list(np.ravel(clamped))
    idx = np.array([int(k) for k in keys], dtype=np.int64)
    bad = idx[(idx < 0) | (idx >= net.n_springs)]
    if bad.size:
        raise ValueError(f"clamped names spring {bad[0]} outside 0..{net.n_springs - 1}")
    return idx


def _check_method(method: str) -> None:
    if method not in ("auto", "dense", "sparse"):
        raise ValueError(f"method must be 'auto', 'dense' or 'sparse', got {method!r}")


def _check_rtol(rtol: float) -> None:
    if not (np.isfinite(rtol) and 0 < rtol < 1):
        raise ValueError(f"rtol must be in (0, 1), got {rtol}")


def _dense_rank(R: sp.spmatrix | NDArray, rtol: float) -> int:
    if min(R.shape) == 0:
        return 0
    s = np.linalg.svd(R.toarray() if sp.issparse(R) else R, compute_uv=False)
    return int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0


def _sparse_nullity(R: sp.spmatrix, rtol: float) -> int:
    """Dimension of the null space of ``R`` (m, n): how many singular values are at most
    ``rtol`` times the largest (bounded by Gershgorin on ``R^T R``).

    Block shift-invert subspace iteration on ``R^T R`` around a small shift
    (:func:`_count_smallest`) finds the subspace of the ``k`` smallest singular values;
    ``k`` doubles until one is above the threshold. A block, not single-vector Lanczos:
    Lanczos finds one vector of an eigenvalue per start vector and the rest only through
    round-off, and scipy's ``eigsh`` (shift-invert ARPACK) counted 7 of 9, 28 of 31 or 62 of
    63 zero modes on 4 of 120 diluted lattices (5-11 per side), differently from run to run.
    """
    n = R.shape[1]
    K = (R.T @ R).tocsc()
    lam_max = float(np.max(np.abs(K).sum(axis=1))) if K.nnz else 0.0  # Gershgorin bound
    if lam_max == 0.0:
        return n
    threshold = rtol * np.sqrt(lam_max)
    # modes below the shift are not told apart from the null space by the iteration, only
    # by the SVD of the block, which must then hold them all: at 1e-6 (before) the soft
    # bending modes of a thin isostatic strip (sigma^2 down to 1e-14 of lam_max) filled it
    shift = 1e-10 * lam_max
    # symmetric mode, minimum degree on K + K^T (K > 0): the count at 4e3 / 1e4 nodes took
    # 0.09 / 0.28 s with SuperLU's default (partial pivoting, COLAMD), now 0.065 / 0.21 s
    solve = sparse_lu(K + shift * sp.identity(n, format="csc")).solve
    rng = np.random.default_rng(0)  # a seeded block: counts reproducible bit for bit
    k = 8
    while True:
        if k >= n - 1:  # too many zero modes for a block this wide: count them densely
            return n - _dense_rank(R, rtol)
        n_zero = _count_smallest(R, solve, k, threshold, rng)
        if n_zero < k:
            return n_zero
        k *= 2


def _count_smallest(R: sp.spmatrix, solve, k: int, threshold: float, rng) -> int:
    """How many of the ``k`` smallest singular values of ``R`` (m, n) are ``<= threshold``,
    given ``solve = (R^T R + shift I)^-1``.

    Subspace iteration on that inverse with a random block of ``k + 8`` columns; each
    iteration's count comes from the singular values of ``R`` on the block (a dense SVD of
    ``R X``, (m, k + 8)). Those never fall below the singular values of their rank, so the
    count never exceeds the true one; and they resolve a singular value to round-off of
    the largest, where eigenvalues of ``R^T R`` (the squares) stop near 1e-8 of it: a
    rigid 349-node isostatic strip (smallest singular value 1.7e-7 of the largest) was
    counted floppy. A random block of more columns than zero singular values holds all
    of their directions, which the iteration amplifies by ``(sigma^2 + shift) / shift``
    each step. Stops when the count has not changed for two iterations and the smallest
    singular value above the threshold has settled to 1e-3.
    """
    X = np.linalg.qr(rng.standard_normal((R.shape[1], k + 8)))[0]
    counts: list[int] = []
    above = np.inf
    for _ in range(200):
        X = np.linalg.qr(solve(X))[0]
        RX = R @ X
        sigma = np.linalg.svd(RX, compute_uv=False)[::-1]  # smallest first
        # fewer rows than columns: the missing singular values are zeros
        sigma = np.concatenate([np.zeros(max(0, RX.shape[1] - RX.shape[0])), sigma])[:k]
        count = int(np.sum(sigma <= threshold))
        rest = sigma[count] if count < k else 0.0
        settled = abs(rest - above) <= 1e-3 * rest
        counts.append(count)
        if len(counts) >= 3 and counts[-1] == counts[-2] == counts[-3] and settled:
            return count
        above = rest
    return counts[-1]


def zero_modes(
    net: SpringNetwork,
    *,
    pinned: Sequence[int] | NDArray | None = None,
    clamped: Mapping[int, float] | Sequence[int] = (),
    x: ArrayLike | None = None,
    method: Method = "auto",
    rtol: float = 1e-8,
) -> int:
    """Number of zero modes of the stiffness matrix restricted to the free coordinates.

    The count is ``n_free - rank R_f``, where ``R_f`` holds the rows of the springs with
    ``k > 0`` and of the clamped springs (a clamp fixes a length, whatever the stiffness)
    and the columns of the free coordinates.

    Parameters
    ----------
    net : SpringNetwork
    pinned : node indices, (n_nodes, 2) bool mask, or None
        Fixed coordinates. None pins nothing, so the count includes the 3 rigid motions
        (2 translations and a rotation; 2 for a single node). Pass
        ``default_pins(net)`` to count what :func:`~continuum_vs_network.relax` sees.
    clamped : {spring: length} or sequence of spring indices
        Springs whose length is held; only the indices are used.
    x : (n_nodes, 2) float array, optional
        Positions at which ``R`` is evaluated (default ``net.positions``).
    method : {"auto", "dense", "sparse"}
        ``dense``: singular values of ``R_f`` (O(n^3); about 2 s at 2000 coordinates).
        ``sparse``: singular values of ``R_f`` on the subspace of its smallest, found by
        shift-invert iteration on ``R_f^T R_f`` (fast when the count is small).
        ``auto``: 0 when one Cholesky factorisation certifies full rank with a margin
        (:data:`CERTIFY_MARGIN`, the common case of a rigid network under pins; from
        :data:`CERTIFY_MIN` free coordinates), else
        dense up to :data:`DENSE_LIMIT` free coordinates, sparse above.
    rtol : float
        A singular value below ``rtol * sigma_max`` counts as zero (the sparse path bounds
        ``sigma_max`` by Gershgorin on ``R_f^T R_f``).

    Returns
    -------
    int
    """
    _check_method(method)
    _check_rtol(rtol)
    _positions(net, None)  # checks net
    free = np.ones((net.n_nodes, 2), bool) if pinned is None else ~pin_mask(net, pinned)
    return count_zero_modes(
        net, free, _clamp_indices(net, clamped), _positions(net, x), method=method, rtol=rtol
    )


def count_zero_modes(
    net: SpringNetwork,
    free: NDArray,
    clamps: NDArray,
    x: NDArray,
    *,
    method: Method = "auto",
    rtol: float = 1e-8,
) -> int:
    """:func:`zero_modes` on arguments already checked: ``free`` (n_nodes, 2) bool, the
    clamped springs' indices, positions ``x`` (n_nodes, 2)."""
    rows = net.stiffness > 0
    rows[clamps] = True
    rows, cols = np.flatnonzero(rows), np.flatnonzero(free.ravel())
    n_free = cols.size
    if n_free == 0:
        return 0
    certify = method == "auto" and n_free >= CERTIFY_MIN
    if certify and _full_rank(_sparse_rigidity(net, x, rows, cols), rtol):
        return 0
    if method == "dense" or (method == "auto" and n_free <= DENSE_LIMIT):
        return n_free - _dense_rank(_dense_rigidity(net, x, rows, cols), rtol)
    R = rigidity_matrix(net, x)[rows][:, cols]
    return _sparse_nullity(R.tocsr(), rtol)


def is_rigid(
    net: SpringNetwork, *, x: ArrayLike | None = None, method: Method = "auto", rtol: float = 1e-8
) -> bool:
    """True when the springs with ``k > 0`` leave only rigid motions: ``rank R = 2N - 3``.

    A single node is rigid. ``method`` and ``rtol`` are those of :func:`zero_modes`.
    """
    _positions(net, None)  # checks net
    if net.n_nodes <= 1:
        return True
    return zero_modes(net, x=x, method=method, rtol=rtol) == 3


def self_stresses(
    net: SpringNetwork, *, x: ArrayLike | None = None, rtol: float = 1e-8
) -> NDArray[np.float64]:
    """An orthonormal basis of the states of self-stress (dense SVD).

    A state of self-stress is a vector of spring tensions ``t`` with ``R^T t = 0``: they
    balance at every node without external force. All springs are included, whatever their
    stiffness.

    Returns
    -------
    (n_springs, n_self_stresses) float array
        Orthonormal columns; ``n_self_stresses = n_springs - rank R``.
    """
    _check_rtol(rtol)
    R = rigidity_matrix(net, x).toarray()
    if R.shape[0] == 0:
        return np.zeros((0, 0))
    U, s, _ = np.linalg.svd(R, full_matrices=True)
    rank = int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    return U[:, rank:]


def self_stress_support(
    net: SpringNetwork, *, x: ArrayLike | None = None, method: Method = "auto", rtol: float = 1e-8
) -> NDArray[np.float64]:
    """How much of the self-stress space each spring carries, a (n_springs,) array in [0, 1].

    Entry ``j`` is the diagonal ``P_jj`` of the orthogonal projector onto the states of
    self-stress (equivalently ``1 - h_j``, with ``h_j`` the leverage of row ``j`` of ``R``).
    It is zero exactly when spring ``j`` carries no state of self-stress: then its tension,
    and so its strain, vanishes in any unloaded equilibrium, and removing it makes the
    network lose rigidity (spring ``j`` is a "bridge" of the rigidity matroid).

    Parameters
    ----------
    method : {"auto", "dense", "sparse"}
        ``dense``: row norms of :func:`self_stresses`. ``sparse``: leverage scores
        ``h_j = r_j^T (R_p^T R_p)^{-1} r_j`` with three coordinates pinned by
        :func:`~continuum_vs_network.default_pins`, from a dense Cholesky factor up to
        5000 coordinates (0.6 s at 2000) and a sparse LU factor above; needs a rigid
        network (raises ValueError otherwise). ``auto``: dense up to
        :data:`DENSE_LIMIT` coordinates, sparse above unless the network is not rigid.
    """
    _check_method(method)
    _check_rtol(rtol)
    n = 2 * net.n_nodes
    if method == "dense" or (method == "auto" and n <= DENSE_LIMIT):
        basis = self_stresses(net, x=x, rtol=rtol)
        return np.einsum("ij,ij->i", basis, basis)
    if not is_rigid(net.with_stiffness(np.ones(net.n_springs)), x=x, method="sparse"):
        if method == "auto":
            return self_stress_support(net, x=x, method="dense", rtol=rtol)
        raise ValueError("method='sparse' needs a rigid network; use method='dense'")
    R = rigidity_matrix(net, x)
    keep = np.flatnonzero(~default_pins(net).ravel())
    Rp = R[:, keep].tocsc()
    K = (Rp.T @ Rp).tocsc()
    if K.shape[0] <= _CHOLESKY_LIMIT:  # a dense Cholesky solve beats SuperLU's many-RHS solve
        factor = sla.cho_factor(K.toarray())

        def solve(b: NDArray) -> NDArray:
            return sla.cho_solve(factor, b)
    else:
        solve = spla.splu(K).solve
    RpT = Rp.T.tocsc()
    h = np.empty(net.n_springs)
    chunk = max(1, 4_000_000 // max(1, Rp.shape[1]))
    for start in range(0, net.n_springs, chunk):
        block = RpT[:, start : start + chunk].toarray()
        h[start : start + chunk] = np.einsum("ij,ij->j", block, solve(block))
    return np.clip(1.0 - h, 0.0, 1.0)
