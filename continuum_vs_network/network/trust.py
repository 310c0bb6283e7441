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
   shift, following negative curvature (the "hard case" adds the lowest eigenvector);
4. moves back onto the clamp lengths (Gauss-Newton projection) and puts stiff springs back
   to the lengths the linear model predicted (:class:`StiffSprings`);
5. accepts the step when the energy falls by a fair share of the model's prediction
   (computed without cancellation), and grows or shrinks the radius by the ratio.

Near the solution the radius no longer binds and the iteration is Newton's, quadratically
convergent. Saddles cannot be returned: a step along a negative eigenvector always lowers
the model.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .constraints import Problem, clamp_tensions
from .energy import spring_energy_change, spring_gradient
from .lagrangian import Frame, lagrangian_blocks
from .stopping import Outcome, StopRule, Trace

__all__ = ["TR_DENSE_MAX", "StiffSprings", "trust_region_newton"]

TR_DENSE_MAX = 400  # free coordinates; above, the sparse shifted Newton of newton.py (faster there)
_ETA = 1e-4  # acceptance threshold on actual / predicted decrease
_GROW = 2.0  # radius growth after a good step that reached the boundary (4 and 8: no better)


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
    def find(cls, problem: Problem, coords: NDArray) -> StiffSprings | None:
        springs, k, _ = problem.all_springs()
        positive = k[k > 0]
        if not positive.size:
            return None
        stiff = np.flatnonzero(k > cls.CONTRAST * float(np.median(positive)))
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


def _subproblem(vals: NDArray, vecs: NDArray, gt: NDArray, radius: float) -> NDArray:
    """Exact solution of ``min g.p + p.H.p / 2, |p| <= radius`` from ``H = V diag(vals) V^T``
    (``gt = V^T g``), in the eigenbasis coordinates' original frame."""

    def step(shift: float) -> NDArray:
        return -(gt / (vals + shift))

    lowest = float(vals[0])
    if lowest > 0:
        p = step(0.0)
        if np.linalg.norm(p) <= radius:
            return vecs @ p
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
            return vecs @ p
    # safeguarded Newton on the secular equation 1/|p(shift)| = 1/radius (More-Sorensen),
    # bracketed by bisection
    g2 = gt * gt
    lo, hi = low, low + np.linalg.norm(gt) / radius + abs(float(vals[-1])) + tiny
    shift = hi
    for _ in range(60):
        den = vals + shift
        norm2 = float(np.sum(g2 / den**2))
        norm = np.sqrt(norm2)
        if abs(norm - radius) <= 1e-6 * radius:
            break
        if norm > radius:
            lo = shift
        else:
            hi = shift
        derivative = -float(np.sum(g2 / den**3)) / norm  # d|p| / d shift
        trial = shift - (1.0 / radius - 1.0 / norm) / (-derivative / norm2)
        shift = trial if lo < trial < hi else 0.5 * (lo + hi)
    return vecs @ step(shift)


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
    stiff = StiffSprings.find(problem, coords)
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
        if m:
            As = A[:m] / root_d[None, :]
            Q = np.linalg.svd(As)[2][m:].T
            H = Q.T @ Ws @ Q
            gr = Q.T @ gs
        else:
            Q, H, gr = None, Ws, gs
        H = 0.5 * (H + H.T)
        vals, vecs = np.linalg.eigh(H)
        lowest = float(vals[0]) if vals.size else np.inf
        gt = vecs.T @ gr
        accepted = False
        for _ in range(40):
            ps = _subproblem(vals, vecs, gt, radius)
            predicted = float(gr @ ps + 0.5 * ps @ H @ ps)
            step = (Q @ ps if Q is not None else ps) / root_d
            y = x.copy()
            y.ravel()[coords] += step
            if stiff is not None:
                z = stiff.restore(y, x, step)
                y = z if z is not None else y
            y = _onto_clamps(problem, y, coords)
            if np.all(np.isfinite(y)):
                actual = spring_energy_change(y, x, *all_springs)
                ratio = actual / predicted if predicted < 0 else -1.0
                length = float(np.linalg.norm(ps))
                if ratio > _ETA:
                    if ratio > 0.75 and length >= 0.99 * radius:
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
            else:
                length = float(np.linalg.norm(ps))
            radius = 0.25 * min(radius, length)
            if radius <= 1e-15 * float(np.sqrt(np.sum(root_d**2))) * float(
                np.mean(net.rest_length)
            ):
                break
        if not accepted:
            return Outcome(x, it + 1, False, "trust region collapsed (no decrease possible)")
    return Outcome(x, stop.max_iter, False, "no convergence")
