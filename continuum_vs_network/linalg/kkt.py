"""Symmetric saddle-point (KKT) systems: factorise once, solve many times, report inertia.

The system is::

    [[W, A^T],   [x,     [b,
     [A,  0 ]] .  y]  =   c]

with ``W`` symmetric (n, n) (``scipy.sparse`` or a dense array) and ``A`` (m, n) (sparse,
dense or None for m = 0). Nothing here knows about springs or finite elements: the network
equilibrium solvers (Newton steps, the learning tracker, sensitivities) and the continuum's
linear finite-element systems with constraints use the same path.

Two factorisations:

* **range space** (``W`` positive definite): one Cholesky / symmetric SuperLU factorisation
  of ``W``, ``Z = W^-1 A^T`` (m solves) and the small Schur complement ``S = A Z``. Then
  ``y = S^-1 (A W^-1 b - c)``, ``x = W^-1 b - Z y``. By Haynsworth,
  ``inertia(K) = inertia(W) + inertia(-S) = (n + n_neg(S), n_pos(S), n_zero(S))``.
* **full** (``W`` indefinite or singular): an LU of the whole matrix. Its inertia comes
  from a dense ``LDL^T`` (Bunch-Kaufman, small systems) or from SuperLU's diagonal when the
  pivots stayed symmetric (``perm_r == perm_c``: then ``U``'s diagonal is ``D`` of
  ``P K P^T = L D L^T``, Sylvester); otherwise it is unknown (None).

Positive-definite factorisations of ``W`` (dense, banded or SuperLU Cholesky, PARDISO)
and the choice among them are in :mod:`.spd`; their names are re-exported here.

A constrained minimum is strict exactly when ``inertia(K) == (n, m, 0)`` (the reduced
Hessian is positive definite and ``A`` has full rank).

Examples
--------
>>> import numpy as np, scipy.sparse as sp
>>> W = sp.csr_matrix(np.diag([2.0, 1.0]))
>>> A = np.array([[1.0, 1.0]])
>>> kkt = factor_kkt(W, A)
>>> x, y = kkt.solve(np.zeros(2), np.array([3.0]))   # min x^T W x / 2 s.t. x0 + x1 = 3
>>> np.round(x, 12).tolist(), kkt.inertia
([1.0, 2.0], Inertia(positive=2, negative=1, zero=0))
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .spd import (
    BAND_MAX_WORK,
    DENSE_MAX,
    SPARSE_SOLVERS,
    Factor,
    _dense,
    banded_pays,
    factor_spd,
    factor_spd_or_curvature,
    sparse_backend,
    sparse_lu,
)

__all__ = [
    "BAND_MAX_WORK",
    "DENSE_MAX",
    "KKT",
    "SPARSE_SOLVERS",
    "Factor",
    "Inertia",
    "banded_pays",
    "factor_kkt",
    "factor_spd",
    "factor_spd_or_curvature",
    "schur_solve",
    "sparse_backend",
    "sparse_lu",
]


class Inertia(NamedTuple):
    """Numbers of positive, negative and zero eigenvalues of a symmetric matrix."""

    positive: int
    negative: int
    zero: int


def _inertia_of_values(values: NDArray, scale: float) -> Inertia:
    tiny = 1e-13 * max(scale, 1e-300)
    return Inertia(
        int(np.sum(values > tiny)), int(np.sum(values < -tiny)), int(np.sum(np.abs(values) <= tiny))
    )


class KKT:
    """A factorised KKT matrix ``[[W, A^T], [A, 0]]``; build it with :func:`factor_kkt`.

    Attributes
    ----------
    n, m : int
        Sizes of ``W`` and of the constraint block.
    inertia : Inertia or None
        Of the whole KKT matrix; None when the factorisation used does not reveal it.
    range_space : bool
        True when ``W`` itself was positive definite (range-space form).
    """

    def __init__(
        self,
        n: int,
        m: int,
        solve: Callable[[NDArray, NDArray], tuple[NDArray, NDArray]],
        inertia: Inertia | None,
        range_space: bool,
    ) -> None:
        self.n, self.m = n, m
        self._solve = solve
        self.inertia = inertia
        self.range_space = range_space

    @property
    def is_minimum(self) -> bool | None:
        """True when the inertia is ``(n, m, 0)``: positive-definite reduced Hessian and
        full-rank ``A`` (a strict constrained minimum); None when the inertia is unknown."""
        if self.inertia is None:
            return None
        return self.inertia == Inertia(self.n, self.m, 0)

    def solve(self, b: NDArray, c: NDArray | None = None) -> tuple[NDArray, NDArray]:
        """Solve ``W x + A^T y = b``, ``A x = c`` (``c`` default 0).

        ``b`` (n,) or (n, p); ``c`` (m,) or (m, p). Returns ``(x, y)`` of matching shapes.
        """
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.n:
            raise ValueError(f"b must have {self.n} rows, got shape {b.shape}")
        if c is None:
            c = np.zeros((self.m, *b.shape[1:]))
        c = np.asarray(c, dtype=np.float64)
        if c.shape[0] != self.m:
            raise ValueError(f"c must have {self.m} rows, got shape {c.shape}")
        return self._solve(b, c)


def schur_solve(
    z: NDArray, A: sp.spmatrix | NDArray, Z: NDArray, S, c: NDArray
) -> tuple[NDArray, NDArray]:
    """The range-space solve of ``[[W, A^T], [A, 0]] [x; y] = [b; c]`` given ``z = W^-1 b``.

    ``y = S^-1 (A z - c)``, ``x = z - Z y`` with ``Z = W^-1 A^T`` (n, m) and ``S = A Z``
    (m, m: an array, or its ``scipy.linalg.lu_factor``). The Schur-complement reuse: with
    ``Z`` and ``S`` formed once for many constraint rows, the system of any subset of them
    is ``A[rows]``, ``Z[:, rows]``, ``S[rows][:, rows]``: no further solve with ``W``.
    ``z`` (n,) or (n, p), ``c`` (m,) or (m, p).
    """
    r = A @ z - c
    if isinstance(S, tuple):  # LAPACK getrs directly, without lu_solve's per-call overhead
        y, info = sla.lapack.dgetrs(S[0], S[1], r)
        if info:
            raise ValueError(f"getrs: illegal argument {-info}")
    else:
        y = np.linalg.solve(S, r)
    return z - Z @ y, y


def range_space(factor: Factor, A: sp.spmatrix | NDArray | None) -> KKT:
    """The KKT system of a positive-definite ``W`` given as a solver, and ``A``.

    Raises ``numpy.linalg.LinAlgError`` when ``A`` is rank deficient (singular ``S``).
    """
    return range_space_solve(factor, A)[0]


def range_space_solve(
    factor: Factor,
    A: sp.spmatrix | NDArray | None,
    b: NDArray | None = None,
    c: NDArray | None = None,
) -> tuple[KKT, tuple[NDArray, NDArray] | None]:
    """:func:`range_space` and, when ``b`` (n,) is given, the solution ``(x, y)`` of its
    system with right-hand side ``(b, c)`` (``c`` (m,), default 0), from one solve with
    ``factor`` of ``m + 1`` columns (cheaper than separate solves; see
    ``docs/solver-notes.md#kkt``).
    """
    n = factor.n
    if A is None or A.shape[0] == 0:

        def solve_unconstrained(b: NDArray, c: NDArray) -> tuple[NDArray, NDArray]:
            return np.asarray(factor.solve(b)), np.zeros((0, *b.shape[1:]))

        kkt = KKT(n, 0, solve_unconstrained, Inertia(n, 0, 0), True)
        return kkt, None if b is None else kkt.solve(b, c)
    m = A.shape[0]
    rhs = _dense(A.T).reshape(n, m)
    if b is not None:
        rhs = np.column_stack([rhs, np.asarray(b, dtype=np.float64)])
    sol = np.asarray(factor.solve(rhs)).reshape(n, rhs.shape[1])
    Z = sol[:, :m]
    S = np.asarray(A @ Z).reshape(m, m)
    values = np.linalg.eigvalsh(0.5 * (S + S.T))
    s_inertia = _inertia_of_values(values, float(np.max(np.abs(values))))
    if s_inertia.zero:
        raise np.linalg.LinAlgError("constraints are rank deficient (singular A W^-1 A^T)")
    # S = A Z itself, not its symmetric part: then A x = c holds to round-off for any
    # accuracy of the solve (a float32 preconditioner's S is asymmetric by ~1e-7)
    lu_S = sla.lu_factor(S, check_finite=False)

    def solve(b: NDArray, c: NDArray) -> tuple[NDArray, NDArray]:
        return schur_solve(np.asarray(factor.solve(b)), A, Z, lu_S, c)

    inertia = Inertia(n + s_inertia.negative, s_inertia.positive, 0)
    kkt = KKT(n, m, solve, inertia, True)
    if b is None:
        return kkt, None
    c = np.zeros(m) if c is None else np.asarray(c, dtype=np.float64)
    return kkt, schur_solve(sol[:, m], A, Z, lu_S, c)


def factor_kkt(
    W: sp.spmatrix | NDArray,
    A: sp.spmatrix | NDArray | None = None,
    *,
    ordered: bool = False,
    sparse_solver: str = "auto",
) -> KKT:
    """Factorise ``[[W, A^T], [A, 0]]``: range space when ``W > 0``, else the full matrix.

    Parameters
    ----------
    W : (n, n) symmetric sparse matrix or array
    A : (m, n) sparse matrix or array, or None
    ordered : bool
        ``W``'s rows are already in a fill-reducing order.
    sparse_solver : {"auto", "pardiso", "superlu"}
        The factorisation of ``W`` (:func:`~.spd.factor_spd`; "auto": PARDISO when
        ``pypardiso`` imports, else SuperLU or the banded Cholesky). The full matrix, when
        ``W`` is not positive definite, is always SuperLU's.

    Raises ``numpy.linalg.LinAlgError`` when the KKT matrix is singular.
    """
    n = W.shape[0]
    m = 0 if A is None else A.shape[0]
    if A is not None and A.shape[1] != n:
        raise ValueError(f"A must have {n} columns, got shape {A.shape}")
    factor = factor_spd(W, ordered=ordered, sparse_solver=sparse_solver)
    if factor is not None:
        try:
            return range_space(factor, A)
        except np.linalg.LinAlgError:
            if m == 0:
                raise
    size = n + m
    if size <= DENSE_MAX:
        K = np.zeros((size, size))
        K[:n, :n] = _dense(W)
        if m:
            K[n:, :n] = _dense(A)
            K[:n, n:] = _dense(A).T
        lu, d, _ = sla.ldl(K, lower=True, check_finite=False)
        del lu
        values = np.concatenate([np.linalg.eigvalsh(d[i:j, i:j]) for i, j in _blocks(d)])
        inertia = _inertia_of_values(values, float(np.max(np.abs(K))) if size else 1.0)
        if inertia.zero:
            raise np.linalg.LinAlgError("singular KKT matrix")
        piv = sla.lu_factor(K, check_finite=False)

        def solve_dense(b: NDArray, c: NDArray) -> tuple[NDArray, NDArray]:
            sol = sla.lu_solve(piv, np.concatenate([b, c]), check_finite=False)
            return sol[:n], sol[n:]

        return KKT(n, m, solve_dense, inertia, False)
    blocks = [[sp.csc_matrix(W), None if not m else sp.csc_matrix(A).T]]
    if m:
        blocks.append([sp.csc_matrix(A), None])
    K = sp.bmat(blocks, format="csc")
    inertia = None
    try:
        lu = spla.splu(K, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        if np.array_equal(lu.perm_r, lu.perm_c):
            diag = lu.U.diagonal()
            inertia = _inertia_of_values(diag, float(np.max(np.abs(diag))))
    except RuntimeError:
        lu = None
    if lu is None or (inertia is not None and inertia.zero):
        try:
            lu = spla.splu(K)
        except RuntimeError as err:
            raise np.linalg.LinAlgError(f"singular KKT matrix: {err}") from err
        inertia = None

    def solve_sparse(b: NDArray, c: NDArray) -> tuple[NDArray, NDArray]:
        sol = lu.solve(np.concatenate([b, c]))
        return sol[:n], sol[n:]

    return KKT(n, m, solve_sparse, inertia, False)


def _blocks(d: NDArray) -> list[tuple[int, int]]:
    """``(start, stop)`` of the 1x1 and 2x2 diagonal blocks of an LDL^T factor ``d``."""
    out, i, size = [], 0, d.shape[0]
    while i < size:
        step = 2 if i + 1 < size and d[i + 1, i] != 0.0 else 1
        out.append((i, i + step))
        i += step
    return out
