"""Trust-region Newton that follows negative curvature, scaled for stiffness contrast.

For problems up to :data:`TR_DENSE_MAX` free coordinates :func:`newton` uses this method:
each iteration

1. takes the Lagrangian Hessian ``W`` (:func:`~.lagrangian.lagrangian_hessian`, exact
   multipliers ``mu``, rods included), the gradient and the clamp Jacobian ``A``;
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
   onto the clamp lengths (Gauss-Newton projection) and puts springs stiffer than
   :data:`_CONTRAST` times the median back to the lengths the linear model predicted
   (:class:`StiffSprings`);
5. accepts the step when the energy falls by a fair share of the model's prediction
   (computed without cancellation), and grows or shrinks the radius by the ratio; while a
   step on the boundary keeps its promise, radii twice as large are tried at the same
   Hessian (up to :data:`_GROW_TRIES` times), so a long descent takes few Hessians.

On the 500-network family of ``benchmarks/bench_family.py`` these took the median from 82
to 25 iterations (p95 349 to 74). On its first 100 networks (median 71.5, p95 320 before):
rigid motions removed 50 / 240; with the geodesic step 37.5 / 161; with the radius tries
33.5 / 126; with stiff springs from 10x the median (not 1e3x) 23 / 75.

Near the solution the radius no longer binds and the iteration is Newton's, quadratically
convergent. Saddles cannot be returned: a step along a negative eigenvector always lowers
the model.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .constraints import Problem, clamp_tensions
from .energy import _scatter_nodes, spring_energy_change, spring_gradient
from .lagrangian import Frame, lagrangian_blocks
from .stopping import Outcome, StopRule, Trace

__all__ = [
    "TR_DENSE_MAX",
    "StiffSprings",
    "null_basis",
    "rigid_motions",
    "trust_region_newton",
]

TR_DENSE_MAX = 400  # free coordinates; above, the sparse shifted Newton of newton.py (faster there)
_ETA = 1e-4  # acceptance threshold on actual / predicted decrease
_GROW = 2.0  # radius growth after a good step that reached the boundary
_GROW_TRIES = 6  # doublings of the radius tried at one Hessian while the model holds
_ACCEL_MAX = 0.75  # largest |geodesic acceleration| / |step| used (Transtrum & Sethna)
_CONTRAST = 10.0  # springs this much stiffer than the median are put back (StiffSprings)


class StiffSprings:
    """Springs much stiffer than the network's median (and exact clamps), and a projection
    onto their lengths.

    ``restore(y, x, dx)`` moves ``y = x + dx`` the least (Gauss-Newton, minimum norm) so
    that every such spring has the length the linear model predicted,
    ``r(x) + u(x) . (dx_b - dx_a)``; None when that does not converge. A linear step that
    rotates a spring lengthens it by ``|rotation|^2 r / 2``: for a spring ``1e3``-``1e12``
    times stiffer than the rest that second-order error alone would veto the step.
    """

    CONTRAST = 1e3

    def __init__(self, springs: NDArray, index: NDArray, n: int) -> None:
        self.springs = springs
        self.index = index
        self.n = n

    @classmethod
    def find(
        cls, problem: Problem, coords: NDArray, *, contrast: float | None = None
    ) -> StiffSprings | None:
        """Springs ``contrast`` (default :attr:`CONTRAST`) times stiffer than the median."""
        contrast = cls.CONTRAST if contrast is None else contrast
        springs, k, _ = problem.all_springs()
        positive = k[k > 0]
        if not positive.size:
            return None
        stiff = np.flatnonzero(k > contrast * float(np.median(positive)))
        if not stiff.size:
            return None
        if problem.exact:  # clamps are infinitely stiff springs: restored the same way
            stiff = np.union1d(stiff, problem.clamp_springs)
        index = np.full(2 * problem.net.n_nodes, -1, dtype=np.int64)
        index[coords] = np.arange(coords.size)
        return cls(springs[stiff], index, coords.size)

    def _jacobian(self, x: NDArray) -> tuple[sp.csr_matrix, NDArray]:
        s = self.springs
        d = x[s[:, 1]] - x[s[:, 0]]
        r = np.hypot(d[:, 0], d[:, 1])
        u = d / np.maximum(r, 1e-300)[:, None]
        flat = np.stack([2 * s[:, 0], 2 * s[:, 0] + 1, 2 * s[:, 1], 2 * s[:, 1] + 1], 1)
        vals = np.concatenate([-u, u], axis=1)
        cols = self.index[flat]
        keep = cols >= 0
        rows = np.broadcast_to(np.arange(len(s))[:, None], flat.shape)
        J = sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(len(s), self.n))
        return J, r

    def restore(self, y: NDArray, x: NDArray, dx: NDArray) -> NDArray | None:
        """``dx`` (n,) in the row order of ``coords`` given to :meth:`find`."""
        J0, r0 = self._jacobian(x)
        target = r0 + J0 @ dx
        z = y.copy()
        coords = np.flatnonzero(self.index >= 0)
        order = self.index[coords]
        for _ in range(8):
            J, r = self._jacobian(z)
            c = r - target
            if np.max(np.abs(c)) <= 1e-14 * max(float(np.max(r0)), 1e-300):
                return z
            G = (J @ J.T).tocsc() + 1e-12 * sp.identity(J.shape[0], format="csc")
            try:
                lam = spla.splu(G).solve(c)
            except RuntimeError:
                return None
            move = -(J.T @ lam)
            z = z.copy()
            z.ravel()[coords] += move[order]
            if not np.all(np.isfinite(z)):
                return None
        return None  # no convergence: the caller keeps the unprojected point


def _node_stiffness(problem: Problem) -> NDArray:
    """``kappa`` per flat coordinate: the sum of the stiffnesses at its node (rods too)."""
    springs, k, _ = problem.all_springs()
    n = problem.net.n_nodes
    kappa = np.bincount(springs[:, 0], k, n) + np.bincount(springs[:, 1], k, n)
    positive = kappa[kappa > 0]
    kappa[kappa <= 0] = float(np.min(positive)) if positive.size else 1.0
    return np.repeat(kappa, 2)


def _subproblem(vals: NDArray, vecs: NDArray, gt: NDArray, radius: float) -> tuple[NDArray, float]:
    """Exact solution of ``min g.p + p.H.p / 2, |p| <= radius`` from ``H = V diag(vals) V^T``
    (``gt = V^T g``), in the eigenbasis coordinates' original frame."""

    def step(shift: float) -> NDArray:
        return -(gt / (vals + shift))

    lowest = float(vals[0])
    if lowest > 0:
        p = step(0.0)
        if np.linalg.norm(p) <= radius:
            return vecs @ p, 0.0
    low = max(0.0, -lowest)
    # hard case: the gradient has (almost) no component on the lowest eigenvectors
    tiny = 1e-12 * max(float(np.abs(vals).max()), 1e-300)
    on_low = np.abs(vals - lowest) <= tiny
    if lowest <= 0 and np.linalg.norm(gt[on_low]) <= 1e-10 * max(np.linalg.norm(gt), 1e-300):
        shifted = vals + low
        safe = ~on_low
        p = np.zeros_like(gt)
        p[safe] = -gt[safe] / shifted[safe]
        rest = radius**2 - float(p @ p)
        if rest > 0:
            e = np.flatnonzero(on_low)[0]
            p[e] += np.sqrt(rest) * (1.0 if gt[e] <= 0 else -1.0)
            return vecs @ p, low
    # safeguarded Newton on the secular equation 1/|p(shift)| = 1/radius (More-Sorensen),
    # bracketed by bisection
    g2 = gt * gt
    lo, hi = low, low + np.linalg.norm(gt) / radius + abs(float(vals[-1])) + tiny
    shift = hi
    for _ in range(60):
        inv = 1.0 / (vals + shift)
        norm2 = float(g2 @ (inv * inv))
        norm = np.sqrt(norm2)
        if abs(norm - radius) <= 1e-6 * radius:
            break
        if norm > radius:
            lo = shift
        else:
            hi = shift
        # Newton on phi = 1/radius - 1/|p|, which is nearly linear in the shift
        slope = float(g2 @ (inv * inv * inv)) / (norm2 * norm)  # -d(phi)/d(shift)
        trial = shift + (1.0 / radius - 1.0 / norm) / slope
        shift = trial if lo < trial < hi else 0.5 * (lo + hi)
    return vecs @ step(shift), shift


