"""Newton steps solved with an earlier factorisation: preconditioned conjugate gradients.

:func:`~.newton.newton` refactorises the Lagrangian Hessian only when these fail: after a
full step the next one is first tried by (projected) conjugate gradients preconditioned by
the last factorisation, a few triangular solves instead of a factorisation.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.kkt import Factor, range_space_solve, sparse_backend

__all__ = ["NegativeCurvature", "SolveFailed", "pcg", "projected_pcg", "reuse_budget"]


class SolveFailed(RuntimeError):
    """A reused factorisation did not solve the new system (indefinite or too far off)."""


class NegativeCurvature(SolveFailed):
    """Conjugate gradients met a direction ``d`` (n,) with ``d^T W d <= 0``: ``W`` is not > 0.

    ``direction`` is ``d``; from :func:`projected_pcg` it lies in the null space of ``A``.
    """

    def __init__(self, direction: NDArray) -> None:
        super().__init__("negative curvature")
        self.direction = direction


def reuse_budget(size: int, sparse_solver: str = "auto") -> int:
    """Preconditioned CG iterations allowed before a new factorisation of (size, size).

    ``0.3 sqrt(size)`` (at least 2): twice the triangular solves that one SuperLU
    nested-dissection factorisation costs on 2D networks; with PARDISO (its analysis
    kept; ``sparse_solver``, :func:`~..linalg.kkt.sparse_backend`), 16, twice its cost in
    solves (``docs/solver-notes.md#reuse-budget``). A count,
    not a timing, so that runs are reproducible bit for bit.
    """
    if sparse_backend(sparse_solver) == "pardiso":
        return 16
    return max(2, int(0.3 * np.sqrt(size)))


def pcg(W: sp.csr_matrix, preconditioner: Factor, *, rtol: float, max_iter: int) -> Factor:
    """Conjugate gradients on ``W`` preconditioned by an earlier factorisation.

    ``max_iter`` bounds the iterations of all right-hand sides together; a right-hand side
    whose rate so far cannot reach ``rtol`` in budget is given up early, by the rule of
    :func:`projected_pcg` (:func:`_hopeless`; ``docs/solver-notes.md#reuse-hopeless``).

    Raises :class:`NegativeCurvature` on negative curvature (``W`` not positive definite),
    :class:`SolveFailed` when ``rtol`` is not reached.
    """

    budget = [max_iter]
    apply = preconditioner.precondition  # an approximate solve is enough (CG corrects it)

    def solve_one(b: NDArray) -> NDArray:
        x = apply(b)
        r = b - W @ x
        b_norm = np.linalg.norm(b)
        if np.linalg.norm(r) <= rtol * b_norm:
            return x
        z = apply(r)
        p = z.copy()
        rz = r @ z
        first = best = float(np.linalg.norm(r))
        done = 0
        while budget[0] > 0:
            budget[0] -= 1
            Wp = W @ p
            curvature = p @ Wp
            if curvature <= 0:
                raise NegativeCurvature(p)
            a = rz / curvature
            x += a * p
            r -= a * Wp
            norm = float(np.linalg.norm(r))
            if norm <= rtol * b_norm:
                return x
            done, best = done + 1, min(best, norm)
            if _hopeless(first, best, rtol * b_norm, done, max_iter):
                break
            z = apply(r)
            rz, rz_old = r @ z, rz
            p = z + (rz / rz_old) * p
        raise SolveFailed("no convergence")

    def solve(b: NDArray) -> NDArray:
        if b.ndim == 1:
            return solve_one(b)
        return np.column_stack([solve_one(col) for col in b.T])

    return Factor(solve, W.shape[0])


def projected_pcg(
    W: sp.csr_matrix,
    preconditioner: Factor,
    grad: NDArray,
    A: sp.spmatrix | None,
    viol: NDArray,
    *,
    rtol: float,
    max_iter: int,
) -> tuple[NDArray, NDArray]:
    """The Newton step of ``[[W, A^T], [A, 0]] [step; lam] = [-grad; -viol]`` by projected
    conjugate gradients with the constraint preconditioner ``[[W0, A^T], [A, 0]]``.

    ``W0`` is an earlier factorisation (``preconditioner``), ``A`` the current clamp
    Jacobian (m, n). Every iterate satisfies ``A step = -viol`` and the search stays in
    the null space of ``A`` (Gould, Hribar & Nocedal 2001), so one CG run (one solve with
    ``W0`` an iteration, after one m-column solve for the preconditioner's Schur
    complement) replaces the ``m + 1`` separate CG runs of a range-space solve. Stops when
    the step's force residual ``grad + W step + A^T lam`` (``lam`` by least squares) is
    ``rtol`` times the force at ``step = 0``; the residual is kept projected, as Gould et al.
    recommend (the clamp-force part of ``grad``, 1e9 times the tolerance near convergence,
    otherwise spoils the preconditioned residual by round-off).

    Raises :class:`SolveFailed` on negative curvature in the null space or when
    ``max_iter`` iterations do not reach ``rtol``.
    """
    if A is None:
        return -np.asarray(pcg(W, preconditioner, rtol=rtol, max_iter=max_iter).solve(grad)), (
            np.empty(0)
        )
    m = A.shape[0]
    # the preconditioner's approximate solve (float32 for a banded factor) serves: with Z
    # and S = A Z from the same solve, every projected vector still meets A g = c exactly
    rough = Factor(preconditioner.precondition, preconditioner.n)
    kkt, (x, _) = range_space_solve(rough, A, -grad, -viol)  # one batched solve
    At = A.T  # formed once: scipy.sparse builds a new matrix at every .T
    gram = A @ At
    gram = gram.toarray() if sp.issparse(gram) else np.asarray(gram)
    # inverted once: (m, m) with m a few clamps, where np.linalg.solve's per-call overhead
    # (two per CG iteration) shows in a profile (docs/solver-notes.md#reuse-gram-inverse)
    gram_inverse = np.linalg.inv(gram)
    zero = np.zeros(m)

    def multipliers(v: NDArray) -> NDArray:
        """``lam`` minimising ``|v + A^T lam|``."""
        return -(gram_inverse @ (A @ v))

    tol = rtol * float(np.linalg.norm(grad + At @ multipliers(grad)))
    r = W @ x + grad
    d = np.zeros_like(x)
    rg_old = np.inf
    first = best = np.inf
    for it in range(max_iter + 1):
        # keep the residual projected (its large clamp-force part removed): otherwise its
        # round-off through the preconditioner swamps a tight tolerance (Gould et al.)
        r = r + At @ multipliers(r)
        norm = float(np.linalg.norm(r))
        if norm <= tol:
            return x, multipliers(W @ x + grad)
        first = norm if it == 0 else first
        best = min(best, norm)  # CG's residual is not monotone: judged by the best so far
        if it == max_iter or _hopeless(first, best, tol, it, max_iter):
            break
        g = kkt.solve(r, zero)[0]  # projected, preconditioned residual: A g = 0
        rg = float(r @ g)
        d = -g + (rg / rg_old) * d
        Wd = W @ d
        curvature = float(d @ Wd)
        if curvature <= 0:
            raise NegativeCurvature(d)
        alpha = rg / curvature
        x = x + alpha * d
        r = r + alpha * Wd
        rg_old = rg
    raise SolveFailed("no convergence")


def _hopeless(first: float, best: float, tol: float, done: int, max_iter: int) -> bool:
    """True when CG's mean residual reduction over its first ``done >= 4`` iterations
    (from ``first`` to the ``best`` so far) is none, or would need more than three times
    ``max_iter`` iterations to reach ``tol``.

    Preconditioners that fail typically do not bring the residual below its start in 4
    iterations and then use the whole budget. The margin of 3 is there because CG
    accelerates: predicting with the budget itself stops some that then succeed
    (``docs/solver-notes.md#reuse-hopeless``).
    """
    if done < 4:
        return False
    if best >= first or tol <= 0.0:  # tol 0 (no force at step 0): no iteration meets it
        return True
    rate = np.log(best / first) / done
    return bool(np.log(tol / first) / rate > 3 * max_iter)
