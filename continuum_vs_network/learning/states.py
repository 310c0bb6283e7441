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
``Z_c = W^{-1} a_c`` cached per clamped spring (an approximate ``W^-1`` serves: ``rough``,
float32 where accurate: :func:`~..linalg.spd.factor_spd`; one alive per key). One iteration costs
one pair of triangular solves. Because learning changes the network little per step, the
same factorisation serves the free state, the nudged state (its extra target clamps need
one cached column each: the Schur-complement reuse) and many following learning steps; it
is refreshed when the iteration contracts slowly (ratio > ``refactor_ratio``) and, if that
fails too, the state is found by :func:`~continuum_vs_network.relax`. The chord iteration
is accelerated by Anderson mixing (GMRES-like on its linear error) and starts from a guess
extrapolated from the previous steps (the free state linearly, the nudged state by last
step's nudge displacement). Convergence is judged by ``relax``'s own local stop rule
(:mod:`~continuum_vs_network.network.stopping`), so reuse changes the cost, never the
tolerance. The Lagrangian Hessian and the row order are the engine's
(:mod:`~continuum_vs_network.network.lagrangian`); this module keeps only what is reused.

When ``relax`` itself fails (learning drives networks through snap-through
instabilities, where a Newton iteration can creep), the tracker continues from the failed
state with the engine's dense trust-region Newton, which follows negative curvature
(:func:`~continuum_vs_network.network.trust.trust_region_newton`: what ``relax``'s Newton
runs up to :data:`~continuum_vs_network.network.trust.TR_DENSE_MAX` free coordinates; here
up to ``Solver.trust_region_max_free``, where ``relax`` ran the sparse Newton), to a
looser tolerance, and polishes with ``relax``; then it retries with strain continuation
(``retry_ramps``).

Any other solver setting (``method="paper"``, ``"fire"``, rods, ``reuse=False``) calls
:func:`~continuum_vs_network.relax` with a warm start.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..linalg.kkt import schur_solve
from ..network.arguments import solver_arguments
from ..network.constraints import Problem, clamp_tensions
from ..network.equilibrium import METHODS, Equilibrium, EquilibriumError, relax
from ..network.lagrangian import Frame, lagrangian_hessian
from ..network.model import SpringNetwork
from ..network.stopping import Trace
from ..network.trust import trust_region_newton

__all__ = ["Solver", "Tracker"]

_MAX_REFACTORS = 3  # per chord solve; then relax (with its line search) takes over
_RECOVERY_TOL = 100.0  # the recovery's solve stops at this multiple of tol; relax polishes
_RECOVERY_ITER = 200  # its iteration budget


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
        Relative tolerance of ``relax`` (each net force over its node's ``sum k L``).
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
        When ``relax`` fails (typically at a nearly degenerate equilibrium, where learning
        is about to make the network snap), continue from the failed state with the
        engine's dense trust-region Newton
        (:func:`~continuum_vs_network.network.trust.trust_region_newton`, a fresh radius,
        up to 200 iterations) to ``100 tol`` and polish with ``relax``: problems of at most
        ``trust_region_max_free`` free coordinates (dense).
    trust_region_max_free : int
    retry_ramps : tuple of int
        When that fails too, try again from the start with these numbers of continuation
        steps (``ramp``) before giving up. Neither is tried where ``tol`` is below
        float64's reach at the failed state (``EquilibriumError.roundoff``).
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
            A = self.frame.rows(net, self.x, np.array(missing), dense=True)
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
        load: NDArray | None = None,
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
        load : (n_nodes, 2) float array, optional
            Constant external forces on the nodes (force units; a node task's two-node
            constraint, :meth:`~.node_tasks.NodeTask.hold`). The state then balances
            ``grad E = load``; ``energy`` reports the springs' energy only. Loads need the
            fast path (``Solver.fast`` and ``x0``); where it fails the solve raises.

        Raises
        ------
        EquilibriumError
            No equilibrium to ``tol`` (unless ``accept_unconverged``).
        """
        t0 = time.perf_counter()
        self.stats.solves += 1
        if load is not None:
            return self._loaded(net, pinned, clamped, x0, key, guess, load, t0)
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

    def _loaded(self, net, pinned, clamped, x0, key, guess, load, t0) -> Equilibrium:
        """A solve with external ``load``: the chord iteration only (``relax`` takes none)."""
        load = np.asarray(load, dtype=float)
        if load.shape != (net.n_nodes, 2) or not np.all(np.isfinite(load)):
            raise ValueError(f"load must be a finite ({net.n_nodes}, 2) array")
        if not self.solver.fast or x0 is None:
            raise ValueError(
                "external loads need Solver(method='newton', clamp='exact', reuse=True) and x0"
            )
        start = np.asarray(x0, float)
        if guess is not None:
            start = np.where(pinned, start, np.asarray(guess, float))
        try:
            state = self._chord(net, pinned, clamped, start, key, load=load)
        except (np.linalg.LinAlgError, FloatingPointError, RuntimeError):
            state = None
        finally:
            self.stats.seconds += time.perf_counter() - t0
        if state is None:
            self._lin.pop(key, None)
            raise EquilibriumError("loaded equilibrium: the chord iteration did not converge")
        return state

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
        self._lin.pop(key, None)  # stale after relax: released before (memory at 1e6)
        try:
            return self._relax_once(net, pinned, clamped, x0, first)
        except EquilibriumError as err:
            return self._recover(net, pinned, clamped, x0, first, err)

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
        """After a failed relax: trust region from the failed state, then continuation;
        neither where ``tol`` is below float64's reach at the failed state
        (``err.roundoff``): no solver or start does better there, and the continuation
        from the start cost the paper scene's GPC runs 2000 iterations (2.5 s) a step to
        end in a misleading reason (clamps far from their lengths)."""
        if err.roundoff:
            raise err
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
            y = self._from_failure(problem, x)
            if y is not None:
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

    def _from_failure(self, problem: Problem, x: NDArray) -> NDArray | None:
        """The engine's dense trust region on ``problem`` from ``x`` to ``_RECOVERY_TOL``
        times ``tol`` (``relax`` then polishes): the state it reaches, or None where it
        does not. Dense at every size the tracker asks (``trust_region_max_free``): above
        ``TR_DENSE_MAX`` ``relax`` ran the sparse Newton, and that again from its failed
        state recovered fewer of the stalls the trust region recovers
        (``docs/solver-notes.md#tracker-recovery``)."""
        s = self.solver
        stop = problem.stop_rule(
            _RECOVERY_TOL * s.tol, max_iter=_RECOVERY_ITER, max_seconds=s.max_seconds
        )
        try:
            outcome = trust_region_newton(problem, problem.start(x), stop, Trace())
        except (np.linalg.LinAlgError, FloatingPointError):
            return None
        self.stats.iterations += outcome.iterations
        return outcome.x if outcome.converged and np.all(np.isfinite(outcome.x)) else None

    # -- fast path --------------------------------------------------------------------
    def _linearise(
        self, problem: Problem, frame: Frame, x: NDArray, mu: NDArray, key: str
    ) -> _Linearisation | None:
        self._lin.pop(key, None)  # released before the next one is made (memory at 1e6)
        W = lagrangian_hessian(problem, x, mu, frame=frame)
        factor = frame.factor(W, rough=True)  # the chord needs only an approximate W^-1
        self.stats.factorisations += 1
        if factor is None:
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
        load: NDArray | None = None,
    ) -> Equilibrium | None:
        """Chord SQP from ``x`` (``grad E - load = 0``); None when it fails (the caller
        then relaxes)."""
        s = self.solver
        problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
        lin = self._lin.get(key)
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
                self.stats.iterations += it
                residual = float(np.max(np.abs(force))) if force.size else 0.0
                clamp_error = float(np.max(np.abs(viol))) if viol.size else 0.0
                return _equilibrium(
                    net, x, r, (residual, relative, clamp_error), mu, it, t0, trace_r, trace_t
                )
            measure = max(relative, clamp_relative) / s.tol
            if not np.isfinite(measure):
                return None
            if lin is None or measure > s.refactor_ratio * previous:
                if refactors >= _MAX_REFACTORS:
                    if measure >= previous:
                        return None  # Newton steps do not contract here: relax instead
                else:
                    lin = None  # the caller's reference too: one factorisation alive
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