def rigid_motions(x: NDArray, coords: NDArray) -> NDArray:
    """The rigid motions of ``x`` (n_nodes, 2) at flat coordinates ``coords``, (3, n):
    the two translations and the rotation about the centroid."""
    c = x - x.mean(axis=0)
    full = np.zeros((3, x.size))
    full[0, 0::2] = 1.0
    full[1, 1::2] = 1.0
    full[2, 0::2] = -c[:, 1]
    full[2, 1::2] = c[:, 0]
    return full[:, coords]


def null_basis(M: NDArray) -> NDArray:
    """Orthonormal basis (n, n - rank) of the null space of ``M`` (k, n)."""
    _, sv, vt = np.linalg.svd(M)
    rank = int(np.sum(sv > 1e-12 * max(float(sv[0]), 1e-300))) if sv.size else 0
    return vt[rank:].T


def _bending(x: NDArray, step: NDArray, coords: NDArray, springs, k, L) -> NDArray:
    """``J^T (k r_vv)`` at ``coords``: the force of every spring's second-order length
    change ``r_vv = |dd_perp|^2 / r`` along ``step`` (geodesic acceleration's right side)."""
    full = np.zeros(x.size)
    full[coords] = step
    full = full.reshape(x.shape)
    d = x[springs[:, 1]] - x[springs[:, 0]]
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
    u = d / r[:, None]
    dd = full[springs[:, 1]] - full[springs[:, 0]]
    perp = dd[:, 0] * u[:, 1] - dd[:, 1] * u[:, 0]
    t = (k * perp * perp / r)[:, None] * u
    return _scatter_nodes(t, springs, x.shape[0]).ravel()[coords]


