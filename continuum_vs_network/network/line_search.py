"""The sparse Newton's line search: Armijo backtracking on the augmented Lagrangian.

Used by :func:`~.newton.newton`. Besides the plain step it tries the step with a
second-order correction onto the clamp lengths and with stiff springs put back to the
lengths the linear model predicted (:class:`~.stiff_springs.StiffSprings`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .constraints import Problem
from .energy import spring_energy_change
from .stiff_springs import StiffSprings

__all__ = ["line_search"]


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
) -> tuple[NDArray, float]:
    """Armijo backtracking on the augmented Lagrangian; accepts any step halving the residual.

    With clamps, the full step is also tried with a second-order correction: the minimum-norm
    move back onto the clamp lengths, which keeps the curvature of ``r_c`` along the step
    from blocking full steps (the Maratos effect; Nocedal & Wright, Sec. 18.3).

    Returns the new positions and the step length taken (0 when none was accepted).
    """
    all_springs = problem.all_springs()
    lam_c = lam if A is not None else None

    def merit(y: NDArray) -> float:
        """Merit at ``y`` minus its value at ``x``, free of cancellation (stiff springs
        make ``E`` itself many orders larger than the changes that matter)."""
        e = spring_energy_change(y, x, *all_springs)
        if lam_c is None:
            return e
        c = problem.clamp_violation(y)
        return e + float(lam_c @ (c - viol)) + 0.5 * rho * float(c @ c - viol @ viol)

    slope_vec = grad if A is None else grad + A.T @ (lam + rho * viol)
    slope = float(slope_vec @ step)
    phi0 = 0.0
    alpha = 1.0
    for _ in range(60):
        y = x.copy()
        y.ravel()[coords] += alpha * step
        if np.all(np.isfinite(y)):
            phi = merit(y)
            if phi <= phi0 + 1e-4 * alpha * min(slope, 0.0) and (slope < 0 or phi < phi0):
                return y, alpha
            if alpha == 1.0:
                if A is not None:
                    z = problem.toward_clamps(y, coords, A)
                    if merit(z) <= phi0 + 1e-4 * min(slope, 0.0):
                        return z, alpha
                if problem.residual(y).imbalance < 0.5 * residual:
                    return y, alpha
            if stiff is not None and alpha >= 1.0 / 64:
                # the linear step lengthens a rotating spring by |rotation|^2 r / 2; at a
                # stiffness contrast up to 1e12 that alone cuts the step to a crawl, so stiff
                # springs are first put back to the lengths the linear model predicted
                z = stiff.restore(y, x, alpha * step)
                if z is not None and merit(z) <= phi0 + 1e-4 * alpha * min(slope, 0.0):
                    return z, alpha
                if z is not None and alpha == 1.0:
                    if problem.residual(z).imbalance < 0.5 * residual:
                        return z, alpha
        alpha *= 0.5
    return x, 0.0
