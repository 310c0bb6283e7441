"""Equilibria for learning: warm starts and factorisations reused between states and steps.

A learning step needs one or two equilibria (free, nudged or clamped) of a network whose
rest lengths or stiffnesses moved a little since the last step. :class:`Solver` says how
they are found; :class:`Tracker` finds them and keeps what can be reused.

With ``Solver(method="newton", clamp="exact", reuse=True)`` (the default) the tracker runs
a *chord* (modified Newton) SQP iteration (:func:`~.chord.chord_solve`) on a factorisation
of the Lagrangian Hessian kept per key ("free", "clamped") and reused between states and
learning steps; where that fails, the state is found by :func:`~continuum_vs_network.relax`.
The chord starts from a guess extrapolated from the previous steps (the free state
linearly, the nudged state by last step's nudge displacement).

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

from ..network.arguments import solver_arguments
from ..network.constraints import Problem
from ..network.equilibrium import METHODS, Equilibrium, EquilibriumError, relax
from ..network.model import SpringNetwork
from ..network.stopping import Trace
from ..network.trust import trust_region_newton
from .chord import Linearisation, chord_solve

__all__ = ["Solver", "Tracker"]

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
        self._lin: dict[str, Linearisation] = {}

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
                try:
                    state = self._chord(net, pinned, clamped, x0, key, guess, None)
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
        try:
            state = self._chord(net, pinned, clamped, x0, key, guess, load)
        except (np.linalg.LinAlgError, FloatingPointError, RuntimeError):
            state = None
        finally:
            self.stats.seconds += time.perf_counter() - t0
        if state is None:
            self._lin.pop(key, None)
            raise EquilibriumError("loaded equilibrium: the chord iteration did not converge")
        return state

    def _chord(self, net, pinned, clamped, x0, key, guess, load) -> Equilibrium | None:
        """:func:`~.chord.chord_solve` from ``x0``, its free coordinates from ``guess`` when
        given, with this tracker's solver, factorisations and stats."""
        start = np.asarray(x0, float)
        if guess is not None:
            start = np.where(pinned, start, np.asarray(guess, float))
        return chord_solve(
            net, pinned, clamped, start, solver=self.solver, cache=self._lin, key=key,
            stats=self.stats, load=load,
        )  # fmt: skip

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
