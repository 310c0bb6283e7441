"""Sparse Newton for spring-network equilibria with exact clamps.

Clamps are equality constraints ``r_c(x) = l_c`` handled by sequential quadratic
programming in range-space form. With ``A = dr_c/dx`` (m, n_free) and
``W = H_E + sum_c mu_c d^2 r_c/dx^2 + rho A^T A`` (the Hessian of the augmented Lagrangian,
assembled in the spring-block pattern because every term lives on a spring's node pair),
each step solves::

    W z = grad E,   W Z = A^T,   (A Z) lam = (r - l) - A z,   dx = -z - Z lam

with one factorisation of ``W`` and ``m + 1`` triangular solves. Adding ``rho A^T A``
leaves the step unchanged (it is the same KKT system) but makes ``W`` positive definite at a
stable constrained minimum, so positive definiteness can be checked with a factorisation:
if ``W`` is indefinite a Levenberg shift ``mu I`` grows until it is not. The step is
accepted by an Armijo line search on the augmented Lagrangian merit function
``E + lam.(r - l) + rho |r - l|^2 / 2``, for which ``dx`` is a descent direction, or when it
halves the residual (the quadratic regime, where the merit is below round-off).

Small problems (<= ``DENSE_MAX`` free coordinates) use dense Cholesky; larger ones use
SuperLU with a symmetric minimum-degree ordering and diagonal pivots, whose ``U`` diagonal
then carries the inertia of ``W`` (Sylvester), so a positive diagonal proves ``W > 0``.
"""

from __future__ import annotations

import weakref

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .constraints import Problem
from .energy import HessianPattern, spring_energy, spring_gradient
from .equilibrium import Outcome, StopRule, Trace

__all__ = ["DENSE_MAX", "factor_pd", "newton", "pattern_for"]

DENSE_MAX = 400
_PATTERNS: dict[int, dict] = {}


def pattern_for(springs: NDArray, n_nodes: int, free: NDArray) -> HessianPattern:
    """The Hessian pattern of a topology and pin mask, cached while the springs array lives.

    Networks made with ``with_*`` share their (read-only) springs array, so a learning
    loop builds the pattern once.
    """
    key_array = id(springs)
    if key_array not in _PATTERNS:
        _PATTERNS[key_array] = {}
        weakref.finalize(springs, _PATTERNS.pop, key_array, None)
    per_topology = _PATTERNS[key_array]
    key = (n_nodes, free.tobytes())
    if key not in per_topology:
        per_topology[key] = HessianPattern(springs, n_nodes, free)
    return per_topology[key]


class _Factor:
    """A positive-definite factorisation with ``solve`` for vectors and matrices."""

    def __init__(self, solve) -> None:
        self.solve = solve


def factor_pd(W: sp.csr_matrix) -> _Factor | None:
    """Factorise symmetric ``W``; None when it is not positive definite."""
    n = W.shape[0]
    if n <= DENSE_MAX:
        try:
            c = sla.cho_factor(W.toarray(), lower=True, check_finite=False)
        except sla.LinAlgError:
            return None
        return _Factor(lambda b: sla.cho_solve(c, b, check_finite=False))
    try:
        lu = spla.splu(
            W.tocsc(),
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options={"SymmetricMode": True},
        )
    except RuntimeError:  # exactly singular
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c) or not np.all(lu.U.diagonal() > 0):
        return None
    return _Factor(lu.solve)


