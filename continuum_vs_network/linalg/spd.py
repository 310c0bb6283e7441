"""Factorisations of a symmetric positive-definite ``W`` (n, n), and the sparse solver choice.

:func:`factor_spd` returns a :class:`Factor` (a solver for ``W s = b``), or None when ``W``
is not positive definite; :func:`factor_spd_or_curvature` also returns directions of
negative curvature read off a failed factorisation. The KKT systems of :mod:`.kkt` are
built on these factors.

Sparse positive-definite factorisations (:func:`factor_spd`) use MKL PARDISO's Cholesky
(``pypardiso``, the optional extra ``continuum_vs_network[pardiso]``) when it is
importable (faster than SuperLU on spring-network Hessians, with half the memory); it
certifies ``W > 0`` by completing. Otherwise, or with the argument
``sparse_solver="superlu"`` (:data:`SPARSE_SOLVERS`, :func:`sparse_backend`), SuperLU;
or, for a matrix whose rows are in a narrow-band order (:func:`banded_pays`, e.g.
:func:`~continuum_vs_network.network.ordering.band_order` on a network of up to ~1e4
nodes), LAPACK's banded Cholesky, which is faster there. A
``rough`` factorisation (an approximate ``W^-1`` serves: a Newton step judged by the true
residual, a preconditioner) is made in float32 where that is accurate: the banded Cholesky
at any size, SuperLU from ``ROUGH_MIN`` rows. The measurements behind these choices and
constants are in ``docs/solver-notes.md#spd``.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .fpenv import flushing_subnormals
from .memo import per_array

__all__ = [
    "BAND_MAX_WORK",
    "DENSE_MAX",
    "ROUGH_MIN",
    "ROUGH_RESIDUAL",
    "ROUGH_SPREAD",
    "SPARSE_SOLVERS",
    "Factor",
    "banded_pays",
    "factor_spd",
    "factor_spd_or_curvature",
    "fixed_vector",
    "sparse_backend",
    "sparse_lu",
]

DENSE_MAX = 400  # below this many unknowns dense LAPACK beats scipy.sparse's overhead
# the most work n (u + 1)^2 (LAPACK pbtrf: about n u^2 flops for lower bandwidth u) at
# which the banded Cholesky beats SuperLU with nested dissection; the work, not n, sets
# the crossover (docs/solver-notes.md#spd-banded)
BAND_MAX_WORK = 1e9
# the choices of a ``sparse_solver`` argument (:func:`sparse_backend`)
SPARSE_SOLVERS = ("auto", "pardiso", "superlu")
# From this many rows a ``rough`` factorisation (factor_spd) is SuperLU in float32: faster,
# and half the memory for values, which coupled learning on a million-node lattice needs
# (docs/solver-notes.md#spd-rough)
ROUGH_MIN = 100_000
ROUGH_RESIDUAL = 1e-2  # a float32 factor must solve a random right-hand side to this
# nor is float32 tried where the diagonal spans more (rods, stiffness over many decades):
# there float32 factorisations often miss ROUGH_RESIDUAL and are made again in float64
ROUGH_SPREAD = 1e6
# below this many rows a ``rough`` banded Cholesky stays in float64: spbtrf's gain is then
# smaller than the extra conjugate-gradient solves its float32 factor costs (a relax of
# 500-1000 coordinates 5-13 % faster, of 2000 5 % slower)
ROUGH_BANDED_MIN = 1000
_EMPTY_INDEX = np.empty(0, dtype=np.int64)
_PARDISO: dict = {}  # the pypardiso module, or False when it does not import (looked up once)


def _pardiso():
    """The ``pypardiso`` module, or None (imported once, lazily)."""
    if "module" not in _PARDISO:
        try:
            import pypardiso  # optional and heavy (MKL): imported on first use

            _PARDISO["module"] = pypardiso
        except (ImportError, OSError):
            _PARDISO["module"] = False
    return _PARDISO["module"] or None


def sparse_backend(sparse_solver: str = "auto") -> str:
    """The sparse positive-definite factorisation that the choice ``sparse_solver`` means:
    "pardiso" or "superlu" (SuperLU, or the banded Cholesky where :func:`banded_pays`).

    ``"auto"``: PARDISO when ``pypardiso`` imports, else SuperLU; ``"pardiso"``: PARDISO
    (ImportError when ``pypardiso`` is missing); ``"superlu"``: SuperLU. ValueError for
    any other name.
    """
    if sparse_solver not in SPARSE_SOLVERS:
        raise ValueError(f"sparse_solver must be one of {SPARSE_SOLVERS}, got {sparse_solver!r}")
    if sparse_solver == "pardiso" and _pardiso() is None:
        raise ImportError("sparse solver 'pardiso' needs pypardiso (pip install pypardiso)")
    if sparse_solver == "auto":
        return "pardiso" if _pardiso() is not None else "superlu"
    return sparse_solver


def _pardiso_spd(W: sp.spmatrix) -> Factor | None:
    """PARDISO Cholesky of symmetric ``W`` (:mod:`.pardiso`: the analysis of each
    structure is kept); None when ``W`` is not positive definite."""
    from . import pardiso  # needs pypardiso: imported only when it is present

    solve = pardiso.factorise(W)
    return None if solve is None else Factor(solve, W.shape[0])


class Factor:
    """A solver for ``W s = b`` (``b`` of shape (n,) or (n, p)).

    Attributes
    ----------
    solve : callable
    n : int
    precondition : callable
        An approximate ``W^-1 b`` for use as a preconditioner: ``solve`` itself, or, for
        the banded Cholesky, the same factor rounded to float32 (relative error ~1e-7;
        faster, where the solve is limited by reading the band from memory).
    approximate : bool
        ``solve`` itself is only float32-accurate (a ``rough`` factor of ``W`` rounded to
        float32): a caller that needs more refines it (Newton: projected CG).
    """

    def __init__(
        self,
        solve: Callable[[NDArray], NDArray],
        n: int,
        precondition: Callable[[NDArray], NDArray] | None = None,
        *,
        approximate: bool = False,
    ) -> None:
        self.solve = solve
        self.n = n
        self.precondition = solve if precondition is None else precondition
        self.approximate = approximate


def _dense(M) -> NDArray:
    return M.toarray() if sp.issparse(M) else np.asarray(M, dtype=np.float64)


def sparse_lu(W: sp.spmatrix, *, ordering: str = "MMD_AT_PLUS_A", symmetric: bool = True):
    """SuperLU factorisation of a square sparse ``W`` (raises RuntimeError when singular).

    ``ordering``: SuperLU ``permc_spec``. Minimum degree on ``W + W^T`` suits symmetric
    stiffness matrices (less fill and faster factorisations than ``COLAMD``).
    ``symmetric``: diagonal pivots in SuperLU's symmetric mode, which keep that ordering
    (for symmetric positive-definite ``W``; partial pivoting breaks it and is much slower);
    False: partial pivoting. Measurements: ``docs/solver-notes.md#spd-superlu``.
    """
    pivots: dict = (
        {"diag_pivot_thresh": 0.0, "options": {"SymmetricMode": True}} if symmetric else {}
    )
    return spla.splu(sp.csc_matrix(W), permc_spec=ordering, **pivots)


def banded_pays(n: int, bandwidth: int) -> bool:
    """True when a banded Cholesky of an (n, n) matrix of lower ``bandwidth`` is expected to
    beat SuperLU: ``n (u + 1)^2 <= BAND_MAX_WORK`` and ``u + 1 <= 3 sqrt(n)`` (a 2D
    network's band order; wider bands, e.g. of an unordered matrix, go to SuperLU)."""
    width = bandwidth + 1
    return n * width**2 <= BAND_MAX_WORK and width <= 3.0 * np.sqrt(n)


def _banded_cholesky(
    W: sp.spmatrix, *, rough: bool = False, rung: bool = False
) -> Factor | bool | None:
    """LAPACK banded Cholesky of sparse symmetric ``W`` when :func:`banded_pays` for its
    lower bandwidth: a Factor, or None when ``W`` is not positive definite (pbtrf met a
    non-positive pivot, or ``W`` is not finite); False when the band is too wide.

    ``rough`` (from ``ROUGH_BANDED_MIN`` rows, the diagonal spanning at most
    ``ROUGH_SPREAD``): first the band rounded to
    float32 (:func:`_banded_float32`); where that fails or is not accurate, float64
    decides, except that with ``rung`` (see :func:`factor_spd`) a non-positive float32
    pivot is final.
    """
    W = sp.csr_matrix(W)
    layout = _band_layout(W)
    if layout is None:  # duplicates summed on a copy, the caller's W kept
        W = W.copy()
        W.sum_duplicates()
        layout = _band_layout(W)
    n = W.shape[0]
    width, lower, flat, diagonal = layout
    if not banded_pays(n, width):
        return False
    if not np.all(np.isfinite(W.data)):
        return None  # LAPACK's pivot test lets NaN through
    values = W.data[lower]
    if rough and n >= ROUGH_BANDED_MIN and _spread(values[diagonal], n) <= ROUGH_SPREAD:
        factor = _banded_float32(W, _band(values, flat, width, n, np.float32))
        if isinstance(factor, Factor):
            return factor
        if factor is None and rung:
            return None
    band = _band(values, flat, width, n, np.float64)
    c, info = sla.lapack.dpbtrf(band, lower=1, overwrite_ab=1)
    if info:
        return None

    def solve(b: NDArray) -> NDArray:
        # LAPACK directly: scipy's cho_solve_banded checks cost as much as the solve on
        # small networks, and a learning step's chord iteration makes several solves
        b = np.asarray(b, dtype=np.float64)
        if b.shape[:1] != (n,) or b.ndim > 2:
            raise ValueError(f"right-hand side must be ({n},) or ({n}, k), got {b.shape}")
        x, info = sla.lapack.dpbtrs(c, b, lower=1)
        if info:
            raise ValueError(f"dpbtrs: illegal argument {-info}")
        return x

    if n < ROUGH_BANDED_MIN:
        # the float64 solve preconditions too: conjugate gradients then meet their
        # tolerance in fewer iterations than a float32 solve saves
        return Factor(solve, n)
    rounded = []  # the factor in float32, made when first preconditioning

    def precondition(b: NDArray) -> NDArray:
        if not rounded:
            rounded.append(np.asfortranarray(c, dtype=np.float32))
        x, info = sla.lapack.spbtrs(rounded[0], np.asarray(b, dtype=np.float32), lower=1)
        if info:
            raise ValueError(f"spbtrs: illegal argument {-info}")
        return x.astype(np.float64)

    return Factor(solve, n, precondition)


def _band_layout(W: sp.csr_matrix) -> tuple[int, NDArray, NDArray, NDArray] | None:
    """Where the stored entries of ``W`` (n, n) go in LAPACK's lower band layout: its
    lower bandwidth, the positions (into ``W.data``) of the entries on or below the
    diagonal, their column-major positions in the (width + 1, n) band, and which of those
    are on the diagonal; None when ``W`` is not in canonical format.

    Kept per structure (``W.indptr``, checked against ``W.indices``): a Newton solve
    factorises matrices of one pattern many times, and finding the layout is a large
    part of the factorisation's time outside LAPACK. Entries are written in one flat step
    (faster than a 2D scatter; ``docs/solver-notes.md#spd-banded``)."""
    store = per_array(W.indptr, "band_layout")
    hit = store.get("layout")
    if hit is not None and np.array_equal(hit[0], W.indices):
        return hit[1:]
    if not W.has_canonical_format:
        return None
    n = W.shape[0]
    offset = np.repeat(np.arange(n), np.diff(W.indptr)) - W.indices
    width = int(offset.max(initial=0))
    if not banded_pays(n, width):  # nothing kept (at 1e6 nodes it would be ~0.4 GB)
        return width, _EMPTY_INDEX, _EMPTY_INDEX, _EMPTY_INDEX
    lower = np.flatnonzero(offset >= 0)
    offset = offset[lower]
    flat = offset + (width + 1) * W.indices[lower].astype(np.int64)
    layout = (width, lower, flat, np.flatnonzero(offset == 0))
    store["layout"] = (W.indices.copy(), *layout)
    return layout


def _band(values: NDArray, flat: NDArray, width: int, n: int, dtype: type) -> NDArray:
    """LAPACK's lower band layout (width + 1, n), column-major, of ``dtype``, holding
    ``values`` at the column-major positions ``flat`` (:func:`_band_layout`; rounded once,
    where float32)."""
    band = np.zeros((width + 1, n), dtype=dtype, order="F")
    band.T.reshape(-1)[flat] = values  # band.T is C-contiguous: reshape gives a view
    return band


def _spread(diagonal: NDArray, n: int) -> float:
    """``max |d| / min |d|`` of the diagonal entries ``diagonal`` of an (n, n) matrix
    (inf when one is zero, or missing: fewer than ``n`` given)."""
    d = np.abs(diagonal)
    return float(d.max() / d.min()) if d.size == n and d.min() > 0 else np.inf


def _banded_float32(W: sp.csr_matrix, band: NDArray) -> Factor | bool | None:
    """The banded Cholesky of ``W`` (its lower ``band`` in LAPACK's layout: float32,
    factorised in place, or float64, left as it is and rounded to float32), solves taking
    and returning float64; None when it meets a non-positive pivot (``W`` indefinite, or
    positive definite only beyond float32's reach); False when the band leaves float32's
    range or the factor does not solve to ``ROUGH_RESIDUAL`` (:func:`_accurate`).

    LAPACK's spbtrf runs faster than dpbtrf (its blocks vectorise twice as wide), as the
    float32 SuperLU of ``ROUGH_MIN`` rows does (``docs/solver-notes.md#spd-rough``).
    """
    rounded = np.asfortranarray(band, dtype=np.float32)
    if not np.all(np.isfinite(rounded)):  # beyond float32's range
        return False
    with flushing_subnormals():
        c, info = sla.lapack.spbtrf(rounded, lower=1, overwrite_ab=1)
    if info:
        return None

    def solve(b: NDArray) -> NDArray:
        x, info = sla.lapack.spbtrs(c, np.asarray(b, dtype=np.float32), lower=1)
        if info:
            raise ValueError(f"spbtrs: illegal argument {-info}")
        return x.astype(np.float64)

    return Factor(solve, W.shape[0], approximate=True) if _accurate(W, solve) else False


def factor_spd(
    W: sp.spmatrix | NDArray,
    *,
    ordered: bool = False,
    certify: bool = True,
    rough: bool = False,
    rung: bool = False,
    sparse_solver: str = "auto",
) -> Factor | None:
    """Factorise symmetric ``W`` (n, n); None when it is not positive definite.

    Dense Cholesky up to ``DENSE_MAX`` rows; above, a banded Cholesky when the rows are in
    a narrow-band order (:func:`banded_pays`; it completes only for ``W > 0``; certifying
    calls only), else SuperLU
    with diagonal pivots in symmetric mode, whose ``U`` diagonal carries the inertia (a
    positive diagonal with symmetric pivots proves ``W > 0``), or PARDISO's Cholesky
    (``sparse_solver``, :func:`sparse_backend`: "auto" takes PARDISO when ``pypardiso``
    imports; it orders by METIS and ignores ``ordered``). ``ordered``: the
    rows are already in a fill-reducing order (natural order is kept); otherwise minimum
    degree on ``W``. ``certify=False`` skips reading SuperLU's ``U`` diagonal (a copy of
    ``U``) for a ``W`` positive definite by
    construction (a stiffness with rigid motion removed); only exact singularity then
    returns None. ``rough``: an approximate ``W^-1`` serves the caller (a Newton or chord
    step judged by the true residual, a preconditioner): the banded Cholesky, and from
    ``ROUGH_MIN`` rows SuperLU, then factorise ``W`` rounded to float32 where it solves to
    ``ROUGH_RESIDUAL`` (:func:`_banded_float32`, :func:`factor_spd_or_curvature`).
    ``rung``: ``W`` is a rung of the Levenberg-Marquardt ladder
    (:func:`~continuum_vs_network.network.hessian_ladder.factor_positive_model`), whose
    failure sends the caller to a 10x larger shift: a non-positive pivot of the float32
    banded Cholesky is then final, without the float64 factorisation (``W`` is indefinite,
    or within float32's rounding of singular, where the step along its near-null direction
    is one a line search cuts; the same iterations and equilibria, less time:
    ``docs/solver-notes.md#spd-rung``).
    """
    if sparse_solver not in SPARSE_SOLVERS:  # checked at every size, not only sparse ones
        raise ValueError(f"sparse_solver must be one of {SPARSE_SOLVERS}, got {sparse_solver!r}")
    n = W.shape[0]
    if n <= DENSE_MAX:
        try:
            c = sla.cho_factor(_dense(W), lower=True, check_finite=False)
        except (sla.LinAlgError, ValueError):
            return None
        return Factor(lambda b: sla.cho_solve(c, b, check_finite=False), n)
    if sparse_backend(sparse_solver) == "pardiso":
        return _pardiso_spd(W)
    if certify:
        # a failed one needs no SuperLU: W is not > 0
        banded = _banded_cholesky(W, rough=rough, rung=rung)
        if banded is not False:
            return banded
        return factor_spd_or_curvature(
            W, ordered=ordered, rough=rough, sparse_solver=sparse_solver
        )[0]
    try:
        lu = sparse_lu(W, ordering="NATURAL" if ordered else "MMD_AT_PLUS_A")
    except RuntimeError:  # exactly singular
        return None
    return Factor(lu.solve, n) if np.array_equal(lu.perm_r, lu.perm_c) else None


def factor_spd_or_curvature(
    W: sp.spmatrix,
    *,
    ordered: bool = False,
    count: int = 2,
    rough: bool = False,
    sparse_solver: str = "auto",
) -> tuple[Factor | None, NDArray | None]:
    """:func:`factor_spd` of sparse symmetric ``W`` (n, n), and when ``W`` is indefinite
    up to ``count`` directions of negative curvature read off the same factorisation.

    Returns ``(factor, None)`` when ``W > 0``; ``(None, V)`` with ``V`` (n, k), each column
    ``v`` with ``v^T W v < 0`` (checked), when SuperLU's symmetric factorisation
    ``P^T W P = L D L^T`` shows negative pivots: ``v = P L^-T e_i`` for the most negative
    ``d_i`` gives ``v^T W v = d_i`` (one triangular solve each); ``(None, None)`` when no
    direction is known (singular, pivots left the diagonal, PARDISO, or dense sizes). A
    narrow-band ``W`` (:func:`banded_pays`) is first given to the banded Cholesky; SuperLU
    runs only when that fails.

    ``rough``, a diagonal spanning at most ``ROUGH_SPREAD`` (max / min): a banded
    Cholesky in float32 (:func:`_banded_float32`); else, from ``ROUGH_MIN`` rows, first
    SuperLU of ``W`` rounded to float32
    (solutions off by up to ~1e-7 times the condition number: 3e-4 on a 1e6-node lattice).
    Its positive pivots certify ``W > 0`` up to float32 round-off (a negative eigenvalue
    above ~-1e-7 of the largest may pass) when it also solves a fixed random right-hand
    side to ``ROUGH_RESIDUAL``; a direction of negative curvature it finds (checked in
    float64) proves ``W`` indefinite. Otherwise the float64 factorisation decides.
    """
    n = W.shape[0]
    if n <= DENSE_MAX or sparse_backend(sparse_solver) == "pardiso":
        return factor_spd(W, ordered=ordered, sparse_solver=sparse_solver), None
    banded = _banded_cholesky(W, rough=rough)
    if isinstance(banded, Factor):
        return banded, None
    if rough and n >= ROUGH_MIN and _diagonal_spread(W) <= ROUGH_SPREAD:
        factor, directions = _superlu(W, ordered, count, np.float32)
        if factor is not None or directions is not None:
            return factor, directions  # positive and accurate, or proven indefinite
    return _superlu(W, ordered, count, np.float64)


def _diagonal_spread(W: sp.spmatrix) -> float:
    """``max |W_ii| / min |W_ii|`` (inf with a zero on the diagonal)."""
    return _spread(W.diagonal(), W.shape[0])


def _accurate(W: sp.spmatrix, solve: Callable[[NDArray], NDArray]) -> bool:
    """True when ``solve`` solves ``W s = b`` for a fixed random ``b`` to ``ROUGH_RESIDUAL``."""
    b = fixed_vector(W.shape[0])
    return bool(np.linalg.norm(W @ solve(b) - b) <= ROUGH_RESIDUAL * np.linalg.norm(b))


@functools.lru_cache(maxsize=8)
def fixed_vector(n: int) -> NDArray:
    """A fixed generic vector (n,): standard normal draws of seed 0, read-only, kept for
    the last few sizes (drawing it is a noticeable part of a small relax).

    The right-hand side :func:`_accurate` probes a rough factor with, and the start vector
    of every Krylov eigensolve (``eigsh(..., v0=fixed_vector(n))``): scipy's default start
    is drawn from fresh entropy at every call, and with it the computed mode changed by
    ~1e-15. The accuracy scene's continuum Newmark order varied by 2e-4 between main jobs
    (1.99975-1.99993).
    """
    b = np.random.default_rng(0).standard_normal(n)
    b.setflags(write=False)
    return b


def _superlu(
    W: sp.spmatrix, ordered: bool, count: int, dtype: type
) -> tuple[Factor | None, NDArray | None]:
    """SuperLU with diagonal pivots of ``W`` in ``dtype`` (float32: rounded, solves taking and
    returning float64): :func:`factor_spd_or_curvature`'s ``(factor, directions)``. A
    float32 factor is returned only when it is :func:`_accurate`."""
    n = W.shape[0]
    values = W
    if dtype == np.float32:
        values = sp.csc_matrix(W, dtype=np.float32)
        if not np.all(np.isfinite(values.data)):
            return None, None
    # float32 elimination can reach subnormal numbers, much slower in SuperLU (.fpenv)
    flush = flushing_subnormals if dtype == np.float32 else contextlib.nullcontext
    try:
        with flush():
            lu = sparse_lu(values, ordering="NATURAL" if ordered else "MMD_AT_PLUS_A")
    except RuntimeError:  # exactly singular
        return None, None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None, None
    solve = lu.solve
    if dtype == np.float32:

        def solve(b: NDArray) -> NDArray:
            with flushing_subnormals():
                x = lu.solve(np.asarray(b, dtype=np.float32))
            return x.astype(np.float64)

    d = lu.U.diagonal()  # a copy of U: dropped before directions are sought
    if np.all(d > 0):
        if dtype == np.float32 and not _accurate(W, solve):
            return None, None
        return Factor(solve, n, approximate=dtype == np.float32), None
    # W^-1 P^T L e_i = P U^-1 e_i = P L^-T e_i / d_i (U = D L^T): a solve with lu itself
    L = lu.L
    directions = []
    for i in np.argsort(d)[:count]:
        if d[i] >= 0:
            break
        column = L[:, [i]].toarray().ravel()
        v = solve(column[lu.perm_r])
        if np.all(np.isfinite(v)) and float(v @ (W @ v)) < 0:
            directions.append(v)
    return None, (np.column_stack(directions) if directions else None)
