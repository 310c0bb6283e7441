"""The chord (modified Newton) SQP iteration of :class:`~.states.Tracker`'s fast path.

It solves the equilibrium equations::

    F1 = grad E(x) + A(x)^T mu(x) = 0      (net force, mu = least-squares clamp tensions)
    F2 = r_c(x) - l_c              = 0      (clamp lengths)

with a factorisation of the augmented Lagrangian Hessian ``W = H_E + sum mu_c d2r_c +
rho A^T A`` taken at an earlier *linearisation point* and the clamp directions
``Z_c = W^{-1} a_c`` cached per clamped spring (:class:`Linearisation`; an approximate
``W^-1`` serves: ``rough``, float32 where accurate: :func:`~..linalg.spd.factor_spd`; one
alive per key). One iteration costs one pair of triangular solves. Because learning changes
the network little per step, the same factorisation serves the free state, the nudged state
(its extra target clamps need one cached column each: the Schur-complement reuse) and many
following learning steps; it is refreshed when the iteration contracts slowly (ratio >
``refactor_ratio``), at most :data:`MAX_REFACTORS` times a solve. The iteration is
accelerated by Anderson mixing (GMRES-like on its linear error). Convergence is judged by
``relax``'s own local stop rule (:mod:`~continuum_vs_network.network.stopping`), so reuse
changes the cost, never the tolerance. The Lagrangian Hessian and the row order are the
engine's (:mod:`~continuum_vs_network.network.lagrangian`); this module keeps only what is
reused.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from ..linalg.kkt import schur_solve
from ..network.constraints import Problem, clamp_tensions
from ..network.equilibrium import Equilibrium
from ..network.lagrangian import Frame, lagrangian_hessian
from ..network.model import SpringNetwork

__all__ = ["MAX_REFACTORS", "Linearisation", "chord_solve"]

MAX_REFACTORS = 3  # per chord solve; then relax (with its line search) takes over


class Linearisation:
    """A factorised ``W`` at one point, cached columns ``W^{-1} a_c`` and Schur matrices."""

    def __init__(self, factor, x: NDArray, frame: Frame) -> None:
        self.factor = factor
        self.x = x.copy()
        self.frame = frame
        self.columns: dict[int, tuple[NDArray, NDArray]] = {}  # spring -> (a_c, W^-1 a_c)
        self.sets: dict[tuple[int, ...], tuple[NDArray, NDArray, NDArray]] = {}
        self.uses = 0

    def rows_and_columns(
        self, net: SpringNetwork, springs: NDArray
    ) -> tuple[NDArray, NDArray, NDArray]:
        """``(A, Z, S)`` for a clamp set: rows ``a_c`` at the linearisation point (m, n),
        ``Z = W^{-1} A^T`` (n, m) and the Schur complement ``S = A Z`` (m, m)."""
        key = tuple(int(s) for s in springs)
        if key in self.sets:
            return self.sets[key]
        n = self.frame.n
        missing = [s for s in key if s not in self.columns]
        if missing:
            A = self.frame.rows(net, self.x, np.array(missing), dense=True)
            Z = np.asarray(self.factor.solve(A.T.copy())).reshape(n, len(missing))
            for j, s in enumerate(missing):
                self.columns[s] = (A[j], Z[:, j].copy())
        A = np.array([self.columns[s][0] for s in key]).reshape(len(key), n)
        Z = np.array([self.columns[s][1] for s in key]).reshape(len(key), n).T
        self.sets[key] = (A, Z, A @ Z)
        return self.sets[key]


def chord_solve(
    net: SpringNetwork,
    pinned: NDArray,
    clamped: dict[int, float],
    x: NDArray,
    *,
    solver,
    cache: dict[str, Linearisation],
    key: str,
    stats,
    load: NDArray | None = None,
) -> Equilibrium | None:
    """Chord SQP from ``x`` (``grad E - load = 0``); None when it fails (the caller then
    relaxes). ``solver``: a :class:`~.states.Solver`; ``cache[key]``: the linearisation it
    starts from and refreshes; ``stats``: the :class:`~.states.TrackerStats` it counts
    iterations and factorisations in."""
    s = solver
    problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
    lin = cache.get(key)
    if lin is not None and lin.frame.n != int(problem.free_flat.size):
        lin = None
    frame = (
        lin.frame
        if lin is not None
        else Frame(net, problem.free, sparse_solver=problem.sparse_solver)
    )
    clamps = problem.clamp_springs
    stop = problem.stop_rule(s.tol, max_iter=30, max_seconds=s.max_seconds)
    trace_r: list[float] = []
    trace_t: list[float] = []
    t0 = time.perf_counter()
    refactors = 0  # factorisations made by this call
    x = x.copy()
    previous = np.inf
    minus_load = None if load is None else -frame.take(load)
    xs: list[NDArray] = []  # Anderson memory: free coordinates and chord steps
    fs: list[NDArray] = []
    for it in range(30):
        if not np.all(np.isfinite(x)):
            return None
        g, r = frame.gradient_and_lengths(net, x)
        if minus_load is not None:
            g = g + minus_load
        if clamps.size:
            A = frame.rows(net, x, clamps)  # dense while small (200 MB at 1e6)
            viol = r[clamps] - problem.clamp_lengths
            mu = clamp_tensions(A, g, stop.scale[frame.coords])
            force = g + A.T @ mu
        else:
            viol, mu, force = np.empty(0), np.empty(0), g
        relative = stop.imbalance(force, frame.coords)
        clamp_relative = stop.clamp_error(viol)
        trace_r.append(relative)
        trace_t.append(time.perf_counter() - t0)
        if stop.met(relative, clamp_relative):
            stats.iterations += it
            residual = float(np.max(np.abs(force))) if force.size else 0.0
            clamp_error = float(np.max(np.abs(viol))) if viol.size else 0.0
            return _equilibrium(
                net, x, r, (residual, relative, clamp_error), mu, it, t0, trace_r, trace_t
            )
        measure = max(relative, clamp_relative) / s.tol
        if not np.isfinite(measure):
            return None
        if lin is None or measure > s.refactor_ratio * previous:
            if refactors >= MAX_REFACTORS:
                if measure >= previous:
                    return None  # Newton steps do not contract here: relax instead
            else:
                lin = None  # the caller's reference too: one factorisation alive
                lin = _linearise(problem, frame, x, mu, cache, key, stats)
                refactors += 1
                xs.clear()
                fs.clear()
                if lin is None:
                    return None
        if measure >= previous:
            xs.clear()
            fs.clear()
        previous = measure
        z = lin.factor.solve(force)
        if clamps.size:
            At, Z, S = lin.rows_and_columns(net, clamps)
            step, _ = schur_solve(-z, At, Z, S, -viol)
        else:
            step = -z
        lin.uses += 1
        xf = frame.take(x)
        new = xf + step
        if s.anderson and xs:
            # Anderson acceleration of the chord iteration (GMRES-like on its error)
            dX = np.column_stack([xf - xo for xo in xs])
            dF = np.column_stack([step - fo for fo in fs])
            gamma = np.linalg.lstsq(dF, step, rcond=None)[0]
            new = new - (dX + dF) @ gamma
        xs.append(xf)
        fs.append(step)
        if len(xs) > s.anderson:
            xs.pop(0)
            fs.pop(0)
        x = x.copy()
        x.reshape(-1)[frame.coords] = new
    return None


def _linearise(
    problem: Problem,
    frame: Frame,
    x: NDArray,
    mu: NDArray,
    cache: dict[str, Linearisation],
    key: str,
    stats,
) -> Linearisation | None:
    cache.pop(key, None)  # released before the next one is made (memory at 1e6)
    W = lagrangian_hessian(problem, x, mu, frame=frame)
    factor = frame.factor(W, rough=True)  # the chord needs only an approximate W^-1
    stats.factorisations += 1
    if factor is None:
        return None
    lin = Linearisation(factor, x, frame)
    cache[key] = lin
    return lin


def _equilibrium(
    net: SpringNetwork,
    x: NDArray,
    r: NDArray,
    residuals: tuple[float, float, float],
    mu: NDArray,
    iterations: int,
    t0: float,
    trace_r: list[float],
    trace_t: list[float],
) -> Equilibrium:
    residual, relative, clamp_error = residuals
    x = x.copy()
    x.setflags(write=False)
    return Equilibrium(
        positions=x,
        energy=float(0.5 * np.dot(net.stiffness, (r - net.rest_length) ** 2)),
        residual=residual,
        relative_residual=relative,
        clamp_error=clamp_error,
        clamp_force=-np.asarray(mu, dtype=np.float64),  # dE/dl_c, as relax reports it
        converged=True,
        iterations=iterations,
        seconds=time.perf_counter() - t0,
        method="newton-chord",
        residual_trace=np.asarray(trace_r),
        seconds_trace=np.asarray(trace_t),
    )