class _Model(NamedTuple):
    """The quadratic model of one iteration, in scaled reduced coordinates."""

    x: NDArray  # (n_nodes, 2) the iterate
    Q: NDArray | None  # (n, r) basis of the clamps' (and rigid motions') tangent space
    H: NDArray  # (r, r) reduced scaled Hessian
    vals: NDArray  # its eigenvalues (r,)
    vecs: NDArray  # and eigenvectors (r, r)
    gr: NDArray  # reduced scaled gradient (r,)
    gt: NDArray  # the same in the eigenbasis
    root_d: NDArray  # (n,) sqrt of the node stiffness per coordinate
    coords: NDArray  # (n,) flat coordinates


def _trial(
    problem: Problem, model: _Model, radius: float, stiff: StiffSprings | None
) -> tuple[NDArray, float, float, float]:
    """The trust-region step of ``radius`` taken from ``model.x``: the new positions, the
    step's scaled length, and the predicted and actual energy changes (inf when the
    positions are not finite).

    The step is bent by its geodesic acceleration (Transtrum & Sethna 2012): the
    second-order length change ``|dd_perp|^2 / r`` of every spring along the linear step
    exerts forces, corrected by the same (shifted) model Hessian, so that a step that turns
    a stiff spring does not stretch it. Then stiff springs are put back to the lengths the
    linear model predicted and the clamps met again.
    """
    x, Q, H, vals, vecs, gr, gt, root_d, coords = model
    all_springs = problem.all_springs()
    ps, shift = _subproblem(vals, vecs, gt, radius)
    predicted = float(gr @ ps + 0.5 * ps @ H @ ps)
    step = (Q @ ps if Q is not None else ps) / root_d
    y = x.copy()
    y.ravel()[coords] += step
    b = _bending(x, step, coords, *all_springs) / root_d
    bt = vecs.T @ (Q.T @ b if Q is not None else b)
    den = vals + shift
    ok = den > 1e-12 * max(float(np.abs(vals).max()), 1e-300)
    accel = vecs @ np.where(ok, -bt / np.where(ok, den, 1.0), 0.0)
    accel = (Q @ accel if Q is not None else accel) / root_d
    if np.linalg.norm(accel) <= _ACCEL_MAX * np.linalg.norm(step):
        y.ravel()[coords] += 0.5 * accel
    if stiff is not None:
        z = stiff.restore(y, x, step)
        y = z if z is not None else y
    y = _onto_clamps(problem, y, coords)
    length = float(np.linalg.norm(ps))
    if not np.all(np.isfinite(y)):
        return y, length, predicted, np.inf
    return y, length, predicted, spring_energy_change(y, x, *all_springs)


def _onto_clamps(problem: Problem, y: NDArray, coords: NDArray) -> NDArray:
    if not problem.exact:
        return y
    target = 1e-14 * float(np.max(problem.clamp_lengths))
    for _ in range(20):
        if np.max(np.abs(problem.clamp_violation(y))) <= target:
            break
        y = problem.toward_clamps(y, coords, problem.clamp_jacobian(y, coords, dense=True))
    return y


