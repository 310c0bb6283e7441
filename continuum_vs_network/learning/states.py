"""Equilibria for learning: warm starts and factorisations reused between states and steps.

A learning step needs one or two equilibria (free, nudged or clamped) of a network whose
rest lengths or stiffnesses moved a little since the last step. :class:`Solver` says how
they are found; :class:`Tracker` finds them and keeps what can be reused.

With ``Solver(method="newton", clamp="exact", reuse=True)`` (the default) the tracker runs
a *chord* (modified Newton) SQP iteration on the equilibrium equations::

    F1 = grad E(x) + A(x)^T mu(x) = 0      (net force, mu = least-squares clamp tensions)
    F2 = r_c(x) - l_c              = 0      (clamp lengths)

with a factorisation of the augmented Lagrangian Hessian ``W = H_E + sum mu_c d2r_c +
rho A^T A`` taken at an earlier *linearisation point* and the clamp directions
``Z_c = W^{-1} a_c`` cached per clamped spring. One iteration costs one pair of triangular
solves. Because learning changes the network little per step, the same factorisation
serves the free state, the nudged state (its extra target clamps need one cached column
each: the Schur-complement reuse) and many following learning steps; it is refreshed when
the iteration contracts slowly (ratio > ``refactor_ratio``) and, if that fails too, the
state is found by :func:`~continuum_vs_network.relax`. The chord iteration is accelerated
by Anderson mixing (GMRES-like on its linear error) and starts from a guess extrapolated
from the previous steps (the free state linearly, the nudged state by last step's nudge
displacement). Convergence is judged as ``relax`` judges it (the largest net force on a
free coordinate with the least-squares clamp tensions removed, relative ``tol``; clamp
lengths to ``tol mean(L)``), so reuse changes the cost, never the tolerance.

When ``relax`` itself stalls (learning drives paper networks through snap-through
instabilities, where the core Newton's positive-definite model creeps), the tracker
continues from the stalled point with a dense trust-region Newton that follows negative
curvature (:func:`trust_region`, small problems) and polishes with ``relax``; then it
retries with strain continuation (``retry_ramps``).

Any other solver setting (``method="paper"``, ``"fire"``, rods, ``reuse=False``) calls
:func:`~continuum_vs_network.relax` with a warm start.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..network.arguments import solver_arguments
from ..network.constraints import Problem
from ..network.equilibrium import METHODS, Equilibrium, EquilibriumError, relax
from ..network.model import SpringNetwork

__all__ = ["Frame", "Solver", "Tracker", "lagrangian_hessian", "trust_region"]

_MAX_REFACTORS = 3  # per chord solve; then relax (with its line search) takes over


@dataclass(frozen=True, kw_only=True)
class Solver:
    """How learning rules find equilibria.

    Parameters
    ----------
    method : str
        Any :func:`~continuum_vs_network.relax` method. ``"paper"`` is the seed paper's
        PyTorch Adagrad with rods; it does not converge to ``tol``, so use it with a fixed
        ``max_iter`` budget and ``accept_unconverged=True`` (then the last iterate,
        ``EquilibriumError.state``, is used as the paper's code used it).
    tol : float
        Relative tolerance of ``relax`` (forces over ``mean(k) mean(L)``).
    clamp : {"exact", "rod"}
        Exact clamps (constraints) or the paper's stiff rods.
    rod_stiffness : float
    max_iter : int, optional
        Iteration budget of ``relax`` (its default when None).
    ramp : int
        Strain continuation steps of ``relax`` for a solve without a warm start.
    reuse : bool
        Reuse factorisations between states and steps (Newton with exact clamps only).
    refactor_ratio : float
        Refresh the factorisation when one chord iteration reduces the residual by less
        than this factor.
    anderson : int
        Depth of the Anderson acceleration of the chord iteration (0: plain chord).
    trust_region : bool
        When ``relax`` stalls (typically at a nearly degenerate equilibrium, where learning
        is about to make the network snap), continue with :func:`trust_region` from the
        stalled point and polish with ``relax``: problems of at most
        ``trust_region_max_free`` free coordinates (dense).
    trust_region_max_free : int
    retry_ramps : tuple of int
        When that fails too, try again from the start with these numbers of continuation
        steps (``ramp``) before giving up.
    accept_unconverged : bool
        Return the last iterate instead of raising when ``relax`` does not converge
        (the paper's fixed-budget relaxation). The returned state has ``converged=False``.
    max_seconds : float
        Time budget of one ``relax`` call.
    """

    method: str = "newton"
    tol: float = 1e-10
    clamp: Literal["exact", "rod"] = "exact"
    rod_stiffness: float = 1e10
    max_iter: int | None = None
    ramp: int = 1
    reuse: bool = True
    refactor_ratio: float = 0.1
    accept_unconverged: bool = False
    max_seconds: float = 600.0
    retry_ramps: tuple[int, ...] = (5, 20)
    anderson: int = 4
    trust_region: bool = True
    trust_region_max_free: int = 600

    def __post_init__(self) -> None:
        object.__setattr__(self, "retry_ramps", solver_arguments(self, tuple(METHODS)))

    @property
    def fast(self) -> bool:
        """True when the chord iteration with reused factorisations is used."""
        return self.reuse and self.method == "newton" and self.clamp == "exact"


class Frame:
    """The order of the free coordinates in assembled matrices, for one topology and pins.

    The core's :func:`~continuum_vs_network.network.newton.pattern_for` may order rows for
    fill reduction (``pattern.coords``); every vector and matrix this module builds uses
    the same order, so factorisations match the ones ``relax`` makes.

    Attributes
    ----------
    pattern : HessianPattern
    coords : (n,) int array
        Flat coordinate (index into ``x.ravel()``) of each row.
    index : (2 n_nodes,) int array
        Row of each flat coordinate, -1 for pinned ones.
    ordered : bool
        Rows are already in a fill-reducing order.
    """

    def __init__(self, net: SpringNetwork, free: NDArray) -> None:
        from ..network import newton

        free = np.asarray(free, dtype=bool)
        try:
            pattern = newton.pattern_for(net.springs, net.n_nodes, free, net.positions)
        except TypeError:  # older signature without positions
            pattern = newton.pattern_for(net.springs, net.n_nodes, free)
        self.pattern = pattern
        coords = getattr(pattern, "coords", None)
        self.coords = np.flatnonzero(free.ravel()) if coords is None else np.asarray(coords)
        self.ordered = bool(getattr(pattern, "ordered", False))
        self.n_nodes = net.n_nodes
        self.n = int(self.coords.size)
        self.index = np.full(2 * net.n_nodes, -1, dtype=np.int64)
        self.index[self.coords] = np.arange(self.n)
        self._incidence: tuple[sp.csr_matrix, sp.csr_matrix] | None = None

    def take(self, full: NDArray) -> NDArray:
        """Free entries of a (n_nodes, 2) array, in row order, (n,)."""
        return np.asarray(full).reshape(-1)[self.coords]

    def put(self, vec: NDArray) -> NDArray:
        """A (n_nodes, 2) array that is ``vec`` on free coordinates and 0 elsewhere."""
        out = np.zeros(2 * self.n_nodes)
        out[self.coords] = vec
        return out.reshape(self.n_nodes, 2)

    def rows(self, net: SpringNetwork, x: NDArray, springs: NDArray) -> sp.csr_matrix:
        """Length gradients ``dr_j/dx`` of ``springs`` as a sparse (len(springs), n)."""
        springs = np.atleast_1d(np.asarray(springs, dtype=np.int64))
        pairs = net.springs[springs]
        d = x[pairs[:, 1]] - x[pairs[:, 0]]
        u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
        flat = np.stack(
            [2 * pairs[:, 0], 2 * pairs[:, 0] + 1, 2 * pairs[:, 1], 2 * pairs[:, 1] + 1], 1
        )
        vals = np.stack([-u[:, 0], -u[:, 1], u[:, 0], u[:, 1]], 1)
        cols = self.index[flat]
        keep = cols >= 0
        rows = np.repeat(np.arange(springs.size), 4).reshape(-1, 4)
        return sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(springs.size, self.n))

    def gradient(self, net: SpringNetwork, x: NDArray) -> NDArray:
        """``dE/dx`` on free coordinates in row order, (n,), by two sparse products.

        Same values as :func:`~continuum_vs_network.network.energy.spring_gradient`
        (round-off aside); the incidence matrices are built once per frame.
        """
        return self.gradient_and_lengths(net, x)[0]

    def gradient_and_lengths(self, net: SpringNetwork, x: NDArray) -> tuple[NDArray, NDArray]:
        """:meth:`gradient` and the spring lengths ``r`` (n_springs,) it used."""
        if self._incidence is None:
            s = net.n_springs
            rows = np.concatenate([np.arange(s), np.arange(s)])
            cols = np.concatenate([net.springs[:, 0], net.springs[:, 1]])
            vals = np.concatenate([-np.ones(s), np.ones(s)])
            D = sp.csr_matrix((vals, (rows, cols)), shape=(s, net.n_nodes))
            self._incidence = (D, D.T.tocsr())
        D, Dt = self._incidence
        d = D @ x
        r = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)
        t = (net.stiffness * (r - net.rest_length) / np.maximum(r, 1e-300))[:, None] * d
        return (Dt @ t).reshape(-1)[self.coords], r

    def dense_rows(self, net: SpringNetwork, x: NDArray, springs: NDArray) -> NDArray:
        """Length gradients ``dr_j/dx`` of ``springs`` as a dense (len(springs), n) array."""
        springs = np.atleast_1d(np.asarray(springs, dtype=np.int64))
        pairs = net.springs[springs]
        d = x[pairs[:, 1]] - x[pairs[:, 0]]
        u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
        out = np.zeros((springs.size, self.n + 1))  # column n collects pinned entries
        rows = np.arange(springs.size)
        for k, (node, c, sign) in enumerate(((0, 0, -1), (0, 1, -1), (1, 0, 1), (1, 1, 1))):
            del k
            out[rows, self.index[2 * pairs[:, node] + c]] = sign * u[:, c]
        return out[:, : self.n]

    def factor(self, W: sp.csr_matrix):
        """Positive-definite factorisation of ``W`` (None when it is not)."""
        from ..network.newton import factor_pd

        return factor_pd(W, ordered=True) if self.ordered else factor_pd(W)


def lagrangian_hessian(
    problem: Problem,
    x: NDArray,
    multipliers: NDArray,
    *,
    rho: float | None = None,
    frame: Frame | None = None,
) -> sp.csr_matrix:
    """Hessian of the (augmented) Lagrangian on free coordinates, (n, n) CSR.

    ``W = H_E(x) + sum_c mu_c d^2 r_c / dx^2 + rho sum_c a_c a_c^T`` with ``a_c = dr_c/dx``
    the clamp directions and ``mu`` the multipliers of ``grad E + A^T mu = 0`` (minus
    ``Equilibrium.clamp_force``). ``rho`` (default ``max(k)`` when there are clamps) adds
    a multiple of ``A^T A`` that leaves every KKT solution unchanged but makes ``W``
    positive definite at a stable constrained minimum. Rows in ``frame`` order (default:
    the frame of ``problem``). Exact clamps only.
    """
    net = problem.net
    frame = frame or Frame(net, problem.free)
    springs, clamps = net.springs, problem.clamp_springs
    d = x[springs[:, 1]] - x[springs[:, 0]]
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
    axial = net.stiffness.copy()
    tangential = net.stiffness * (1.0 - net.rest_length / r)
    if clamps.size:
        rho = float(np.max(net.stiffness)) if rho is None else float(rho)
        np.add.at(axial, clamps, rho)
        np.add.at(tangential, clamps, np.asarray(multipliers, float) / r[clamps])
    u = d / r[:, None]
    uu = u[:, :, None] * u[:, None, :]
    blocks = axial[:, None, None] * uu + tangential[:, None, None] * (np.eye(2) - uu)
    return frame.pattern.assemble(blocks)


def trust_region(
    problem: Problem,
    x: NDArray,
    *,
    force_tol: float,
    max_iter: int = 200,
) -> tuple[NDArray, bool]:
    """Dense trust-region Newton on the clamp manifold, for small stalled problems.

    Newton with a positive-definite model creeps where the equilibrium is nearly degenerate
    (a soft mode whose curvature changes sign: the warm-started branch is about to vanish
    or has just vanished). This method uses the exact reduced Hessian
    ``Q^T W Q`` (``Q`` a basis of the null space of the clamp Jacobian) with a trust region
    (eigen-decomposition, so negative curvature is followed, not clipped), restores the
    clamp lengths after every step, and accepts steps that lower the energy (or, once the
    energy change is at round-off, the residual). It stops when
    the residual is ``<= force_tol`` (absolute); :func:`relax` then polishes. Dense:
    O(n_free^3) per iteration.

    Returns ``(x, reached)``.
    """
    net = problem.net
    frame = Frame(net, problem.free)
    clamps = problem.clamp_springs
    m = problem.n_clamps
    x = _restore(problem, np.array(x, dtype=np.float64))
    scale = float(np.mean(net.rest_length))
    radius = 0.1 * scale
    energy = problem.energy(x)
    for _ in range(max_iter):
        residual, mu = problem.residual(x)
        if residual <= force_tol:
            return x, True
        g = frame.take(problem.gradient(x))
        if m:
            vt = np.linalg.svd(frame.rows(net, x, clamps).toarray())[2]
            Q = vt[m:].T
        else:
            Q = np.eye(frame.n)
        W = lagrangian_hessian(problem, x, mu, rho=0.0, frame=frame).toarray()
        H = Q.T @ W @ Q
        gr = Q.T @ g
        vals, vecs = np.linalg.eigh(H)
        gt = vecs.T @ gr

        low = max(0.0, -vals[0])
        p = _tr_step(vals, vecs, gt, 0.0) if vals[0] > 0 else None
        if p is None or np.linalg.norm(p) > radius:
            lo, hi = low, low + np.linalg.norm(gr) / radius + abs(vals[-1])
            for _ in range(80):  # bisection on the shift: |p(shift)| = radius
                mid = 0.5 * (lo + hi)
                long = np.linalg.norm(_tr_step(vals, vecs, gt, mid)) > radius
                lo, hi = (mid, hi) if long else (lo, mid)
            p = _tr_step(vals, vecs, gt, hi)
        predicted = float(gr @ p + 0.5 * p @ H @ p)
        y = x + frame.put(Q @ p)
        y = _restore(problem, y)
        e_y = problem.energy(y)
        ratio = (e_y - energy) / predicted if predicted < 0 else -1.0
        flat = abs(e_y - energy) <= 1e-12 * abs(energy)  # energy at round-off: use the force
        if e_y < energy or (flat and problem.residual(y)[0] < residual):
            x, energy = y, e_y
        radius *= 2.0 if ratio > 0.75 else (0.25 if ratio < 0.25 else 1.0)
        radius = max(radius, 1e-12 * scale)
    return x, False


def _tr_step(vals: NDArray, vecs: NDArray, gt: NDArray, shift: float) -> NDArray:
    return -vecs @ (gt / (vals + shift))


def _restore(problem: Problem, y: NDArray) -> NDArray:
    """Minimum-norm correction of ``y`` back onto the clamp lengths (Gauss-Newton)."""
    if not problem.n_clamps:
        return y
    target = 1e-13 * float(np.mean(problem.clamp_lengths))
    for _ in range(20):
        if np.max(np.abs(problem.clamp_violation(y))) <= target:
            break
        y = problem.toward_clamps(y)
    return y


class _Linearisation:
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
            A = self.frame.dense_rows(net, self.x, np.array(missing))
            Z = np.asarray(self.factor.solve(A.T.copy())).reshape(n, len(missing))
            for j, s in enumerate(missing):
                self.columns[s] = (A[j], Z[:, j].copy())
        A = np.array([self.columns[s][0] for s in key]).reshape(len(key), n)
        Z = np.array([self.columns[s][1] for s in key]).reshape(len(key), n).T
        self.sets[key] = (A, Z, A @ Z)
        return self.sets[key]


@dataclass
class TrackerStats:
    """Work done by a :class:`Tracker` (cumulative counts)."""

    solves: int = 0
    iterations: int = 0
    factorisations: int = 0
    relax_calls: int = 0
    retries: int = 0
    trust_regions: int = 0
    seconds: float = 0.0


class Tracker:
    """Finds the equilibria of one task along a learning run, reusing what it can.

    A tracker holds mutable caches (warm starts are passed in by the caller; the
    factorisations live here), so use one tracker per training trial.
    """

    def __init__(self, solver: Solver | None = None) -> None:
        self.solver = solver or Solver()
        self.stats = TrackerStats()
        self._lin: dict[str, _Linearisation] = {}

    def forget(self) -> None:
        """Drop every cached factorisation."""
        self._lin.clear()

    # -- the one entry point ----------------------------------------------------------
    def solve(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        x0: NDArray | None,
        *,
        key: str = "free",
        guess: NDArray | None = None,
    ) -> Equilibrium:
        """Equilibrium of ``net`` with ``pinned`` coordinates and ``clamped`` springs.

        Parameters
        ----------
        net : SpringNetwork
        pinned : (n_nodes, 2) bool array
        clamped : {spring: length}
        x0 : (n_nodes, 2) float array or None
            Warm start (None: ``net.positions`` with ``relax``'s ramp).
        key : str
            Which cached linearisation to use and refresh ("free" for the free and the
            nudged state, "clamped" for a clamped state far from the free one).
        guess : (n_nodes, 2) float array, optional
            A predicted equilibrium (extrapolated from earlier steps) for the fast path to
            start from; ``relax`` always starts from ``x0``. Pinned coordinates are taken
            from ``x0``.

        Raises
        ------
        EquilibriumError
            No equilibrium to ``tol`` (unless ``accept_unconverged``).
        """
        t0 = time.perf_counter()
        self.stats.solves += 1
        try:
            if self.solver.fast and x0 is not None:
                start = np.asarray(x0, float)
                if guess is not None:
                    start = np.where(pinned, start, np.asarray(guess, float))
                try:
                    state = self._chord(net, pinned, clamped, start, key)
                except (np.linalg.LinAlgError, FloatingPointError, RuntimeError):
                    self._lin.pop(key, None)  # degenerate linear algebra: relax instead
                    state = None
                if state is not None:
                    return state
            return self._relax(net, pinned, clamped, x0, key)
        finally:
            self.stats.seconds += time.perf_counter() - t0

    # -- robust path ------------------------------------------------------------------
    def _relax(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        x0: NDArray | None,
        key: str,
    ) -> Equilibrium:
        first = self.solver.ramp if x0 is None else 1
        try:
            eq = self._relax_once(net, pinned, clamped, x0, first)
        except EquilibriumError as err:
            eq = self._recover(net, pinned, clamped, x0, first, err)
        self._lin.pop(key, None)
        return eq

    def _relax_once(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        x0: NDArray | None,
        ramp: int,
    ) -> Equilibrium:
        s = self.solver
        self.stats.relax_calls += 1
        try:
            eq = relax(
                net,
                pinned=pinned,
                clamped=clamped,
                x0=x0,
                method=s.method,
                tol=s.tol,
                clamp=s.clamp,
                rod_stiffness=s.rod_stiffness,
                ramp=ramp,
                max_iter=s.max_iter,
                max_seconds=s.max_seconds,
            )
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as err:
            degenerate = isinstance(err, (np.linalg.LinAlgError, FloatingPointError))
            if not degenerate and "floppy" not in str(err):
                raise  # a ValueError about the input
            # the core solver hit a degenerate or non-finite iterate (learning drove the
            # network there): a failed equilibrium, not a bug in the caller
            raise EquilibriumError(f"{s.method}: {type(err).__name__}: {err}") from err
        except EquilibriumError as err:
            state = err.state
            self.stats.iterations += 0 if state is None else state.iterations
            if s.accept_unconverged and state is not None and np.all(np.isfinite(state.positions)):
                return state
            raise
        self.stats.iterations += eq.iterations
        return eq

    def _recover(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        x0: NDArray | None,
        first: int,
        err: EquilibriumError,
    ) -> Equilibrium:
        """After a failed relax: trust region from the stalled point, then continuation."""
        s = self.solver
        last = err
        x = None if err.state is None else np.asarray(err.state.positions)
        problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
        if (
            s.trust_region
            and x is not None
            and np.all(np.isfinite(x))
            and 0 < problem.free_flat.size <= s.trust_region_max_free
        ):
            # a stall at a nearly degenerate equilibrium: follow the exact curvature, polish
            self.stats.trust_regions += 1
            y, reached = trust_region(problem, x, force_tol=100 * s.tol * net.force_scale)
            if reached:
                try:
                    return self._relax_once(net, pinned, clamped, y, 1)
                except EquilibriumError as e:
                    last = e
        for ramp in s.retry_ramps:
            if ramp <= first:
                continue
            self.stats.retries += 1
            try:
                return self._relax_once(net, pinned, clamped, x0, ramp)
            except EquilibriumError as e:
                last = e
        raise last

    # -- fast path --------------------------------------------------------------------
    def _linearise(
        self, problem: Problem, frame: Frame, x: NDArray, mu: NDArray, key: str
    ) -> _Linearisation | None:
        W = lagrangian_hessian(problem, x, mu, frame=frame)
        factor = frame.factor(W)
        self.stats.factorisations += 1
        if factor is None:
            self._lin.pop(key, None)
            return None
        lin = _Linearisation(factor, x, frame)
        self._lin[key] = lin
        return lin

    def _chord(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        x: NDArray,
        key: str,
    ) -> Equilibrium | None:
        """Chord SQP from ``x``; None when it fails (the caller then relaxes)."""
        s = self.solver
        problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
        lin = self._lin.get(key)
        if lin is not None and lin.frame.n != int(problem.free_flat.size):
            lin = None
        frame = lin.frame if lin is not None else Frame(net, problem.free)
        clamps = problem.clamp_springs
        f_tol = s.tol * net.force_scale
        l_tol = s.tol * float(np.mean(net.rest_length))
        trace_r: list[float] = []
        trace_t: list[float] = []
        t0 = time.perf_counter()
        refactors = 0  # factorisations made by this call
        x = x.copy()
        previous = np.inf
        xs: list[NDArray] = []  # Anderson memory: free coordinates and chord steps
        fs: list[NDArray] = []
        for it in range(30):
            if not np.all(np.isfinite(x)):
                return None
            g, r = frame.gradient_and_lengths(net, x)
            if clamps.size:
                A = frame.dense_rows(net, x, clamps)
                viol = r[clamps] - problem.clamp_lengths
                mu = _least_squares_multipliers(A, g)
                force = g + A.T @ mu
            else:
                viol, mu, force = np.empty(0), np.empty(0), g
            residual = float(np.max(np.abs(force))) if force.size else 0.0
            clamp_error = float(np.max(np.abs(viol))) if viol.size else 0.0
            trace_r.append(residual)
            trace_t.append(time.perf_counter() - t0)
            if residual <= f_tol and clamp_error <= l_tol:
                self.stats.iterations += it
                return _equilibrium(net, x, r, residual, clamp_error, mu, it, t0, trace_r, trace_t)
            measure = max(residual / f_tol, clamp_error / l_tol)
            if not np.isfinite(measure):
                return None
            if lin is None or measure > s.refactor_ratio * previous:
                if refactors >= _MAX_REFACTORS:
                    if measure >= previous:
                        return None  # Newton steps do not contract here: relax instead
                else:
                    lin = self._linearise(problem, frame, x, mu, key)
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
                step = -z - Z @ np.linalg.solve(S, viol - At @ z)
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


def _least_squares_multipliers(A: NDArray, g: NDArray) -> NDArray:
    """``mu`` minimising ``|g + A^T mu|`` (normal equations; lstsq if they are singular)."""
    try:
        return -np.linalg.solve(A @ A.T, A @ g)
    except np.linalg.LinAlgError:
        return -np.linalg.lstsq(A @ A.T, A @ g, rcond=None)[0]


def _equilibrium(
    net: SpringNetwork,
    x: NDArray,
    r: NDArray,
    residual: float,
    clamp_error: float,
    mu: NDArray,
    iterations: int,
    t0: float,
    trace_r: list[float],
    trace_t: list[float],
) -> Equilibrium:
    x = x.copy()
    x.setflags(write=False)
    return Equilibrium(
        positions=x,
        energy=float(0.5 * np.dot(net.stiffness, (r - net.rest_length) ** 2)),
        residual=residual,
        clamp_error=clamp_error,
        clamp_force=-np.asarray(mu, dtype=np.float64),  # dE/dl_c, as relax reports it
        converged=True,
        iterations=iterations,
        seconds=time.perf_counter() - t0,
        method="newton-chord",
        residual_trace=np.asarray(trace_r),
        seconds_trace=np.asarray(trace_t),
    )
