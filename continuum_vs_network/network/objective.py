"""The objective the first-order methods minimise, their stop test and the clamp loop.

:class:`Objective` gives FIRE (:mod:`.fire`) and L-BFGS (:mod:`.lbfgs`) the energy, its
gradient and the stop test of :mod:`.stopping` (the net force on each free coordinate after
the clamp-normal components are removed, relative to its node's ``sum k L``; clamp errors
relative to the clamped spring's rest length), the same rule as Newton's.

Exact clamps (``problem.exact``) are handled by FIRE and L-BFGS with an augmented
Lagrangian outer loop: the inner method minimises, over the free coordinates,

    L(x) = E(x) + lam . (r - l) + rho / 2 |r - l|^2

and then the multipliers are updated, ``lam += rho (r - l)``. ``rho = 10 max(k)``: the clamp
is stiffer than any spring, so each outer step cuts the clamp error ~5-fold, while FIRE's
stable step shrinks only ~1.5-fold. ``lam`` starts at the least-squares clamp tension of
the starting point. Each inner solve stops at ``max |grad L| / f_i <= 1e-3 rho
max|r - l| / F`` (``f_i`` the local force scale, ``F = mean(k) mean(L)``: an inner gradient
error well below the coming multiplier change; looser inner solves let the clamp error
stall), tightened to half the tolerance once the clamp error is met. ``rho`` grows
4-fold only when tight inner solves still halve the clamp error no faster. With rods
(``problem.clamp == "rod"``) or no clamps the methods minimise
``problem.energy`` directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .constraints import Problem, clamp_tensions
from .energy import node_stiffness, spring_energy_change, spring_gradient
from .model import unit_vectors
from .stopping import Outcome, StopRule, Trace

__all__ = ["RECORD_EVERY", "InnerMethod", "InnerResult", "Objective", "minimise"]

_RHO_FACTOR = 10.0  # initial augmented-Lagrangian penalty, in units of max(k)
_RHO_GROWTH = 4.0
_RHO_MAX_FACTOR = 1e4
_MAX_OUTER = 60
_INNER_FRACTION = 1e-3
RECORD_EVERY = 10  # iterations between trace records


class Objective:
    """Energy (plus augmented-Lagrangian clamp terms in exact mode) and the stop test.

    Positions and gradients are flat (2 n_nodes,) vectors in the order ``x0, y0, x1, ...``
    (``x.ravel()`` of the (n_nodes, 2) positions). The spring vectors are one sparse matvec
    with the precomputed incidence matrix ``D`` (2 n_springs, 2 n_nodes): ``d = D x`` holds
    the x components of every ``x_b - x_a`` and then the y components; the gradient is
    ``D^T t`` with ``t`` the tension vectors, and lengths are ``sqrt(dx^2 + dy^2)`` (faster
    than ``np.take``, ``np.hypot`` and ``np.bincount``: ``docs/solver-notes.md#objective``).

    ``grad(x)`` takes full (n_nodes, 2) positions and returns the full flat gradient
    (pinned entries are not zeroed; callers read free coordinates). ``check(x, G)``
    returns the relative ``(imbalance, clamp_error)`` exactly as :meth:`Problem.residual`
    defines them, from any gradient ``G`` that differs from ``grad E`` by clamp-normal
    terms only (the projection removes them), at O(n) cost; :meth:`rest_imbalance` is its
    cheap part, the imbalance on the coordinates no clamp touches.
    """

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        n2 = 2 * problem.net.n_nodes
        self.scale = problem.scale  # (2 n_nodes,) local force scale of every coordinate
        self.free_flat = problem.free_flat
        self.clamp_scale = problem.net.rest_length[problem.clamp_springs]
        self.springs, self.k, self.L = problem.all_springs()
        n_s = self.k.size
        a, b = self.springs[:, 0], self.springs[:, 1]
        rows = np.tile(np.arange(2 * n_s), 2)
        cols = np.concatenate([2 * b, 2 * b + 1, 2 * a, 2 * a + 1])
        vals = np.repeat([1.0, -1.0], 2 * n_s)
        self._D = sp.csr_matrix((vals, (rows, cols)), shape=(2 * n_s, n2))
        self._DT = self._D.T.tocsr()
        self.augmented = problem.exact
        m = problem.n_clamps
        self.lam = np.zeros(m)
        self.rho = 0.0
        self.ends = problem.net.springs[problem.clamp_springs]  # (m, 2)
        # coordinates touched by clamps, restricted to free ones, for the projection
        coords = np.stack([2 * self.ends, 2 * self.ends + 1], axis=2).reshape(m, 4)
        free = np.zeros(n2, dtype=bool)
        free[self.free_flat] = True
        self.fixed = np.flatnonzero(~free)
        self.touched = np.unique(coords[free[coords]]) if m else np.empty(0, np.int64)
        other = free.copy()
        other[self.touched] = False
        # 1 / scale on the coordinates no clamp touches, 0 elsewhere (pinned, touched)
        self._other_weight = np.where(other, 1.0 / self.scale, 0.0)
        self._free_weight = np.where(free, 1.0 / self.scale, 0.0)
        self._work = np.empty(n2)
        # where each clamp's four coordinates (ax, ay, bx, by) sit among the touched ones
        pos = np.searchsorted(self.touched, coords)
        hit = (
            self.touched[np.minimum(pos, max(self.touched.size - 1, 0))] == coords
            if self.touched.size
            else np.zeros(coords.shape, dtype=bool)
        )
        self._jac_rows = np.broadcast_to(np.arange(m)[:, None], (m, 4))[hit]
        self._jac_cols = pos[hit]
        self._jac_hit = hit

    # geometry of the clamped springs
    def _clamp_geometry(self, x: NDArray) -> tuple[NDArray, NDArray]:
        return unit_vectors(x, self.ends)

    def violation(self, x: NDArray) -> NDArray:
        if not self.ends.size:
            return np.empty(0)
        _, r = self._clamp_geometry(x)
        return r - self.problem.clamp_lengths

    def _add_clamp_terms(self, x: NDArray, G: NDArray) -> None:
        """Add ``A^T (lam + rho c)``, the gradient of ``lam.c + rho/2 |c|^2``, to flat ``G``."""
        u, r = self._clamp_geometry(x)
        c = r - self.problem.clamp_lengths
        t = (self.lam + self.rho * c)[:, None] * u
        nodes = G.reshape(-1, 2)  # a view: adding to it adds to G
        np.add.at(nodes, self.ends[:, 1], t)
        np.add.at(nodes, self.ends[:, 0], -t)

    def _spring_vectors(self, x: NDArray) -> tuple[NDArray, NDArray]:
        """Spring vectors ``d`` (2, n_springs) (x row, y row) and lengths ``r`` at ``x``."""
        d = (self._D @ x.ravel()).reshape(2, -1)
        r = d[0] * d[0]
        r += d[1] * d[1]
        return d, np.sqrt(r, out=r)

    def _spring_gradient(self, d: NDArray, r: NDArray) -> NDArray:
        """Flat gradient ``D^T t`` from spring vectors ``d`` and lengths ``r`` (kept)."""
        w = r - self.L  # not k - k L / r: that cancels near r = L (rods: k = 1e10)
        w *= self.k
        w /= np.maximum(r, 1e-300)
        return self._DT @ (d * w).ravel()

    def grad(self, x: NDArray) -> NDArray:
        G = self._spring_gradient(*self._spring_vectors(x))
        if self.augmented:
            self._add_clamp_terms(x, G)
        return G

    def reference(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """``(x_ref, d_ref, r_ref)``: a copy of ``x`` and its spring vectors and lengths."""
        x = x.copy()
        return (x, *self._spring_vectors(x))

    def change_and_grad(self, x: NDArray, ref: tuple) -> tuple[float, NDArray]:
        """The objective at ``x`` minus its value at ``ref``, and its full flat gradient.

        Energy differences near a minimum are ~ residual^2 / k; computed as
        ``E(x) - E(x_ref)`` they drown in ``eps E`` below a residual ~ sqrt(eps E k)
        (~1e-9 F on small lattices), which stalls line searches before 1e-10. The change
        is computed as in :func:`~.numerics.spring_energy_change`, fused with the
        gradient so that the spring vectors are computed once.
        """
        x_ref, d0, r0 = ref
        d, r = self._spring_vectors(x)
        du = (self._D @ (x - x_ref).ravel()).reshape(2, -1)
        dr = np.einsum("ij,ij->j", du, d + d0) / np.maximum(r + r0, 1e-300)
        change = float(0.5 * np.dot(self.k, dr * (r + r0 - 2.0 * self.L)))
        G = self._spring_gradient(d, r)
        if self.augmented:
            # lam c + rho/2 c^2 is a spring of stiffness rho and rest length l - lam/rho,
            # up to a constant
            rest = self.problem.clamp_lengths - self.lam / self.rho
            change += spring_energy_change(x, x_ref, self.ends, np.full(rest.size, self.rho), rest)
            self._add_clamp_terms(x, G)
        return change, G

    def rest_imbalance(self, G: NDArray) -> float:
        """``max |G| / scale`` over the free coordinates no clamp touches (0 if none).

        A lower bound on the imbalance of :meth:`check`: the stop rule cannot be met while
        it exceeds the tolerance. Non-finite when ``G`` is.
        """
        work = np.abs(G.ravel(), out=self._work)
        work *= self._other_weight
        return float(work.max()) if work.size else 0.0

    def check(self, x: NDArray, G: NDArray, rest: float | None = None) -> tuple[float, float]:
        """Relative ``(imbalance, clamp_error)`` of ``x`` given its gradient ``G``.

        ``rest``: :meth:`rest_imbalance` of ``G`` when already computed.
        """
        g = G.ravel()
        if rest is None:
            rest = self.rest_imbalance(g)
        if not self.ends.size:
            return rest, 0.0
        u, r = self._clamp_geometry(x)
        near = 0.0
        mu = np.zeros(self.ends.shape[0])
        if self.touched.size:
            # dense clamp Jacobian on the touched free coordinates: rows [-u, +u]
            A = np.zeros((self.ends.shape[0], self.touched.size))
            vals = np.concatenate([-u, u], axis=1)  # (m, 4), order ax, ay, bx, by
            np.add.at(A, (self._jac_rows, self._jac_cols), vals[self._jac_hit])
            gs = g[self.touched]
            mu = clamp_tensions(A, gs, self.scale[self.touched])
            near = float(np.max(np.abs(gs + A.T @ mu) / self.scale[self.touched]))
        viol = r - self.problem.clamp_lengths
        if self.problem.clamp == "rod":
            # Problem.clamp_balance; G holds the rods' forces, so mu is the total tension
            viol = -mu / self.problem.rod_stiffness
        clamp_error = float(np.max(np.abs(viol) / self.clamp_scale))
        return max(rest, near), clamp_error

    def inner_met(self, g: NDArray, tol: float, rest: float | None = None) -> bool:
        """The augmented inner problem's test: ``max |g| / f_i <= tol`` on free coordinates.

        ``g`` the full flat gradient; ``rest`` its :meth:`rest_imbalance` when known (then
        only the clamp-touched coordinates are read again).
        """
        if tol <= 0:
            return False
        g = g.ravel()
        if rest is None:
            work = np.abs(g, out=self._work)
            work *= self._free_weight
            return float(work.max()) <= tol
        if rest > tol:
            return False
        t = self.touched
        return not t.size or float(np.max(np.abs(g[t]) / self.scale[t])) <= tol

    def multipliers(self, x: NDArray, G: NDArray) -> NDArray:
        """Least-squares clamp tensions ``mu`` at ``x`` (the sign convention of ``lam``)."""
        A = self.problem.clamp_jacobian(x)
        g = G.ravel()[self.free_flat]
        return -np.linalg.lstsq((A @ A.T).toarray(), A @ g, rcond=None)[0]

    def hessian_bound(self, x: NDArray) -> float:
        """Gershgorin bound on the largest eigenvalue of the objective's Hessian.

        :func:`~.numerics.hessian_norm_bound`; augmented clamps add ``rho + |lam| / r``
        to the stiffness of their spring.
        """
        node = node_stiffness(x, self.springs, self.k, self.L)
        if self.augmented:
            _, rc = self._clamp_geometry(x)
            wc = self.rho + np.abs(self.lam) / np.maximum(rc, 1e-300)
            n = x.shape[0]
            node += np.bincount(self.ends[:, 0], wc, n) + np.bincount(self.ends[:, 1], wc, n)
        return float(2.0 * np.max(node)) if node.size else 0.0


@dataclass
class InnerResult:
    """What an inner minimisation returns to the outer loop."""

    x: NDArray
    iterations: int
    status: str  # "stop" (rule met), "tol" (inner tol met), "budget", "stalled", "failed"
    message: str = ""


InnerMethod = Callable[[Objective, NDArray, float, StopRule, Trace, int], InnerResult]


def minimise(
    problem: Problem, x: NDArray, stop: StopRule, trace: Trace, inner: InnerMethod
) -> Outcome:
    """Run ``inner`` directly, or inside the augmented-Lagrangian loop for exact clamps."""
    obj = Objective(problem)
    x = problem.start(x)  # the clamped springs set to their lengths (a copy)
    if not obj.augmented:
        res = inner(obj, x, 0.0, stop, trace, stop.max_iter)
        stalled = res.status == "stalled"
        return Outcome(res.x, res.iterations, res.status == "stop", res.message, stalled=stalled)

    kmax = float(np.max(problem.net.stiffness)) if problem.net.n_springs else 1.0
    kmax = kmax if kmax > 0 else 1.0
    obj.rho = _RHO_FACTOR * kmax
    obj.lam = obj.multipliers(x, spring_gradient(x, obj.springs, obj.k, obj.L))
    force_scale = problem.net.force_scale
    inner_tol = max(0.5 * stop.tol, 1e-3)
    iterations = 0
    base = trace.base
    c_prev = np.inf
    for _ in range(_MAX_OUTER):
        trace.base = base + iterations
        res = inner(obj, x, inner_tol, stop, trace, stop.max_iter - iterations)
        x, iterations = res.x, iterations + res.iterations
        if res.status == "stop":
            return Outcome(x, iterations, True)
        if res.status in ("budget", "stalled", "failed"):
            stalled = res.status == "stalled"
            return Outcome(x, iterations, False, res.message, stalled=stalled)
        c = obj.violation(x)
        c_err = float(np.max(np.abs(c)))
        obj.lam = obj.lam + obj.rho * c
        tight = inner_tol <= 0.5 * stop.tol
        if tight and c_err > 0.5 * c_prev and obj.rho < _RHO_MAX_FACTOR * kmax:
            obj.rho *= _RHO_GROWTH  # exact inner solves and still slow: stiffen the clamp
        c_prev = c_err
        # the inner gradient error must be well below the coming multiplier change rho c
        inner_tol = max(
            0.5 * stop.tol, min(inner_tol, _INNER_FRACTION * obj.rho * c_err / force_scale)
        )
        if stop.clamp_error(c) <= stop.tol:
            inner_tol = 0.5 * stop.tol
    message = f"augmented Lagrangian: no convergence in {_MAX_OUTER} outer steps"
    return Outcome(x, iterations, False, message)