def trust_region_newton(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """Minimise ``problem`` from ``x`` (n_nodes, 2) by the trust-region method of the module."""
    net = problem.net
    frame = Frame(net, problem.free)
    coords = frame.coords
    n = coords.size
    m = problem.n_clamps if problem.exact else 0
    all_springs = problem.all_springs()
    stiff = StiffSprings.find(problem, coords, contrast=_CONTRAST)
    root_d = np.sqrt(_node_stiffness(problem)[coords])
    x = _onto_clamps(problem, np.array(x, dtype=np.float64), coords)
    if m and stop.clamp_error(problem.clamp_violation(x)) > 1e-6:
        return Outcome(
            x,
            0,
            False,
            "the clamp lengths cannot all be met (the projection onto them does not converge): "
            f"clamps on springs {problem.clamp_springs.tolist()} are incompatible, e.g. a "
            "triangle of clamped springs that violates the triangle inequality",
        )
    rigid = not problem.free_flat.size < problem.free.size  # nothing pinned
    radius = 0.25 * float(np.mean(net.rest_length)) * float(np.sqrt(np.median(root_d**2) * n))
    lowest = -np.inf  # smallest eigenvalue of the last reduced Hessian
    for it in range(stop.max_iter + 1):
        g = spring_gradient(x, *all_springs).ravel()[coords]
        if not np.all(np.isfinite(g)):
            return Outcome(x, it, False, "forces became non-finite (the network blew up)")
        if problem.n_clamps:
            A = problem.clamp_jacobian(x, coords, dense=True)
            mu = clamp_tensions(A, g, problem.scale[coords])
            force = g + A.T @ mu
        else:
            A, mu, force = None, np.empty(0), g
        residual = stop.imbalance(force, coords)
        if problem.clamp == "rod":
            clamp_error = stop.clamp_error(-mu / problem.rod_stiffness)
        else:
            clamp_error = stop.clamp_error(problem.clamp_violation(x) if m else np.empty(0))
        trace.record(residual, it)
        if stop.met(residual, clamp_error):
            return Outcome(x, it, True, certified=lowest > 1e-8)
        if it == stop.max_iter:
            return Outcome(x, it, False, f"no convergence in {stop.max_iter} iterations")
        if trace.elapsed() > stop.max_seconds:
            return Outcome(x, it, False, f"time budget of {stop.max_seconds:g} s exceeded")
        blocks = lagrangian_blocks(problem, x, mu[:m] if m else np.empty(0), 0.0)
        Ws = frame.pattern.assemble_dense(blocks) / root_d[:, None] / root_d[None, :]
        gs = g / root_d
        if m or rigid:
            rows = [A[:m]] if m else []
            if rigid:
                rows.append(rigid_motions(x, coords))
            Q = null_basis(np.vstack(rows) / root_d[None, :])
            H = Q.T @ Ws @ Q
            gr = Q.T @ gs
        else:
            Q, H, gr = None, Ws, gs
        H = 0.5 * (H + H.T)
        vals, vecs = np.linalg.eigh(H)
        lowest = float(vals[0]) if vals.size else np.inf
        gt = vecs.T @ gr
        accepted = False

        model = _Model(x, Q, H, vals, vecs, gr, gt, root_d, coords)

        accepted = False
        for _ in range(40):
            y, length, predicted, actual = _trial(problem, model, radius, stiff)
            if np.isfinite(actual):
                ratio = actual / predicted if predicted < 0 else -1.0
                if ratio > _ETA:
                    if ratio > 0.75 and length >= 0.99 * radius:
                        # the model holds to the boundary: look further along it at the
                        # same Hessian while the energy keeps falling
                        for _ in range(_GROW_TRIES):
                            wider = _trial(problem, model, 2 * radius, stiff)
                            y2, length2, predicted2, actual2 = wider
                            if not (actual2 < actual and actual2 / predicted2 > 0.25):
                                break
                            y, actual, radius, length = y2, actual2, 2 * radius, length2
                            if length < 0.99 * radius:
                                break
                        if length >= 0.99 * radius:
                            radius *= _GROW
                    elif ratio < 0.25:
                        radius = 0.25 * length
                    x, accepted = y, True
                    break
                # the energy change is at round-off: judge by the force instead
                flat = abs(actual) <= 1e-13 * abs(problem.energy(x)) + 1e-300
                if flat and abs(predicted) <= 1e-13 * abs(problem.energy(x)) + 1e-300:
                    if problem.residual(y).imbalance < residual:
                        x, accepted = y, True
                        break
            radius = 0.25 * min(radius, length)
            if radius <= 1e-15 * float(np.sqrt(np.sum(root_d**2))) * float(
                np.mean(net.rest_length)
            ):
                break
        if not accepted:
            return Outcome(x, it + 1, False, "trust region collapsed (no decrease possible)")
    return Outcome(x, stop.max_iter, False, "no convergence")
