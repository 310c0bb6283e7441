"""Trust-region Newton that follows negative curvature, scaled for stiffness contrast.

For problems up to :data:`TR_DENSE_MAX` free coordinates :func:`newton` uses this method:
each iteration

1. takes the Lagrangian Hessian ``W`` (:func:`~.lagrangian.lagrangian_hessian`, rods
   included), the gradient and the clamp Jacobian ``A``; the multipliers in ``W`` are the
   least-squares clamp tensions in the metric ``D^-1`` in which trials are moved back onto
   the clamps (step 4): then the model of the energy along the clamps is exact to second
   order also away from equilibrium (with ``relax``'s residual tensions, weighted by the
   local force scale, it is not, and prestressed networks creep at a constant radius;
   Euclidean tensions fail elsewhere: ``docs/solver-notes.md#trust-multipliers``);
2. scales every coordinate by its node's stiffness ``kappa_i = sum_j k_j`` over its springs
   and rods (``x = D^-1/2 z``): a stiff region and a soft one get steps of the same
   energetic size, which is what makes contrasts of 1e12 harmless;
3. solves the trust-region subproblem exactly on the tangent space of the clamps
   (``Q`` an orthonormal basis of ``null(A D^-1/2)``, eigen-decomposition of the reduced
   Hessian ``Q^T D^-1/2 W D^-1/2 Q``): the Newton step when the reduced Hessian is positive
   definite and the step fits, otherwise the boundary step of the smallest admissible
   shift, following negative curvature (the "hard case" adds the lowest eigenvector).
   When nothing is pinned (``relax`` under default pins), the three rigid motions are
   removed the same way, as rows of that null space: pins whose lever shortens in a large
   deformation would leave a nearly free rotation to creep along;
4. bends the step by its geodesic acceleration (:func:`_trial`): a linear step that turns
   a spring lengthens it by ``|turn|^2 r / 2``, so the step through a curved valley (a
   stiff spring swinging about soft ones) is corrected to second order; then moves back
   onto the clamp lengths (Gauss-Newton projection, minimum-norm in the metric
   ``D^-1``: the scaled coordinates' own) and puts springs stiffer than
   :attr:`~.stiff_springs.StiffSprings.CONTRAST` times the median back to the lengths the
   linear model predicted (:class:`~.stiff_springs.StiffSprings`); where that projection
   gives up (lengths a long step cannot reach), the iterate nearest them is taken, and the
   trial is the lower in energy of the projected and the plain point;
5. accepts the step when the energy falls by a fair share of the model's prediction
   (computed without cancellation), and grows or shrinks the radius by the ratio; while a
   step on the boundary keeps its promise, radii twice as large are tried at the same
   Hessian (up to :data:`_GROW_TRIES` times), then the radius between the last good one
   and the first worse one, so a long descent takes few Hessians; where stiff springs are
   projected, an accepted step that kept less than 3/4 of its promise is halved (up to
   :data:`_SHORTER_TRIES` times) while the energy falls further.

What each of these parts gained, measured on ``benchmarks/bench_family.py``, is recorded
in ``docs/solver-notes.md#trust``.

Cost on small problems (the paper's N = 10 patch: 20 coordinates), where numpy's per-call
overhead is the cost: the spring terms are dense
incidence products (:mod:`.trust_kernels`, up to 32 nodes) and the reduced Hessian is
assembled in the model's basis from the springs' length and rotation Jacobians, without an
(n, n) matrix; under default pins the rigid motions are removed by Householder
reflections (:class:`~.trust_model.RigidBasis`: translations once, the rotation at each
iterate) instead of an SVD; each model is first factored by Cholesky, whose success with a
shift of ``1e-8`` is the second-order certificate, and is eigen-decomposed only when a
trial needs a boundary step, after which every trial at that model solves the secular
equation and the bending correction on the eigenvalues (:mod:`.trust_model`); an accepted
trial's spring geometry is the next gradient's; products are ``ndarray.dot`` (see
:mod:`.trust_kernels`). What the network, pins and clamp set alone
decide (the frame, ``D^-1/2``, the stiff springs, the translation basis) is kept while the
network lives (:func:`_setup`), so repeated solves of one network skip it.
``benchmarks/bench_patch.py --against OLD_CHECKOUT`` compares this cost with another
checkout.

Near the solution the radius no longer binds and the iteration is Newton's, quadratically
convergent. Saddles cannot be returned: a step along a negative eigenvector always lowers
the model.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack

from ..linalg.memo import per_network
from .constraints import Problem, clamp_tensions
from .lagrangian import Frame
from .stiff_springs import StiffSprings, median
from .stopping import Outcome, StopRule, Trace
from .trust_kernels import kernels
from .trust_model import Model, RigidBasis, null_basis, rigid_motions, subproblem

__all__ = ["ACCEL_MAX", "TR_DENSE_MAX", "trust_region_newton"]

TR_DENSE_MAX = 400  # free coordinates; above, the sparse shifted Newton of newton.py (faster there)
_ETA = 1e-4  # acceptance threshold on actual / predicted decrease
_GROW = 2.0  # radius growth after a good step that reached the boundary
_GROW_TRIES = 6  # doublings of the radius tried at one Hessian while the model holds
_MID = math.sqrt(2.0)  # the radius tried between the last good doubling and a worse one
# halvings tried at one Hessian after a step of ratio below 0.75, only where stiff springs
# are projected: they are for trials whose projection gave up (see the module); with no
# stiff spring they save no iteration and cost trials (docs/solver-notes.md#trust-shorter-tries)
_SHORTER_TRIES = 4
_NOISY = 4.0  # a ratio above this is checked for an energy change at round-off
ACCEL_MAX = 0.75  # largest |geodesic acceleration| / |step| used (Transtrum & Sethna)
_ACCEL2 = ACCEL_MAX**2
_EMPTY = np.empty(0)


def _node_stiffness(problem: Problem) -> NDArray:
    """``kappa`` per flat coordinate: the sum of the stiffnesses at its node (rods too)."""
    springs, k, _ = problem.all_springs()
    n = problem.net.n_nodes
    kappa = np.bincount(springs[:, 0], k, n) + np.bincount(springs[:, 1], k, n)
    low = kappa <= 0
    if np.count_nonzero(low):
        positive = kappa[~low]
        kappa[low] = float(np.min(positive)) if positive.size else 1.0
    return np.repeat(kappa, 2)


def _setup(problem: Problem) -> tuple:
    """What a solve needs that the network, pins and clamp set alone decide: the frame,
    the stiff springs, ``D^-1/2`` on the free coordinates (read-only), the mean rest
    length, and the median and the sum of ``kappa`` there; kept while the network lives
    (its arrays are read-only), so repeated solves of one network skip them."""
    net = problem.net
    key = (
        problem.free.tobytes(), problem.clamp_springs.tobytes(), problem.clamp,
        problem.rod_stiffness,
    )  # fmt: skip
    per = per_network(net, "trust_setup")
    hit = per.get(key)
    if hit is not None:
        return hit
    frame = Frame(net, problem.free, sparse_solver=problem.sparse_solver)
    coords = frame.coords
    stiff = StiffSprings.find(problem, coords)
    kappa = _node_stiffness(problem)
    kappa = kappa if coords.size == 2 * net.n_nodes else kappa[coords]
    inv_root = 1.0 / np.sqrt(kappa)
    inv_root.setflags(write=False)
    mean_rest = problem.mean_rest_length
    hit = per[key] = (
        frame, stiff, inv_root, mean_rest, median(kappa), float(np.add.reduce(kappa))
    )  # fmt: skip
    return hit


def _trial(
    problem: Problem,
    model: Model,
    radius: float,
    stiff: StiffSprings | None,
    coords: NDArray,
    full: bool,
    metric: NDArray | None,
) -> tuple[NDArray, float, float, float]:
    """The trust-region step of ``radius`` taken from ``model.x``: the new positions, the
    step's scaled length, and the predicted and actual energy changes (not finite when
    the positions are not). ``coords``: the free flat coordinates (``full``: all of them, in
    order); ``metric`` (n,): ``1 / kappa`` on them, in which a trial is moved back onto
    exact clamps (None: the problem has none; see :func:`trust_region_newton`).

    The step is bent by its geodesic acceleration (Transtrum & Sethna 2012): the
    second-order length change ``|dd_perp|^2 / r`` of every spring along the linear step
    exerts forces, corrected by the same (shifted) model Hessian, so that a step that turns
    a stiff spring does not stretch it. Then stiff springs are put back to the lengths the
    linear model predicted and the clamps met again.
    """
    terms = model.terms
    if model.spectrum is None and model.newton_length <= radius:  # Newton, by Cholesky
        p, length = model.newton, model.newton_length
        predicted = 0.5 * float(model.gr.dot(p))  # gr.p + p.H.p / 2 with H p = -gr
        step = model.lift(p)
        back = lapack.dpotrs(model.factor, terms.reduced_bending(p, step))[0]
    else:  # in the eigenbasis: the subproblem and the bending solve are vector operations
        spec = model.eigen()
        c, den, length = subproblem(spec, radius)
        predicted = float(c.dot(spec.gt + spec.half_vals * c))
        vecs = model.vecs
        p = vecs.dot(c)
        step = model.lift(p)
        bend = terms.reduced_bending(p, step).dot(vecs)
        if den[0] > spec.tiny:  # ascending: every shifted eigenvalue is kept
            back = vecs.dot(bend / den)
        else:
            ok = den > spec.tiny
            back = vecs.dot(np.where(ok, bend / np.where(ok, den, 1.0), 0.0))
    # the acceleration is -lift(back): negated at the end (the same numbers, one call less)
    back = model.lift(back)
    move = step - 0.5 * back if back.dot(back) <= _ACCEL2 * step.dot(step) else step
    x = model.x
    if full:
        move = move.reshape(x.shape)
        y = x + move
    else:
        y = x.copy()
        y.ravel()[coords] += move
        move = None
    z, met = stiff.nearest(y, x, step) if stiff is not None else (None, False)
    if z is not None:
        z = problem.onto_clamps(z, coords, metric) if metric is not None else z
        restored = terms.energy_change(z)
        if met:
            return z, length, predicted, restored
    if metric is not None:
        y, move = problem.onto_clamps(y, coords, metric), None
    plain = terms.energy_change(y, move)
    # where the projection gave up, the trial is the lower of its nearest and the plain point
    if z is not None and not (
        math.isfinite(plain) and (plain < restored or not math.isfinite(restored))
    ):
        return z, length, predicted, restored
    return y, length, predicted, plain


def _better(trial: tuple[NDArray, float, float, float], actual: float) -> bool:
    """A wider trial (:func:`_trial`'s tuple) falls below ``actual`` and keeps a quarter
    of its model's promise."""
    predicted, change = trial[2], trial[3]
    return change < actual and predicted < 0 and change / predicted > 0.25


def trust_region_newton(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """Minimise ``problem`` from ``x`` (n_nodes, 2) by the trust-region method of the module."""
    net = problem.net
    frame, stiff, inv_root, mean_rest, kappa_median, kappa_sum = _setup(problem)
    coords = frame.coords
    n = coords.size
    # every coordinate free, in natural order (frames above spd.DENSE_MAX are reordered)
    full = n == 2 * net.n_nodes and bool(np.all(coords[1:] > coords[:-1]))
    m = problem.n_clamps if problem.exact else 0
    terms = kernels(problem, frame, inv_root)
    metric = inv_root * inv_root if m else None  # 1 / kappa: the trials' clamp projection
    root_kappa = 1.0 / inv_root if m else None
    start = np.array(x, dtype=np.float64)
    x = problem.onto_clamps(start, coords)
    if m and stop.clamp_error(problem.clamp_violation(x)) > 1e-6:
        # a start where the clamp directions are dependent (clamped springs in a line
        # between pins) gives the projection no direction to lengthen them: off the line
        x = problem.onto_clamps(problem.nudged(start), coords)
    if m and stop.clamp_error(problem.clamp_violation(x)) > 1e-6:
        return Outcome(
            x,
            0,
            False,
            "the clamp lengths cannot all be met (the projection onto them does not converge): "
            f"clamps on springs {problem.clamp_springs.tolist()} are incompatible in the "
            "plane, e.g. all six distances among four nodes clamped (chains shorter than a "
            "clamp or a pinned distance are refused before the solve)",
        )
    rigid = not problem.free_flat.size < problem.free.size  # nothing pinned
    rigid_basis = RigidBasis(x, inv_root, mean_rest) if rigid and not m else None
    radius = 0.25 * mean_rest * math.sqrt(kappa_median * n)
    smallest = 1e-15 * math.sqrt(kappa_sum) * mean_rest  # collapsed radius
    scale = stop.scale if full else stop.scale[coords]
    rod = problem.clamp == "rod"
    model: Model | None = None  # the last iteration's model (its certificate)

    def attempt(r: float) -> tuple[NDArray, float, float, float]:
        """:func:`_trial` of radius ``r`` at the current model, kept by radius: the radius
        tries come back to a radius already tried at the same Hessian (a doubling from a
        quarter of a rejected one), whose step is then not computed again."""
        hit = model.trials.get(r)
        if hit is None:
            hit = model.trials[r] = _trial(problem, model, r, stiff, coords, full, metric)
        return hit

    for it in range(stop.max_iter + 1):
        g = terms.gradient(x)
        if problem.n_clamps:
            if not np.isfinite(g).all():
                return Outcome(x, it, False, "forces became non-finite (the network blew up)")
            A = problem.clamp_jacobian(x, coords, dense=True)
            mu = clamp_tensions(A, g, problem.scale[coords])
            force = g + A.T.dot(mu)
        else:
            A, mu, force = None, _EMPTY, g
        # stop.imbalance (not finite where a force is not)
        residual = float(np.maximum.reduce(np.abs(force) / scale)) if n else 0.0
        if not math.isfinite(residual):
            return Outcome(x, it, False, "forces became non-finite (the network blew up)")
        if rod:
            clamp_error = stop.clamp_error(-mu / problem.rod_stiffness)
        else:
            clamp_error = stop.clamp_error(problem.clamp_violation(x)) if m else 0.0
        trace.record(residual, it)
        if stop.met(residual, clamp_error):
            return Outcome(x, it, True, certified=model is not None and model.certified)
        if it == stop.max_iter:
            return Outcome(x, it, False, f"no convergence in {stop.max_iter} iterations")
        if trace.elapsed() > stop.max_seconds:
            return Outcome(x, it, False, f"time budget of {stop.max_seconds:g} s exceeded")
        if rigid_basis is not None:
            basis = rigid_basis(x)
        elif m or rigid:
            if m and rigid:
                rows = np.vstack([A[:m], rigid_motions(x, coords)])
            else:
                rows = A[:m] if m else rigid_motions(x, coords)
            basis = null_basis(rows * inv_root[None, :]) * inv_root[:, None]
        else:
            basis = None
        # the model's multipliers in the metric its trials are put back onto the clamps in
        H = terms.reduced_hessian(clamp_tensions(A, g, root_kappa) if m else mu, basis)
        # a spring of zero length has no curvature direction; a finite sum (one reduction)
        # proves every entry finite, an inf or NaN entry would make it inf or NaN
        if not math.isfinite(np.add.reduce(H, None)) and not np.isfinite(H).all():
            return Outcome(x, it, False, "the Hessian is not finite (a spring of zero length?)")
        gr = basis.T.dot(g) if basis is not None else g * inv_root
        model = Model(x, H, gr, basis, inv_root, terms)

        accepted = newton_tried = False
        level = None  # the energy change at round-off (computed when first needed)
        for _ in range(40):
            y, length, predicted, actual = attempt(radius)
            if math.isfinite(actual):
                ratio = actual / predicted if predicted < 0 else -1.0
                noise = False  # the energy change at round-off: judged by the force below
                if ratio <= _ETA or ratio > _NOISY:  # no decrease, or far more than promised
                    if level is None:  # |E(x)| once per model (x is fixed until a step)
                        level = 1e-13 * abs(problem.energy(x)) + 1e-300
                    noise = abs(actual) <= level and abs(predicted) <= level
                if ratio > _ETA and not noise:
                    if ratio > 0.75 and length >= 0.99 * radius:
                        # the model holds to the boundary: look further along it at the
                        # same Hessian while the energy keeps falling
                        for _ in range(_GROW_TRIES):
                            wider = attempt(2 * radius)
                            if not _better(wider, actual):
                                # between the two: the falling energy's turning point
                                mid = attempt(_MID * radius)
                                if _better(mid, actual):
                                    y, length, actual = mid[0], mid[1], mid[3]
                                    radius *= _MID
                                break
                            y, length, _, actual = wider
                            radius *= 2
                            if length < 0.99 * radius:
                                break
                        if length >= 0.99 * radius:
                            radius *= _GROW
                    elif ratio < 0.75:
                        # a poor step: a shorter one along the same path may fall further
                        # (where stiff springs are projected: see _SHORTER_TRIES)
                        shorter, r = None, length
                        for _ in range(_SHORTER_TRIES if stiff is not None else 0):
                            r *= 0.5
                            trial = attempt(r)
                            if not trial[3] < actual:
                                break
                            y, length, predicted, actual = trial
                            shorter = actual / predicted if predicted < 0 else 0.0
                        if shorter is not None:
                            radius = length * (_GROW if shorter > 0.75 else 1.0)
                        elif ratio < 0.25:
                            radius = 0.25 * length
                    x, accepted = y, True
                    break
                if noise:
                    if problem.residual(y).imbalance < residual:
                        x, accepted = y, True
                        break
                    if model.certified and length < model.newton_length and not newton_tried:
                        # the radius was shrunk by energies the noise decides: the Newton
                        # step itself, whose residual the force can judge (else the trials
                        # shrink far below it and the solve stalls)
                        radius, newton_tried = model.newton_length, True
                        continue
            radius = 0.25 * min(radius, length)
            if radius <= smallest:
                break
        if not accepted:
            return Outcome(
                x, it + 1, False, "trust region collapsed (no decrease possible)", stalled=True
            )
    return Outcome(x, stop.max_iter, False, "no convergence")
