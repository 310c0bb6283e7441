"""The sparse Newton's line searches on the augmented Lagrangian merit.

Used by :func:`~.newton.newton`. :func:`line_search` backtracks along the Newton step;
besides the plain step it tries the step with a second-order correction onto the clamp
lengths and with stiff springs put back to the lengths the linear model predicted
(:class:`~.stiff_springs.StiffSprings`). :func:`curvature_search` moves along a direction
of negative curvature. :func:`geodesic_path` bends an exact Newton step along the curved
valley a rotation follows.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.kkt import Factor, range_space_solve
from .constraints import Problem
from .energy import spring_bending_on, spring_energy_change
from .stiff_springs import StiffSprings
from .trust import ACCEL_MAX

__all__ = [
    "curvature_search", "follow_curvature", "geodesic_path", "line_search", "merit_change"
]  # fmt: skip

Merit = Callable[[NDArray], float]


def merit_change(
    problem: Problem,
    x: NDArray,
    A: sp.csr_matrix | NDArray | None,
    viol: NDArray,
    lam: NDArray,
    rho: float,
) -> Merit:
    """The change of the merit ``E + lam.(r - l) + rho |r - l|^2 / 2`` from ``x`` (n_nodes,
    2) to ``y``, as a function of ``y``, free of cancellation (stiff springs make ``E``
    itself many orders larger than the changes that matter). ``A`` None: no clamps (``E``).
    """
    all_springs = problem.all_springs()
    lam_c = lam if A is not None else None

    def merit(y: NDArray) -> float:
        e = spring_energy_change(y, x, *all_springs)
        if lam_c is None:
            return e
        c = problem.clamp_violation(y)
        return e + float(lam_c @ (c - viol)) + 0.5 * rho * float(c @ c - viol @ viol)

    return merit


def line_search(
    problem: Problem,
    x: NDArray,
    coords: NDArray,
    step: NDArray,
    grad: NDArray,
    A: sp.csr_matrix | None,
    viol: NDArray,
    lam: NDArray,
    rho: float,
    residual: float,
    stiff: StiffSprings | None = None,
    geodesic: Callable[[], NDArray | None] | None = None,
) -> tuple[NDArray, float]:
    """Armijo backtracking on the augmented Lagrangian; accepts any step halving the residual.

    With clamps, the full step is also tried with a second-order correction: the minimum-norm
    move back onto the clamp lengths, which keeps the curvature of ``r_c`` along the step
    from blocking full steps (the Maratos effect; Nocedal & Wright, Sec. 18.3).

    ``geodesic``: returns the correction ``c`` (n_free,) of the curved path ``x + alpha
    step + alpha^2 c``, or None (:func:`geodesic_path`: computed when first asked, when the
    straight step is first refused); at each ``alpha`` whose straight point is refused, the
    curved one is tried.

    Returns the new positions and the step length taken (0 when none was accepted).
    """
    merit = merit_change(problem, x, A, viol, lam, rho)
    slope_vec = grad if A is None else grad + A.T @ (lam + rho * viol)
    slope = float(slope_vec @ step)
    phi0 = 0.0

    def accepted(y: NDArray, alpha: float) -> NDArray | None:
        """``y`` (or its move onto the clamps, or with stiff springs restored) when it is
        accepted at step length ``alpha``; else None."""
        if not np.all(np.isfinite(y)):
            return None
        phi = merit(y)
        if phi <= phi0 + 1e-4 * alpha * min(slope, 0.0) and (slope < 0 or phi < phi0):
            return y
        if alpha == 1.0:
            if A is not None:
                z = problem.toward_clamps(y, coords, A)
                if merit(z) <= phi0 + 1e-4 * min(slope, 0.0):
                    return z
            if problem.residual(y).imbalance < 0.5 * residual:
                return y
        if stiff is not None and alpha >= 1.0 / 64:
            # the linear step lengthens a rotating spring by |rotation|^2 r / 2; at a
            # stiffness contrast up to 1e12 that alone cuts the step to a crawl, so stiff
            # springs are first put back to the lengths the linear model predicted
            z = stiff.restore(y, x, alpha * step)
            if z is not None and merit(z) <= phi0 + 1e-4 * alpha * min(slope, 0.0):
                return z
            if z is not None and alpha == 1.0:
                if problem.residual(z).imbalance < 0.5 * residual:
                    return z
        return None

    alpha = 1.0
    for _ in range(60):
        y = x.copy()
        y.ravel()[coords] += alpha * step
        z = accepted(y, alpha)
        if z is None and geodesic is not None and (curve := geodesic()) is not None:
            y = x.copy()
            y.ravel()[coords] += alpha * step + (alpha * alpha) * curve
            z = accepted(y, alpha)
        if z is not None:
            return z, alpha
        alpha *= 0.5
    return x, 0.0


def geodesic_path(
    problem: Problem,
    x: NDArray,
    coords: NDArray,
    step: NDArray,
    solver: Factor,
    A: sp.csr_matrix | NDArray | None,
) -> Callable[[], NDArray | None]:
    """The line search's curved path for a Newton ``step`` (n_free,) from ``x`` (n_nodes, 2):
    a function returning ``a / 2``, ``a`` the geodesic acceleration (Transtrum & Sethna
    2012), or None where ``|a| > ACCEL_MAX |step|`` (the path is not near a parabola).

    A straight step that turns a spring lengthens it by ``|dd_perp|^2 / (2 r)``; the force
    of that lengthening (:func:`~.energy.spring_bending`), solved with the step's own
    factorisation (``solver``, or the preconditioner of a step that conjugate gradients
    solved; on the clamps' tangent space ``A a = 0``), bends the path back into the curved
    valley a rotation follows. The dense trust region bends every step (:mod:`.trust`);
    here only exact Newton steps (shift 0), and only where the straight point is refused,
    at the lengths it is refused (``docs/solver-notes.md#line-search-geodesic``).
    """

    @functools.cache  # computed once, when first asked
    def correction() -> NDArray | None:
        springs, k, _ = problem.all_springs()
        bend = spring_bending_on(x, coords, step, springs, k)
        try:
            if A is None:
                accel = -np.asarray(solver.solve(bend))
            else:
                accel = range_space_solve(solver, A, -bend)[1][0]
        except np.linalg.LinAlgError:
            return None
        if not accel @ accel <= ACCEL_MAX**2 * (step @ step):  # also not finite
            return None
        return 0.5 * accel

    return correction


def curvature_search(
    problem: Problem,
    x: NDArray,
    coords: NDArray,
    direction: NDArray,
    grad: NDArray,
    merit: Merit,
    length: float,
    clamps: bool,
) -> tuple[NDArray, float] | None:
    """The move from ``x`` (n_nodes, 2) along ``direction`` (n_free,; of negative curvature,
    in the clamps' tangent space), signed to descend along ``grad``, that lowers ``merit``
    most: the largest coordinate move starts at ``length``, is halved while the merit does
    not fall (at most 30 times) and doubled while it keeps falling; with ``clamps`` each
    trial is put back onto the clamp lengths (one Gauss-Newton step). Returns ``(y,
    merit(y))``, or None when no length lowers the merit.

    Near a saddle whose negative curvature is weak, a Levenberg-Marquardt shift large
    enough to make the Hessian positive definite damps the escape to a creep; a move along
    the direction itself, as long as the energy keeps falling, escapes in one iteration.
    """
    peak = float(np.max(np.abs(direction), initial=0.0))
    if not (peak > 0.0 and np.isfinite(peak)):
        return None
    d = direction * ((-length if float(grad @ direction) > 0.0 else length) / peak)
    best: tuple[NDArray, float] | None = None
    t = 1.0
    for _ in range(30):
        y = x.copy()
        y.ravel()[coords] += t * d
        if clamps:
            y = problem.toward_clamps(y, coords)
        phi = merit(y) if np.all(np.isfinite(y)) else np.inf
        if best is not None and not phi < best[1]:
            break  # the merit rose again: the last length was the best
        if phi < 0.0:
            best, t = (y, float(phi)), 2.0 * t
        elif best is None:
            t *= 0.5
    return best


def follow_curvature(
    problem: Problem,
    coords: NDArray,
    start: NDArray,
    searched: tuple[NDArray, float],
    direction: NDArray,
    step: NDArray,
    grad: NDArray,
    A: sp.csr_matrix | NDArray | None,
    viol: NDArray,
    lam: NDArray,
    rho: float,
) -> tuple[NDArray, float]:
    """``searched``, the line search's ``(x, alpha)`` along ``step`` from ``start``, or the
    move along ``direction`` (negative curvature that conjugate gradients met; ``coords``
    the free coordinates in the order of ``direction`` and ``step``) when its merit is lower
    (:func:`curvature_search`, from the largest coordinate move the line
    search took, or a thousandth of the step's when it took none); that move counts as a
    full step (the shift decays). Without it a weak saddle is escaped only by a creep
    (``docs/solver-notes.md#newton-negative-curvature``).
    """
    x, alpha = searched
    merit = merit_change(problem, start, A, viol, lam, rho)
    mean_rest = float(np.mean(problem.net.rest_length))
    length = max(float(np.max(np.abs(step))) * max(alpha, 1e-3), 1e-6 * mean_rest)
    moved = curvature_search(
        problem, start, coords, direction, grad, merit, length, clamps=A is not None
    )
    if moved is not None and moved[1] < min(merit(x), 0.0):
        return moved[0], max(alpha, 1.0)
    return x, alpha
