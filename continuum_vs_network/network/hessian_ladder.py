"""A positive-definite model of the Lagrangian Hessian for the sparse Newton
(:mod:`.newton`): the exact Hessian where it is positive definite, else the same
with a larger clamp augmentation, else a Levenberg-Marquardt shift that grows until the
factorisation succeeds (the ladder), steered by directions of negative curvature.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.kkt import DENSE_MAX, Factor, factor_spd, factor_spd_or_curvature
from .constraints import Problem
from .energy import HessianPattern
from .lagrangian import lagrangian_blocks

__all__ = [
    "DAMP_MIN",
    "PositiveModel",
    "assemble_hessian",
    "factor_positive_model",
    "marquardt_scale",
    "ritz_lowest",
    "shifted",
]

DAMP_MIN = 1e-6  # the least Levenberg-Marquardt shift (relative to diag W)
_LANCZOS = 10  # Lanczos steps of the bound below which no rung of the ladder is tried


class PositiveModel(NamedTuple):
    """What :func:`factor_positive_model` made: ``factor`` of ``matrix`` (None when no
    shift up to 1e8 made it positive definite), the augmentation ``rho`` and the shift it
    took, whether ``matrix`` is the exact Hessian (shift 0), and the direction of most
    negative curvature (n,) the failed exact factorisation gave (None without one)."""

    factor: Factor | None
    rho: float
    shift: float
    exact: bool
    matrix: sp.csr_matrix | NDArray | None
    negative: NDArray | None


def assemble_hessian(pattern: HessianPattern, blocks: NDArray) -> sp.csr_matrix | NDArray:
    """Dense below ``DENSE_MAX`` coordinates (no sparse overhead), CSR above."""
    if pattern.size <= DENSE_MAX:
        return pattern.assemble_dense(blocks)
    return pattern.assemble(blocks)


def factor_positive_model(
    problem: Problem,
    pattern: HessianPattern,
    x: NDArray,
    lam: NDArray,
    rho: float,
    shift: float,
    *,
    indefinite: tuple[float, NDArray] | None = None,
) -> PositiveModel:
    """Factorise a positive-definite Hessian model: exact if possible, else shifted.

    Order: the exact Hessian (when ``shift`` is 0), also with a larger augmentation ``rho``
    when there are clamps (at a stable constrained minimum a large enough ``rho`` makes it
    positive definite, Finsler's lemma, and the step does not depend on ``rho``; that second
    factorisation is skipped when a direction of negative curvature read off the first,
    :func:`~..linalg.kkt.factor_spd_or_curvature`, stays negative under the larger ``rho``);
    then the exact Hessian plus a Levenberg-Marquardt shift ``mu diag(W)`` that starts at
    the ``mu`` passed in (at least 1e-6; after a failed exact factorisation at least
    :func:`_shift_estimate`) and grows (100-fold from ``DAMP_MIN``, 10-fold from an estimate
    or from a shift carried over from the last iterations) until the
    factorisation is positive definite (the shift, not clipping each spring's negative
    tangential curvature, which creeps: ``docs/solver-notes.md#ladder-tangential-clipping``).
    Where a direction of negative curvature is known, the rungs below the
    negative of the lowest Ritz value from it (:func:`ritz_lowest`, 10 Lanczos steps),
    which cannot be positive definite, are skipped: the same shifts and iterates, fewer
    failed factorisations. The bound is made at once for a direction conjugate gradients
    met, else after the first failed rung (where the first rungs usually succeed, a bound
    made at once costs more than it saves; ``docs/solver-notes.md#ladder-ritz``).

    ``indefinite``: ``(s, d)`` when conjugate gradients met negative curvature along
    ``d`` (n,) on ``W + s D`` (``A d = 0``); ``s`` replaces ``shift``. No factorisation
    bound to fail is made: the ladder starts one rung above ``s``, or at the estimate from ``d``; at
    ``s = 0`` the exact Hessian is not factorised, nor with a larger ``rho``
    (``rho A^T A`` adds nothing along ``d``; ``docs/solver-notes.md#ladder-indefinite``).

    Returns a :class:`PositiveModel`; its ``negative`` (the direction of most negative
    curvature in the shift's metric) only without clamps (``lam`` empty: with clamps ``W``
    carries ``rho A^T A`` and the direction is not in their tangent space). The exact
    Hessian is used whenever it is positive definite, so the last iterations are pure
    Newton steps.
    """
    W = assemble_hessian(pattern, lagrangian_blocks(problem, x, lam, rho))
    directions = None
    if indefinite is not None:  # the shift CG failed at, and its direction
        shift, directions = indefinite[0], indefinite[1][:, None]
    if shift == 0.0:
        if directions is None:
            factor, directions = _factor_or_curvature(W, pattern, problem.sparse_solver)
            if factor is not None:
                return PositiveModel(factor, rho, 0.0, True, W, None)
        if lam.size:
            d = np.maximum(problem.net.lengths(x, problem.clamp_springs), 1e-300)
            new_rho = max(10 * rho, 10 * float(np.max(np.abs(lam) / d)))
            # rho A^T A adds (new_rho - rho) |A v|^2 to the curvature along v: if a known
            # negative direction stays negative, factorising again cannot succeed (the larger
            # rho is kept: it helps later reuse of the factorisation)
            futile = directions is not None and _still_negative(
                W, directions, problem, x, pattern, new_rho - rho
            )
            rho = new_rho
            W = assemble_hessian(pattern, lagrangian_blocks(problem, x, lam, rho))
            factor = (
                None
                if futile
                else factor_spd(
                    W, ordered=pattern.ordered, rough=True, sparse_solver=problem.sparse_solver
                )
            )
            if factor is not None:
                return PositiveModel(factor, rho, 0.0, True, W, None)
    # Marquardt's scaling: shift each coordinate by its own stiffness, so that stiff rods do
    # not freeze soft springs (stiffness ratios up to 1e12 are supported). Without a known
    # direction of negative curvature the shift grows by 100s from DAMP_MIN; with one, from
    # the estimate of _shift_estimate by 10s; from a shift carried over (a decayed one) by
    # 10s too: by 100s it climbs back over the shift needed and crawls
    # (docs/solver-notes.md#ladder-growth)
    scale = marquardt_scale(W)
    shift = max(shift, DAMP_MIN)
    growth = 10.0 if shift > DAMP_MIN else 100.0
    if indefinite is not None and indefinite[0] > 0.0:
        shift *= growth
    negative = lowest = None
    if directions is not None:
        estimate, lowest = _shift_estimate(W, directions, scale)
        if estimate > shift:
            shift, growth = estimate, 10.0
        if estimate > 0.0 and indefinite is None and not lam.size:
            negative = lowest

    def ritz_bound() -> float:
        """No shift below it makes ``W`` positive definite: those rungs are skipped."""
        return -0.99 * ritz_lowest(W, scale, lowest) if lowest is not None else 0.0

    # at once from conjugate gradients' direction (its Rayleigh quotient, not an
    # eigenvector's, left most first rungs to fail), else after the first failed rung
    bound = ritz_bound() if indefinite is not None else None
    while shift <= 1e8:
        if bound is None or shift >= bound:
            model = shifted(W, shift, scale)
            factor = factor_spd(
                model,
                ordered=pattern.ordered,
                rough=True,
                rung=True,
                sparse_solver=problem.sparse_solver,
            )
            if factor is not None:
                return PositiveModel(factor, rho, shift, False, model, negative)
            if bound is None:
                bound = ritz_bound()
        shift *= growth
    return PositiveModel(None, rho, shift, False, None, None)


def marquardt_scale(W: sp.spmatrix | NDArray) -> NDArray:
    """``|W_ii|`` (n,), zeros replaced by the largest entry (or 1): the metric of the
    Levenberg-Marquardt shift ``W + shift diag(scale)``."""
    diag = np.abs(W.diagonal())  # ndarray and sparse alike
    return np.where(diag > 0, diag, max(float(diag.max(initial=0.0)), 1.0))


def shifted(W: sp.csr_matrix | NDArray, shift: float, scale: NDArray) -> sp.csr_matrix | NDArray:
    """``W + shift diag(scale)`` as a new matrix of ``W``'s kind (``W`` is kept).

    CSR: a copy whose stored diagonal entries are raised, the same numbers as the sparse
    sum ``W + sp.diags(shift * scale)`` without building and merging a second matrix (the
    sparse Newton makes many such models a solve); the sum where a diagonal entry is not
    stored.
    """
    if isinstance(W, np.ndarray):
        model = W.copy()
        model.flat[:: W.shape[0] + 1] += shift * scale
        return model
    W = sp.csr_matrix(W)
    n = W.shape[0]
    rows = np.repeat(np.arange(n), np.diff(W.indptr))
    slots = np.flatnonzero(W.indices == rows)
    if slots.size != n:  # a diagonal entry missing (or duplicated): the sparse sum
        return sp.csr_matrix(W + sp.diags(shift * scale))
    model = W.copy()
    model.data[slots] += shift * scale
    return model


def _factor_or_curvature(
    W, pattern: HessianPattern, sparse_solver: str = "auto"
) -> tuple[Factor | None, NDArray | None]:
    """``factor_spd`` of ``W``, with directions of negative curvature when it fails (sparse).

    The directions come from SuperLU in nested-dissection order also where the rows are in
    band order (:meth:`~.energy.HessianPattern.nested_rows`): which negative
    pivots it finds depends on the order, and the shift estimated from them steers the
    iterations.
    """
    if isinstance(W, np.ndarray):
        return factor_spd(W, ordered=pattern.ordered, sparse_solver=sparse_solver), None
    rows = pattern.nested_rows()
    if rows is None:
        return factor_spd_or_curvature(
            W, ordered=pattern.ordered, rough=True, sparse_solver=sparse_solver
        )
    factor = factor_spd(W, ordered=True, rough=True, sparse_solver=sparse_solver)
    if factor is not None:
        return factor, None
    _, nested = factor_spd_or_curvature(W[rows][:, rows], ordered=True, sparse_solver=sparse_solver)
    if nested is None:
        return None, None
    directions = np.empty_like(nested)
    directions[rows] = nested
    return None, directions


def _shift_estimate(W: sp.spmatrix, directions: NDArray, scale: NDArray) -> tuple[float, NDArray]:
    """A first Levenberg-Marquardt shift from directions ``v`` (n, k) of negative curvature:
    twice the largest ``-v^T W v / (v^T diag(scale) v)``, the shift that would just cancel
    ``v``'s negative curvature in the shift's metric; and that direction (n,).

    A heuristic start, not a bound: too small, the ladder grows it; too large, it damps the
    step more than needed. The Rayleigh quotient in the shift's metric, not
    ``-v^T W v / (scale_j v_j^2)`` at ``v``'s largest entry ``j``, which asks for far too
    large a shift when ``v`` is spread over many nodes
    (``docs/solver-notes.md#ladder-shift-estimate``).
    """
    curv = np.einsum("ij,ij->j", directions, W @ directions)
    quad = np.einsum("ij,ij->j", directions, scale[:, None] * directions)
    ratio = -curv / np.maximum(quad, 1e-300)
    j = int(np.argmax(ratio))
    return 2.0 * float(ratio[j]), directions[:, j]


def ritz_lowest(
    W: sp.spmatrix | NDArray, scale: NDArray, start: NDArray, steps: int = _LANCZOS
) -> float:
    """The lowest Ritz value of ``diag(scale)^-1/2 W diag(scale)^-1/2`` after ``steps``
    Lanczos steps (full reorthogonalisation) from ``diag(scale)^1/2 start`` (n,): the least
    ``v^T W v / (v^T diag(scale) v)`` over that Krylov space, so an upper bound on ``W``'s
    lowest eigenvalue in the shift's metric, and ``W + mu diag(scale)`` is indefinite for
    every ``mu`` below its negative (``inf`` where nothing is known: a start of no length,
    ``W`` not finite). From a direction of negative curvature it converges in a few steps
    where that eigenvalue stands apart (a lattice pulled to strain 10: -6.6359 after 5
    steps, the same after 40).
    """
    root = np.sqrt(scale)
    q = root * start
    basis = np.empty((min(steps, q.size), q.size))
    alpha: list[float] = []
    beta: list[float] = []
    norm = float(np.linalg.norm(q))
    for j in range(basis.shape[0]):
        if not (norm > 1e-12 * max(map(abs, alpha), default=0.0) and np.isfinite(norm)):
            break  # an invariant subspace (or a start of no length)
        basis[j] = q / norm
        w = (W @ (basis[j] / root)) / root
        alpha.append(float(basis[j] @ w))
        done = basis[: j + 1]
        w -= done.T @ (done @ w)
        w -= done.T @ (done @ w)  # twice is enough (Kahan)
        norm = float(np.linalg.norm(w))
        beta.append(norm)
        q = w
    diagonal, off = np.array(alpha), np.array(beta[: len(alpha) - 1])
    if not (diagonal.size and np.isfinite(diagonal).all() and np.isfinite(off).all()):
        return np.inf  # nothing known (a start of no length, or W not finite)
    return float(sla.eigvalsh_tridiagonal(diagonal, off, select="i", select_range=(0, 0))[0])


def _still_negative(W, directions, problem, x, pattern, extra_rho) -> bool:
    """True when some direction keeps negative curvature after adding ``extra_rho A^T A``."""
    A = problem.clamp_jacobian(x, pattern.coords, dense=False)
    curv = np.einsum("ij,ij->j", directions, W @ directions)
    Av = A @ directions
    return bool(np.any(curv + extra_rho * np.einsum("ij,ij->j", Av, Av) < 0))
