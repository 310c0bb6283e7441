"""First-order equilibrium methods: FIRE, L-BFGS and the seed paper's Adagrad.

Each method has the signature of :data:`~.equilibrium.METHODS`:
``f(problem, x, stop, trace) -> Outcome`` and is judged by the same local stop rule as
Newton (:mod:`.stopping`: the net force on each free coordinate after the clamp-normal
components are removed, relative to its node's ``sum k L``; clamp errors relative to the
clamped spring's rest length).

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

``paper_adagrad`` is the seed paper's method (PyTorch Adagrad, learning rate 0.1, rod
clamps of stiffness 1e10) kept as a baseline; it is not tuned. It typically stalls far from
equilibrium because the rods make the problem extremely ill-conditioned.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .constraints import Problem, clamp_tensions
from .energy import node_stiffness, spring_energy_change, spring_gradient
from .stopping import Outcome, StopRule, Trace

__all__ = ["fire", "lbfgs", "paper_adagrad"]

# FIRE parameters of Bitzek et al., PRL 97, 170201 (2006)
_N_MIN = 5
_F_INC = 1.1
_F_DEC = 0.5
_ALPHA_START = 0.1
_F_ALPHA = 0.99

_RHO_FACTOR = 10.0  # initial augmented-Lagrangian penalty, in units of max(k)
_RHO_GROWTH = 4.0
_RHO_MAX_FACTOR = 1e4
_MAX_OUTER = 60
_INNER_FRACTION = 1e-3
_DT_FACTOR = 1.4  # dt_max = _DT_FACTOR / sqrt(Gershgorin bound); see _fire_dt_max
_RECORD_EVERY = 10
_PAPER_LR = 0.1


# -- the shared objective: energy, augmented clamp terms, residual --------------------------
class _Objective:
    """Energy (plus augmented-Lagrangian clamp terms in exact mode) and the stop test.

    Positions and gradients are flat (2 n_nodes,) vectors in the order ``x0, y0, x1, ...``
    (``x.ravel()`` of the (n_nodes, 2) positions). The spring vectors are one sparse matvec
    with the precomputed incidence matrix ``D`` (2 n_springs, 2 n_nodes): ``d = D x`` holds
    the x components of every ``x_b - x_a`` and then the y components; the gradient is
    ``D^T t`` with ``t`` the tension vectors. Both products are ~2x faster than gathers
    with ``np.take`` and scatters with ``np.bincount`` and need no temporaries.

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
        d = x[self.ends[:, 1]] - x[self.ends[:, 0]]
        r = np.hypot(d[:, 0], d[:, 1])
        return d / np.maximum(r, 1e-300)[:, None], r

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
        w = r - self.L
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
class _Inner:
    """What an inner minimisation returns to the outer loop."""

    x: NDArray
    iterations: int
    status: str  # "stop" (stop rule met), "tol" (inner tolerance met), "budget", "failed"
    message: str = ""


Inner = Callable[[_Objective, NDArray, float, StopRule, Trace, int], _Inner]


def _minimise(problem: Problem, x: NDArray, stop: StopRule, trace: Trace, inner: Inner) -> Outcome:
    """Run ``inner`` directly, or inside the augmented-Lagrangian loop for exact clamps."""
    obj = _Objective(problem)
    x = np.array(x, dtype=np.float64)
    if not obj.augmented:
        res = inner(obj, x, 0.0, stop, trace, stop.max_iter)
        return Outcome(res.x, res.iterations, res.status == "stop", res.message)

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
        if res.status in ("budget", "failed"):
            return Outcome(x, iterations, False, res.message)
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


