"""Sparse Newton for spring-network equilibria with exact clamps.

Problems of at most :data:`~.trust.TR_DENSE_MAX` free coordinates go to the dense
trust-region Newton of :mod:`.trust` (exact reduced Hessian, negative curvature followed);
larger ones use the shifted sparse Newton below. The record behind its heuristics and
constants is in ``docs/solver-notes.md#newton``.

Clamps are equality constraints ``r_c(x) = l_c`` handled by sequential quadratic
programming in range-space form. With ``A = dr_c/dx`` (m, n_free) and
``W = H_E + sum_c mu_c d^2 r_c/dx^2 + rho A^T A`` (the Hessian of the augmented Lagrangian,
assembled in the spring-block pattern because every term lives on a spring's node pair),
each step solves::

    W z = grad E,   W Z = A^T,   (A Z) lam = (r - l) - A z,   dx = -z - Z lam

with one factorisation of ``W`` and ``m + 1`` triangular solves. The first step is taken
from the start as given, clamps unmet (the linear elastic response to the clamp lengths,
:func:`_clamp_predictor`), and only then are the clamped springs set to their lengths;
without clamps, a start that is the network's geometry with pinned nodes moved gets the
linear elastic response to the pins' displacement (:func:`_pin_predictor`).
Adding ``rho A^T A`` leaves the step unchanged (it is the same KKT system) but makes ``W``
positive definite at a stable constrained minimum, so positive definiteness can be checked
with a factorisation: if ``W`` is indefinite a Levenberg-Marquardt shift ``mu diag(W)``
grows until it is not. The step is
accepted by an Armijo line search on the augmented Lagrangian merit function
``E + lam.(r - l) + rho |r - l|^2 / 2``, for which ``dx`` is a descent direction, or when it
halves the residual (the quadratic regime, where the merit is below round-off). Merit
changes are computed without cancellation (:func:`~.energy.spring_energy_change`). When
no step length decreases the merit, the shift is raised 100-fold and the Hessian
refactorised (Levenberg-Marquardt as a trust region) instead of giving up; and ``rho``,
raised where the exact Hessian was indefinite, decays back by 10 after every full step, so
that it cannot grow until it swamps ``W`` in round-off (strongly prestressed networks
need both: ``docs/solver-notes.md#newton-damping``).

Negative curvature is followed, not only damped: when conjugate gradients preconditioned
by the last factorisation meet a direction of negative curvature, the move along it that
lowers the merit most (doubled while it falls) replaces the line search's point when it
goes lower (:func:`~.line_search.follow_curvature`), and the shift restarts from twice
that direction's Rayleigh quotient (:func:`_shift_estimate`). A shift alone, large
enough to make ``W`` positive definite, damps the escape from a weak saddle to a creep.
Without clamps, the direction the failed factorisation of the exact Hessian gives is
followed too, once the best residual has not halved in ``_CREEP`` iterations.

Stiffness contrast: a linear step that rotates a spring lengthens it by
``|rotation|^2 r / 2``; for springs 10-1e12 times stiffer than the median that
second-order error alone cuts steps short. Each trial step is therefore
also tried after a Gauss-Newton projection that puts the stiff springs (springs from
:attr:`~.stiff_springs.StiffSprings.CONTRAST` times the median stiffness, the trust
region's choice, and exact clamps) back to the lengths the linear model predicted
(:class:`StiffSprings`; ``docs/solver-notes.md#newton-stiff-springs``).

Curved valleys: where the line search refuses an exact Newton step (shift 0), the step is
also tried bent along its geodesic acceleration (:func:`~.line_search.geodesic_path`, as
the dense trust region bends every step): a long strip curling far from its start, or a
lattice far from the origin, follows rotations that a straight step overshoots
(``docs/solver-notes.md#newton-geodesic``).

Factorisations are :func:`~..linalg.kkt.factor_spd`'s (:mod:`..linalg.spd`): each completes only for
``W > 0``, which is how positive definiteness is checked (dense Cholesky up to
``DENSE_MAX`` free coordinates; above, PARDISO, LAPACK's banded Cholesky in a narrow-band
order, or SuperLU with diagonal pivots, whose ``U`` diagonal carries the inertia). A
``rough`` factor is ``W`` rounded to float32 where that solves to
:data:`~..linalg.spd.ROUGH_RESIDUAL`; Newton's step from such a factor is projected CG on the
matrix factorised, preconditioned by it, to the forcing tolerance (:func:`_fresh_step`);
the clamp predictor's step is taken as it is.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.kkt import (
    DENSE_MAX,
    Factor,
    factor_spd,
    range_space_solve,
)
from .checks import dependent_clamps, roundoff_floor
from .constraints import Problem, clamp_tensions
from .energy import HessianPattern, _scatter_nodes, spring_energy_change, spring_gradient
from .hessian_ladder import (
    DAMP_MIN,
    assemble_hessian,
    factor_positive_model,
    marquardt_scale,
    shifted,
)
from .lagrangian import lagrangian_blocks, pattern_for
from .length_jacobian import dense_jacobian_pays
from .line_search import follow_curvature, geodesic_path, line_search
from .model import spring_vectors
from .reuse import NegativeCurvature, SolveFailed, projected_pcg, reuse_budget
from .stiff_springs import StiffSprings
from .stopping import Outcome, StopRule, Trace
from .trust import TR_DENSE_MAX, trust_region_newton

__all__ = ["DENSE_MAX", "newton", "pattern_for"]

DAMP_UP = 10.0  # shift growth after a step cut below a quarter
DAMP_UP_MILD = 2.0  # after a step cut to a quarter or more (Nielsen's gentler growth)
DAMP_RETRY = 1e-4  # least shift after a line search that found no decrease
DAMP_GIVE_UP = 1e6  # no decrease even at this shift: the solve fails
# In-loop second-order certificate (relax then skips its check, a float64 factorisation):
# the converging step came from an exact, positive-definite factorisation made one step
# before and moved no coordinate more than _CERTIFY_MOVE mean rest lengths. Below
# _FRESH_NEAR times tol the Hessian is factorised afresh, not reused, to make it so (a
# factorisation further back can certify a saddle: docs/solver-notes.md#newton-certificate)
_FRESH_NEAR = 1e4
_CERTIFY_MOVE = 1e-6
# The best residual not halved in this many iterations, at a residual within 10x of
# float64's round-off floor there (checks.roundoff_floor): the solve stops, stalled (relax
# then says tol is below float64's reach), instead of running out its iteration budget.
# Needed because accepted steps at round-off (a residual halved by chance) keep the shift
# from growing to the line search's give-up (docs/solver-notes.md#newton-stagnation)
_STAGNANT = 50
# The best residual not halved in this many iterations, the exact Hessian indefinite: the
# direction of negative curvature its failed factorisation gave is followed after the line
# search, as conjugate gradients' are (a shift alone made just positive definite creeps).
# Only in such a creep: followed at every such factorisation it costs iterations on
# solves that converge (docs/solver-notes.md#newton-negative-curvature)
_CREEP = 20


def newton(
    problem: Problem, x: NDArray, stop: StopRule, trace: Trace, *, exact_first: bool = True
) -> Outcome:
    """Minimise ``problem`` from ``x`` (n_nodes, 2) by shifted sparse Newton (see module).

    After a full step the next step first tries projected conjugate gradients preconditioned
    by the last factorisation (:func:`~.reuse.projected_pcg`: a few triangular solves instead of a
    new factorisation); it refactorises when that fails. While the Levenberg-Marquardt shift
    is positive, that solve is of the shifted model the refactorisation would factorise
    (the exact Hessian, still indefinite, made every reuse fail on negative curvature);
    when that model meets negative curvature, the model of the factor's own (larger) shift
    is tried before a refactorisation, and the direction found spares the factorisations
    it proves indefinite (:func:`factor_positive_model`; docs/solver-notes.md#newton-reuse).

    Rod clamps (``exact_first``): the problem with exact clamps is solved first, and the
    rods from its equilibrium (or from ``x`` where that fails).
    """
    if not problem.free_flat.size:  # every node pinned: nothing moves (clamps checked before)
        trace.record(0.0, 0)
        return Outcome(np.array(x, dtype=np.float64), 0, True, certified=True)
    if problem.free_flat.size <= TR_DENSE_MAX:
        return trust_region_newton(problem, problem.start(x), stop, trace)
    if exact_first and problem.clamp == "rod" and problem.n_clamps:
        # stiff rods held far from their lengths creep from the start; the exact clamps'
        # equilibrium is a rod's to within the rods' compliance, and it has the linear
        # predictor: solved first, the rods follow (docs/solver-notes.md#newton-rods)
        exact = newton(problem.as_exact(), x, stop, trace)
        if exact.converged:
            trace.base += exact.iterations
            rods = newton(problem, exact.x, stop, trace, exact_first=False)
            trace.base -= exact.iterations
            return replace(rods, iterations=exact.iterations + rods.iterations)
    net = problem.net
    springs, k = net.springs, net.stiffness
    all_springs = problem.all_springs()
    pattern = pattern_for(
        springs, net.n_nodes, problem.free, net.positions, sparse_solver=problem.sparse_solver
    )
    coords = pattern.coords
    m = problem.n_clamps if problem.exact else 0
    rho = rho_base = float(np.max(k)) if m else 0.0
    shift = 0.0
    exact_ok = True
    certified = False  # see _CERTIFY_MOVE
    mean_rest = problem.mean_rest_length
    move_per_residual = 0.0  # of the last full step (max coordinate move / residual)
    # a few clamps: a dense Jacobian, whose products cost less than scipy.sparse's overhead
    dense_jacobian = dense_jacobian_pays(problem.n_clamps, pattern.size)
    x = np.array(x, dtype=np.float64)
    if m > 1 and dependent_clamps(problem, x).size:
        # clamped springs in a line, say: no KKT step lengthens them (singular Schur
        # complement); off the line by a nudge, the projection onto the clamps can
        x = problem.onto_clamps(problem.nudged(x), coords)
    reusable, factor_shift = None, 0.0  # factor_shift: the shift reusable was made with
    solver: Factor | None = None  # what solved the step (geodesic_path solves with it too)
    if m:
        y, reusable = _clamp_predictor(problem, pattern, x, rho, stop, dense_jacobian)
    else:
        y, reusable = _pin_predictor(problem, pattern, x)
    first = 0 if y is x else 1  # the predictor is a Newton step: counted when taken
    x = y
    x = problem.start(x)  # the clamped springs set to their lengths
    stiff = StiffSprings.find(problem, coords)

    best, best_it = np.inf, first  # the best residual so far, and when it was reached
    for it in range(first, stop.max_iter + 1):
        grad = spring_gradient(x, *all_springs).ravel()[coords]
        if not np.all(np.isfinite(grad)):
            return Outcome(x, it, False, "forces became non-finite (the network blew up)")
        if problem.n_clamps:
            A = problem.clamp_jacobian(x, coords, dense=dense_jacobian)
            lam_ls = clamp_tensions(A, grad, problem.scale[coords])
            force = grad + A.T @ lam_ls  # clamp-normal (rod or constraint) forces removed
        else:
            A, lam_ls, force = None, np.empty(0), grad
        viol = problem.clamp_violation(x) if m else np.empty(0)
        residual = stop.imbalance(force, coords)
        if problem.clamp == "rod":  # Problem.clamp_balance from the total (rod) tensions
            clamp_error = stop.clamp_error(-lam_ls / problem.rod_stiffness)
        else:
            clamp_error = stop.clamp_error(viol)
        trace.record(residual, it)
        if stop.met(residual, clamp_error):
            return Outcome(x, it, True, certified=certified)
        if residual < 0.5 * best:
            best, best_it = residual, it
        elif it - best_it >= _STAGNANT:
            if residual <= 10.0 * roundoff_floor(problem, x):
                return Outcome(x, it, False, f"no progress in {_STAGNANT} iterations", stalled=True)
            best_it = it  # not at round-off: judged again after as many iterations
        if it == stop.max_iter:
            return Outcome(x, it, False, f"no convergence in {stop.max_iter} iterations")
        if trace.elapsed() > stop.max_seconds:
            return Outcome(x, it, False, f"time budget of {stop.max_seconds:g} s exceeded")

        step = lam = None
        indefinite = None  # (shift, direction): W + shift D met negative curvature along it
        # inexact Newton (Eisenstat-Walker-like forcing term): a relative solve error eta
        # leaves a residual ~ eta * residual, superlinear with eta = sqrt(residual) (fewer
        # solves than eta = residual, same iterations). Not below 0.5 tol / residual
        # (Kelley's safeguard against oversolving): a last step from just above the
        # tolerance needs no accurate solve (docs/solver-notes.md#newton-forcing)
        enough = min(0.5, 0.5 * stop.tol / max(residual, 1e-300))  # residual 0: clamps only
        eta = max(min(1e-1, np.sqrt(residual)), enough)
        # a shifted factorisation is not reused once the shift is 0: the exact Hessian is
        # factorised instead, which gives a pure Newton step; near convergence an exact
        # one is not reused either, so that the last step certifies the minimum in the
        # loop (_CERTIFY_MOVE; else the second-order check of relax factorises it)
        # and only when the step is expected to move little enough to certify: a step
        # moves about as much, against its residual, as the last one did
        # (docs/solver-notes.md#newton-certificate)
        near = (
            residual <= _FRESH_NEAR * stop.tol
            and shift == 0.0
            and residual * move_per_residual <= _CERTIFY_MOVE * mean_rest
        )
        certifying = False
        if reusable is not None and not (shift == 0.0 and not exact_ok) and not near:
            budget = reuse_budget(pattern.size, problem.sparse_solver)
            W = assemble_hessian(pattern, lagrangian_blocks(problem, x, lam_ls[:m], rho))
            # the damped model a refactorisation would solve now; when that (a shift decayed
            # after full steps) is indefinite, the model the factor was made for, before
            # any refactorisation (docs/solver-notes.md#newton-reuse)
            trials = (shift, factor_shift) if factor_shift > shift else (shift,)
            scale = marquardt_scale(W) if trials[-1] > 0.0 else None
            for trial in trials:
                model = shifted(W, trial, scale) if trial > 0.0 else W
                try:
                    step, lam = projected_pcg(
                        model, reusable, grad, A if m else None, viol, rtol=eta, max_iter=budget
                    )
                except NegativeCurvature as negative:
                    indefinite = (trial, negative.direction)
                    continue
                except (SolveFailed, np.linalg.LinAlgError):
                    pass
                break
            if step is not None:
                shift = trial  # the model solved (trials never go below shift)
                solver = reusable
        if step is None:
            factor = reusable = solver = None  # released first: one factorisation alive at a time
            # unpacked, not kept: the next refactorisation releases the factor first
            factor, rho, shift, exact_ok, model, negative = factor_positive_model(
                problem, pattern, x, lam_ls[:m], rho, shift, indefinite=indefinite
            )
            if factor is None:
                return Outcome(x, it, False, "Hessian could not be made positive definite")
            if negative is not None and it - best_it >= _CREEP:
                indefinite = (0.0, negative)  # a creep: follow what the exact Hessian showed
            # reuse only pays above the dense size; with rods the gradient's huge axial part
            # makes CG's relative tolerance meaningless for the rest. A shifted factor also
            # preconditions the exact Hessian (negative curvature makes CG fail: refactorise)
            reuse = pattern.size > DENSE_MAX and problem.clamp == "exact"
            try:
                step, lam = _fresh_step(
                    factor, model, grad, A if m else None, viol, eta, reuse, problem.sparse_solver
                )
            except np.linalg.LinAlgError:
                return Outcome(
                    x,
                    it,
                    False,
                    "clamp constraints are degenerate (singular Schur complement)",
                )
            reusable = factor if reuse else None
            solver = factor
            factor_shift = shift
            certifying = exact_ok and shift == 0.0
        start = x
        x, alpha = line_search(
            problem,
            x,
            coords,
            step,
            grad,
            A if m else None,
            viol,
            lam,
            rho,
            residual,
            stiff=stiff,
            geodesic=geodesic_path(problem, x, coords, step, solver, A if m else None)
            if shift == 0.0
            else None,
        )
        if indefinite is not None:  # negative curvature known: follow it if that goes lower
            x, alpha = follow_curvature(
                problem, coords, start, (x, alpha), indefinite[1], step, grad,
                A if m else None, viol, lam, rho,
            )  # fmt: skip
        move = float(np.max(np.abs(x - start), initial=0.0))
        if alpha == 1.0 and residual > 0.0:
            move_per_residual = move / residual
        certified = certifying and alpha > 0.0 and move <= _CERTIFY_MOVE * mean_rest
        if alpha == 0.0:
            # no decrease along the step: damp 100x harder and refactorise (Levenberg-
            # Marquardt as a trust region); only no decrease at DAMP_GIVE_UP gives up
            if shift >= DAMP_GIVE_UP:
                return Outcome(x, it + 1, False, "line search found no decrease", stalled=True)
            shift, reusable = max(100.0 * shift, DAMP_RETRY), None
            continue
        # Levenberg-Marquardt: a cut step asks for more damping next time, a full one less.
        # A step cut to a quarter or more only doubles it (Nielsen's gentler growth: 10x
        # makes the shift oscillate between two decades; docs/solver-notes.md#newton-damping)
        if alpha < 1.0:
            reusable = None
            shift = max((DAMP_UP if alpha < 0.25 else DAMP_UP_MILD) * shift, DAMP_MIN)
        else:
            shift = shift / 10 if shift > 10 * DAMP_MIN else 0.0
            # the augmentation decays back too: grown without bound over hundreds of
            # iterations it swamps W in round-off
            rho = max(rho_base, rho / 10)
    return Outcome(x, stop.max_iter, False, "no convergence")


def _clamp_predictor(
    problem: Problem,
    pattern: HessianPattern,
    x: NDArray,
    rho: float,
    stop: StopRule,
    dense_jacobian: bool,
) -> tuple[NDArray, Factor | None]:
    """Newton's first step: the linear response to the clamps where it is trustworthy.

    :meth:`~.constraints.Problem.start` alone moves only the clamped springs' end nodes,
    which at a strain of order 1 leaves their neighbours far off and the Hessian
    indefinite. When the clamps are not met at ``x`` (n_nodes, 2) and the Lagrangian
    Hessian there is positive definite, one Newton step of the KKT system (no line
    search: the linear elastic response to the clamp lengths, prestress relaxed with it)
    is taken first; the caller then sets the clamped springs to their lengths. The step is
    refused when it turns any other spring by more than 90 degrees (the linearisation of
    the rotations has failed, e.g. springs crossed over at large strain). Returns the
    positions after the step (``x`` itself when it
    was not taken) and the factorisation (None when none was made). The next iterations
    reuse it, also after a refused step: conjugate gradients preconditioned by it either
    solve the start's Newton step or meet negative curvature along a direction that
    spares the factorisations bound to fail (:func:`factor_positive_model`).
    Measurements: ``docs/solver-notes.md#newton-clamp-predictor``.
    """
    viol = problem.clamp_violation(x)
    if stop.clamp_error(viol) <= stop.tol:
        return x, None
    coords = pattern.coords
    grad = spring_gradient(x, *problem.all_springs()).ravel()[coords]
    A = problem.clamp_jacobian(x, coords, dense=dense_jacobian)
    lam = clamp_tensions(A, grad, problem.scale[coords])
    factor = factor_spd(
        assemble_hessian(pattern, lagrangian_blocks(problem, x, lam, rho)),
        ordered=pattern.ordered,
        rough=True,
        sparse_solver=problem.sparse_solver,
    )
    if factor is None:
        return x, None
    try:
        step, _ = _kkt_step(factor, grad, A, viol, problem.n_clamps)
    except np.linalg.LinAlgError:
        return x, None
    y = x.copy()
    y.ravel()[coords] += step
    springs = problem.net.springs
    turned = _turned_over(x, y, springs)
    turned[problem.clamp_springs] = False
    if not np.all(np.isfinite(y)) or turned.any():
        return x, factor
    return y, factor


def _pin_predictor(
    problem: Problem, pattern: HessianPattern, x: NDArray
) -> tuple[NDArray, Factor | None]:
    """Newton's first step when the start is the network's geometry with pinned nodes moved.

    ``x`` (n_nodes, 2) equal to ``net.positions`` on every free coordinate and off it on
    some pinned ones (a source displaced and held, e.g.
    :func:`~continuum_vs_network.continuum.transmission.network_patch_source`): the start
    leaves the whole displacement in the springs next to the pins. The Newton step of the
    geometry with the pins' displacement as its load (the linear elastic response, about
    where the network is linear) spreads it over the network. It is taken when it lowers
    the energy below the start's and turns no spring by more than 90 degrees (as
    :func:`_clamp_predictor`); otherwise ``x`` is kept. Problems with clamps, and any
    other start, are returned unchanged, with no factorisation (a warm start from an
    earlier equilibrium is nearer than the geometry). Returns the positions and the
    factorisation made (None when none was), which the next iterations reuse. At large
    pin displacements the step raises the energy and is refused. The dense trust region
    (:mod:`.trust`) does not use it and starts from ``x`` (there it costs iterations;
    measurements: ``docs/solver-notes.md#newton-pin-predictor``).
    """
    net = problem.net
    free = problem.free
    reference = net.positions
    if problem.n_clamps or not np.array_equal(x[free], reference[free]):
        return x, None
    load = np.where(free, 0.0, x - reference)  # the pins' displacement
    if not np.any(load):
        return x, None
    springs = problem.all_springs()
    blocks = lagrangian_blocks(problem, reference, np.empty(0), 0.0)
    # gradient at the geometry plus the Hessian times the displacement (spring by spring)
    stretch = np.einsum("sij,sj->si", blocks, spring_vectors(load, net.springs))
    rhs = spring_gradient(reference, *springs) + _scatter_nodes(stretch, net.springs, net.n_nodes)
    factor = factor_spd(
        assemble_hessian(pattern, blocks),
        ordered=pattern.ordered,
        rough=True,
        sparse_solver=problem.sparse_solver,
    )
    if factor is None:
        return x, None
    y = x.copy()
    y.ravel()[pattern.coords] = reference.ravel()[pattern.coords] - factor.solve(
        rhs.ravel()[pattern.coords]
    )
    if not np.all(np.isfinite(y)) or _turned_over(reference, y, net.springs).any():
        return x, factor
    if not spring_energy_change(y, x, *springs) < 0.0:
        return x, factor
    return y, factor


def _turned_over(before: NDArray, after: NDArray, springs: NDArray) -> NDArray:
    """Per spring (s,): True where positions ``after`` (n_nodes, 2) point it at least 90
    degrees away from ``before``: a predictor's linearised rotation has failed there."""
    vectors = spring_vectors(before, springs), spring_vectors(after, springs)
    return np.einsum("ij,ij->i", *vectors) <= 0.0


def _fresh_step(
    factor: Factor,
    model: sp.csr_matrix | NDArray,
    grad: NDArray,
    A: sp.csr_matrix | None,
    viol: NDArray,
    eta: float,
    refine: bool,
    sparse_solver: str = "auto",
) -> tuple[NDArray, NDArray]:
    """The Newton step of ``model`` (the matrix just factorised) from its ``factor``.

    A float32 factor (``factor.approximate``) solves only to ~1e-7 times the condition
    number: where ``refine`` (the projected CG pays), conjugate gradients on ``model``
    preconditioned by it take the step to the forcing tolerance ``eta``, usually in no
    iteration beyond its first solve (unrefined direct steps can stall short of a tight
    tolerance: ``docs/solver-notes.md#newton-fresh-step``). Otherwise the direct KKT step.
    """
    if refine and factor.approximate:
        try:
            return projected_pcg(
                model, factor, grad, A, viol, rtol=eta,
                max_iter=reuse_budget(model.shape[0], sparse_solver),
            )  # fmt: skip
        except (SolveFailed, NegativeCurvature, np.linalg.LinAlgError):
            pass  # float32 round-off beyond CG's reach: the direct step
    return _kkt_step(factor, grad, A, viol, 0 if A is None else A.shape[0])


def _kkt_step(
    solver: Factor, grad: NDArray, A: sp.csr_matrix | None, viol: NDArray, m: int
) -> tuple[NDArray, NDArray]:
    """Newton step of the KKT system (:func:`~..linalg.kkt.range_space`): ``(step, multipliers)``
    with ``W step + A^T lam = -grad`` and ``A step = -viol``."""
    if not m:
        return -np.asarray(solver.solve(grad)), np.empty(0)
    return range_space_solve(solver, A, -grad, -viol)[1]