def newton(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """Minimise ``problem`` from ``x`` (n_nodes, 2) by shifted sparse Newton (see module)."""
    net = problem.net
    springs, k = net.springs, net.stiffness
    all_springs = problem.all_springs()
    free = problem.free_flat
    pattern = pattern_for(springs, net.n_nodes, problem.free)
    m = problem.n_clamps if problem.exact else 0
    rho = float(np.max(k)) if m else 0.0
    shift = 0.0
    exact_ok = True
    x = np.array(x, dtype=np.float64)

    for it in range(stop.max_iter + 1):
        grad = spring_gradient(x, *all_springs).ravel()[free]
        if problem.n_clamps:
            A = problem.clamp_jacobian(x)
            lam_ls = -np.linalg.solve((A @ A.T).toarray(), A @ grad)
            force = grad + A.T @ lam_ls  # clamp-normal (rod or constraint) forces removed
        else:
            lam_ls, force = np.empty(0), grad
        viol = problem.clamp_violation(x) if m else np.empty(0)
        residual = float(np.max(np.abs(force))) if force.size else 0.0
        clamp_error = float(np.max(np.abs(viol))) if m else 0.0
        trace.record(residual)
        if stop.met(residual, clamp_error):
            return Outcome(x, it, True)
        if it == stop.max_iter:
            return Outcome(x, it, False, f"no convergence in {stop.max_iter} iterations")
        if trace.elapsed() > stop.max_seconds:
            return Outcome(x, it, False, f"time budget of {stop.max_seconds:g} s exceeded")

        # Hessian of the augmented Lagrangian, in the spring-block pattern
        factor, shift, exact_ok = _factor_lagrangian_hessian(
            problem, pattern, x, lam_ls[:m], rho, shift, try_exact=exact_ok or shift == 0.0
        )
        if factor is None:
            return Outcome(x, it, False, "Hessian could not be made positive definite")

        z = factor.solve(grad)
        if m:
            Z = factor.solve(A.T.toarray())
            if Z.ndim == 1:
                Z = Z[:, None]
            lam = np.linalg.solve(A @ Z, viol - A @ z)
            step = -z - Z @ lam
        else:
            lam, step = np.empty(0), -z
        x, ok = _line_search(problem, x, step, grad, A if m else None, viol, lam, rho, residual)
        if not ok:
            return Outcome(x, it + 1, False, "line search found no decrease")
    return Outcome(x, stop.max_iter, False, "no convergence")


def _lagrangian_blocks(
    problem: Problem, x: NDArray, lam: NDArray, rho: float, *, clip: bool
) -> NDArray:
    """Per-spring 2x2 blocks of the augmented Lagrangian's Hessian, (n_springs, 2, 2).

    With ``clip`` every tangential coefficient ``k (1 - L/r)`` (and ``lam / r`` of a
    compressed clamp) is floored at 0: a sum of positive semi-definite blocks.
    """
    net = problem.net
    springs, clamps = net.springs, problem.clamp_springs
    d = x[springs[:, 1]] - x[springs[:, 0]]
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
    axial = net.stiffness.copy()
    tangential = net.stiffness * (1.0 - net.rest_length / r)
    if problem.clamp == "rod" and problem.n_clamps:
        k_rod = problem.rod_stiffness
        axial[clamps] += k_rod
        tangential[clamps] += k_rod * (1.0 - problem.clamp_lengths / r[clamps])
    elif lam.size:
        axial[clamps] += rho
        tangential[clamps] += lam / r[clamps]
    if clip:
        tangential = np.maximum(tangential, 0.0)
    u = d / r[:, None]
    uu = u[:, :, None] * u[:, None, :]
    return axial[:, None, None] * uu + tangential[:, None, None] * (np.eye(2) - uu)


def _factor_lagrangian_hessian(
    problem: Problem,
    pattern: HessianPattern,
    x: NDArray,
    lam: NDArray,
    rho: float,
    shift: float,
    *,
    try_exact: bool,
) -> tuple[_Factor | None, float, bool]:
    """Factorise a positive-definite Hessian model: exact if possible, else modified.

    Order: the exact Hessian (when ``try_exact``); then the tangentially clipped one, which is
    positive semi-definite by construction; then the clipped one with a Levenberg shift that
    grows tenfold until the factorisation is positive definite. Returns ``(factor, shift,
    exact_used)``. The exact Hessian is used whenever it is positive definite, so the last
    iterations are pure Newton steps and converge quadratically.
    """
    if try_exact:
        W = pattern.assemble(_lagrangian_blocks(problem, x, lam, rho, clip=False))
        factor = factor_pd(W)
        if factor is not None:
            return factor, 0.0, True
    W = pattern.assemble(_lagrangian_blocks(problem, x, lam, rho, clip=True))
    scale = float(np.max(np.abs(W.diagonal()))) if W.shape[0] else 1.0
    floor = 1e-12 * scale
    shift = shift / 10 if shift > 10 * floor else 0.0
    eye = sp.identity(W.shape[0], format="csr")
    while shift <= 1e8 * scale:
        factor = factor_pd(W + shift * eye if shift else W)
        if factor is not None:
            return factor, shift, False
        shift = max(floor, 10 * shift)
    return None, shift, False


def _line_search(
    problem: Problem,
    x: NDArray,
    step: NDArray,
    grad: NDArray,
    A: sp.csr_matrix | None,
    viol: NDArray,
    lam: NDArray,
    rho: float,
    residual: float,
) -> tuple[NDArray, bool]:
    """Armijo backtracking on the augmented Lagrangian; accepts any step halving the residual."""
    free = problem.free_flat
    all_springs = problem.all_springs()

    def merit(y: NDArray) -> float:
        e = spring_energy(y, *all_springs)
        if A is None:
            return e
        c = problem.clamp_violation(y)
        return e + float(lam @ c) + 0.5 * rho * float(c @ c)

    slope_vec = grad if A is None else grad + A.T @ (lam + rho * viol)
    slope = float(slope_vec @ step)
    phi0 = merit(x)
    alpha = 1.0
    for _ in range(60):
        y = x.copy()
        y.ravel()[free] += alpha * step
        if np.all(np.isfinite(y)):
            phi = merit(y)
            if phi <= phi0 + 1e-4 * alpha * min(slope, 0.0) and (slope < 0 or phi < phi0):
                return y, True
            if alpha == 1.0:
                trial, _ = problem.residual(y)
                if trial < 0.5 * residual:
                    return y, True
        alpha *= 0.5
    return x, False