# -- FIRE -----------------------------------------------------------------------------------
def _fire_dt_max(obj: _Objective, x: NDArray) -> float:
    """FIRE's largest time step at ``x``: ``1.4 / sqrt(bound)`` (unit masses).

    The explicit (semi-implicit Euler) step is stable for ``dt < 2 / sqrt(lambda_max)``, and
    ``lambda_max`` is at most the Gershgorin ``bound`` of :meth:`_Objective.hessian_bound`
    (``2 max_nodes sum_incident k`` for springs near their rest lengths, with augmented
    clamps adding ``rho`` to their spring). At ``2 / sqrt(bound)`` itself a stiff, localised
    mode (a clamp penalty, a rod), for which the bound is nearly tight, sits at the edge of
    stability: its undamped period-2 oscillation dominates the power ``F.V`` and FIRE resets
    every ~10 steps (a 32x32 lattice with one clamp did not converge in 20000 iterations).
    With the factor 1.4 (about sqrt 2) it converges in ~4000; 1.0 costs ~25% more, 1.7 ~5%
    less. Rods of stiffness 1e10 enter the bound and make FIRE's steps tiny.
    """
    return _DT_FACTOR / np.sqrt(max(obj.hessian_bound(x), 1e-300))


@dataclass
class _FireStats:
    """Diagnostics of one FIRE run: velocity resets (``P = F.V <= 0``) and where the first was."""

    resets: int = 0
    first_reset_x: NDArray | None = None


def _fire_inner(
    obj: _Objective,
    x: NDArray,
    tol: float,
    stop: StopRule,
    trace: Trace,
    budget: int,
    stats: _FireStats | None = None,
) -> _Inner:
    """FIRE (Bitzek et al. 2006) with semi-implicit Euler steps and unit masses.

    Stops when the stop rule is met (``status="stop"``) or, for the augmented inner
    problem, when ``max |grad L| <= tol`` on free coordinates (``status="tol"``).

    The state is kept on all 2 n_nodes coordinates with the gradient zeroed on the pinned
    ones, so pinned velocities stay 0 and pinned positions never move: no gathers or
    scatters between free and full vectors. Each iteration reads the cheap part of the stop
    test (:meth:`_Objective.rest_imbalance`, the imbalance on coordinates no clamp touches);
    the full test (the clamp projection and the clamp errors) runs only when that part is
    within the tolerance, or when the trace records. The stopping decision is the same as
    running the full test every iteration.
    """
    x = x.copy()
    flat = x.ravel()  # view: moving flat moves x
    fixed = obj.fixed
    v = np.zeros_like(flat)
    step = np.empty_like(flat)
    dt_max = _fire_dt_max(obj, x)
    dt = 0.1 * dt_max
    alpha = _ALPHA_START
    n_pos = 0
    moving = False
    residual = np.inf
    threshold = max(stop.tol, tol)
    for it in range(budget + 1):
        G = obj.grad(x)
        G[fixed] = 0.0
        rest = obj.rest_imbalance(G)
        record = it % _RECORD_EVERY == 0
        if not np.isfinite(rest):
            trace.record(rest, it)
            return _Inner(x, it, "failed", "FIRE: forces became non-finite")
        if rest <= threshold or record:
            residual, clamp_error = obj.check(x, G, rest)
            if stop.met(residual, clamp_error):
                trace.record(residual, it)
                return _Inner(x, it, "stop")
            if obj.inner_met(G, tol, rest):
                trace.record(residual, it)
                return _Inner(x, it, "tol")
            if record:
                trace.record(residual, it)
        if it == budget:
            break
        if trace.elapsed() > stop.max_seconds:
            residual = obj.check(x, G, rest)[0]
            trace.record(residual, it)
            return _Inner(x, it, "budget", f"FIRE: time budget of {stop.max_seconds:g} s exceeded")

        # F = -G: power P = F.V, mixing V <- (1 - alpha) V + alpha |V| F / |F|
        P = -float(G @ v)
        if P > 0.0:
            mix = alpha * float(np.sqrt(v @ v)) / float(np.sqrt(G @ G))
            v *= 1.0 - alpha
            v -= mix * G
            if n_pos > _N_MIN:
                dt = min(dt * _F_INC, dt_max)
                alpha *= _F_ALPHA
            n_pos += 1
        elif moving:  # uphill (or stopped): freeze, shrink the step, restart the mixing
            if stats is not None:
                stats.resets += 1
                if stats.first_reset_x is None:
                    stats.first_reset_x = x.copy()
            n_pos = 0
            dt *= _F_DEC
            alpha = _ALPHA_START
            v[:] = 0.0
        v -= np.multiply(G, dt, out=step)
        flat += np.multiply(v, dt, out=step)
        moving = True
    residual = obj.check(x, G)[0]
    trace.record(residual, budget)
    return _Inner(x, budget, "budget", f"FIRE: no convergence in {stop.max_iter} iterations")


def fire(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """FIRE minimisation of ``problem`` from ``x`` (n_nodes, 2).

    Standard parameters (Bitzek et al. 2006): ``dt_start = 0.1 dt_max``, ``N_min = 5``,
    ``f_inc = 1.1``, ``f_dec = 0.5``, ``alpha_start = 0.1``, ``f_alpha = 0.99``, power
    ``P = F . V``, unit masses; ``dt_max = 1.4 / sqrt(bound)`` from the Gershgorin bound on
    the Hessian's largest eigenvalue (``2 max_nodes sum_incident k``; see ``_fire_dt_max``).
    Exact clamps by the augmented Lagrangian of the module docstring.
    """
    return _minimise(problem, x, stop, trace, _fire_inner)


# -- L-BFGS ---------------------------------------------------------------------------------
def _one_blas_thread():
    """Pin BLAS to one thread (multithreaded OpenBLAS slows L-BFGS-B's tiny products)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


class _StopNow(Exception):
    pass


def _lbfgs_inner(
    obj: _Objective, x: NDArray, tol: float, stop: StopRule, trace: Trace, budget: int
) -> _Inner:
    """scipy's L-BFGS-B on the free coordinates, restarted when its line search stalls."""
    from scipy.optimize import minimize

    free = obj.free_flat
    x = x.copy()
    flat = x.ravel()
    cache: dict = {}
    done = {"iterations": 0, "status": "", "message": ""}

    def fun(y: NDArray) -> tuple[float, NDArray]:
        flat[free] = y
        e, G = obj.change_and_grad(x, ref)
        cache["y"], cache["G"] = y.copy(), G
        return e, G.ravel()[free]

    def test(y: NDArray, step: bool) -> None:
        if "y" not in cache or not np.array_equal(cache["y"], y):
            fun(y)
        flat[free] = y
        residual, clamp_error = obj.check(x, cache["G"])
        done["iterations"] += int(step)
        it = done["iterations"]
        final = False
        if not np.isfinite(residual):
            done.update(status="failed", message="L-BFGS: forces became non-finite")
            final = True
        elif stop.met(residual, clamp_error):
            done["status"] = "stop"
            final = True
        elif obj.inner_met(cache["G"], tol):
            done["status"] = "tol"
            final = True
        elif trace.elapsed() > stop.max_seconds:
            message = f"L-BFGS: time budget of {stop.max_seconds:g} s exceeded"
            done.update(status="budget", message=message)
            final = True
        elif it >= budget:
            message = f"L-BFGS: no convergence in {stop.max_iter} iterations"
            done.update(status="budget", message=message)
            final = True
        if final or not step or it % _RECORD_EVERY == 0:
            trace.record(residual, it)
        if final:
            raise _StopNow

    def callback(intermediate_result) -> None:
        test(np.asarray(intermediate_result.x), True)

    y = flat[free].copy()
    ref = obj.reference(x)
    stalls = 0
    with _one_blas_thread():
        try:
            test(y, False)  # the starting point may already satisfy the stop rule
            while True:
                start_iterations = done["iterations"]
                flat[free] = y
                ref = obj.reference(x)  # energies are measured from the restart point
                res = minimize(
                    fun,
                    y,
                    jac=True,
                    method="L-BFGS-B",
                    callback=callback,
                    options={
                        "maxiter": max(budget - done["iterations"], 1),
                        "maxcor": 10,
                        "gtol": 0.0,
                        "ftol": 0.0,
                        "maxfun": 20 * budget + 100,
                    },
                )
                y = np.asarray(res.x)
                # scipy stopped by itself (line search at round-off): restart with fresh memory
                test(y, False)
                stalls = stalls + 1 if done["iterations"] - start_iterations <= 2 else 0
                if stalls >= 3:
                    done.update(status="failed", message=f"L-BFGS: stalled ({res.message})")
                    raise _StopNow
        except _StopNow:
            pass
    return _Inner(x, done["iterations"], done["status"], done["message"])


def lbfgs(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """L-BFGS-B (scipy, memory 10) on the free coordinates of ``problem`` from ``x``.

    ``gtol`` and ``ftol`` are zero so that scipy never stops before the stop rule; our own
    test runs in the callback after every iteration. When scipy's line search stalls at
    round-off the method restarts with fresh memory, and reports failure after three
    restarts without progress. BLAS is pinned to one thread when ``threadpoolctl`` is
    installed. Exact clamps by the augmented Lagrangian of the module docstring.
    """
    return _minimise(problem, x, stop, trace, _lbfgs_inner)


# -- the seed paper's method ----------------------------------------------------------------
def paper_adagrad(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """The seed paper's equilibrium method: PyTorch Adagrad, learning rate 0.1, float64.

    Minimises the total energy with rod clamps (``problem.clamp == "rod"``; ``relax`` forces
    it for ``method="paper"``) over the free coordinates, one Adagrad step per iteration,
    until the stop rule, ``stop.max_iter`` or ``stop.max_seconds``. Kept untuned as a
    baseline: it stalls far from equilibrium on stiff (rod) problems.
    """
    import torch

    if problem.exact:
        raise ValueError("paper_adagrad needs rod clamps (problem.clamp == 'rod')")
    obj = _Objective(problem)
    free = obj.free_flat
    x = np.array(x, dtype=np.float64)
    springs = torch.as_tensor(obj.springs, dtype=torch.int64)
    a, b = springs[:, 0], springs[:, 1]
    k = torch.as_tensor(obj.k, dtype=torch.float64)
    L = torch.as_tensor(obj.L, dtype=torch.float64)
    base = torch.as_tensor(x.ravel().copy(), dtype=torch.float64)
    free_t = torch.as_tensor(free, dtype=torch.int64)
    p = torch.nn.Parameter(base[free_t].clone())
    opt = torch.optim.Adagrad([p], lr=_PAPER_LR)
    G = np.zeros_like(x)
    residual = np.inf
    for it in range(stop.max_iter + 1):
        opt.zero_grad()
        pos = base.index_put((free_t,), p).view(-1, 2)
        d = pos[b] - pos[a]
        r = torch.sqrt((d * d).sum(dim=1))
        energy = 0.5 * (k * (r - L) ** 2).sum()
        energy.backward()
        x.ravel()[free] = p.detach().numpy()
        G.ravel()[free] = p.grad.detach().numpy()
        residual, clamp_error = obj.check(x, G)
        final = True
        if not np.isfinite(residual):
            message, converged = "paper: forces became non-finite", False
        elif stop.met(residual, clamp_error):
            message, converged = "", True
        elif it == stop.max_iter:
            message = f"paper (Adagrad): no convergence in {stop.max_iter} iterations"
            converged = False
        elif trace.elapsed() > stop.max_seconds:
            message = f"paper (Adagrad): time budget of {stop.max_seconds:g} s exceeded"
            converged = False
        else:
            final = False
        if final or it % _RECORD_EVERY == 0:
            trace.record(residual, it)
        if final:
            return Outcome(x, it, converged, message)
        opt.step()
    return Outcome(x, stop.max_iter, False, "paper (Adagrad): no convergence")
