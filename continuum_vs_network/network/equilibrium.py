"""Mechanical equilibrium of a pinned, clamped spring network: ``cvn.relax``.

Every method minimises the same :class:`~.constraints.Problem` and is judged by the same
residual (:meth:`Problem.residual`): the largest net force on a free coordinate after the
clamp-normal components (the Lagrange multipliers) are removed. ``tol`` is relative to the
network's force scale ``F = mean(k) mean(L)`` for forces and to ``mean(L)`` for clamp
lengths; the reported residual is in absolute force units.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from .arguments import lone_nodes, relax_arguments
from .constraints import ClampMode, Pins, Problem, default_pins
from .energy import spring_energy
from .model import SpringNetwork

__all__ = ["METHODS", "Equilibrium", "EquilibriumError", "StopRule", "Trace", "relax"]


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """Result of :func:`relax`.

    Attributes
    ----------
    positions : (n_nodes, 2) float array
    energy : float
        Elastic energy of the network's springs (Eq. 11), rods excluded.
    residual : float
        Largest net force on a free coordinate, clamp-normal forces removed (force units).
    clamp_error : float
        Largest ``|r_c - l_c|`` over clamped springs (length units; 0 without clamps).
    clamp_force : (m,) float array
        Generalised force on each clamp, ``dE/dl_c`` at equilibrium (minus the Lagrange
        multiplier): the tension with which the network pulls the clamp's two nodes
        together, positive when the clamp holds them apart. In ``clamped`` order.
    converged : bool
    iterations : int
    seconds : float
        Wall-clock time of the solve.
    method : str
    residual_trace, seconds_trace : (n_records,) float arrays
        Residual at each recorded iteration and the wall-clock time at which it was
        reached, for error-against-run-time plots.
    iteration_trace : (n_records,) int array
        The iteration (counted over every stage of the solve) of each record: Newton
        records every iteration, FIRE, L-BFGS and Adagrad every tenth and the last.
        Default: ``arange(n_records)`` (one record per iteration).
    """

    positions: NDArray[np.float64]
    energy: float
    residual: float
    clamp_error: float
    clamp_force: NDArray[np.float64]
    converged: bool
    iterations: int
    seconds: float
    method: str
    residual_trace: NDArray[np.float64] = field(repr=False)
    seconds_trace: NDArray[np.float64] = field(repr=False)
    iteration_trace: NDArray[np.int64] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.iteration_trace is None:
            object.__setattr__(
                self, "iteration_trace", np.arange(np.asarray(self.residual_trace).size)
            )


class EquilibriumError(RuntimeError):
    """Raised when a method does not reach the requested residual.

    Attributes
    ----------
    state : Equilibrium
        The last iterate, with ``converged=False`` and its diagnostics.
    reason : str
    """

    def __init__(self, reason: str, state: Equilibrium | None = None) -> None:
        self.reason = reason
        self.state = state
        detail = ""
        if state is not None:
            detail = (
                f" (method={state.method}, iterations={state.iterations}, "
                f"residual={state.residual:.3e}, clamp_error={state.clamp_error:.3e}, "
                f"seconds={state.seconds:.3g})"
            )
        super().__init__(reason + detail)


class Trace:
    """Residual against wall-clock time and iteration, recorded by a solver as it iterates.

    A solver records ``record(residual, it)`` with its own iteration count ``it``; the
    caller that chains solves (stages, inner loops) sets ``base`` to the iterations done
    before, so the recorded iteration is the count over the whole solve.
    """

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.base = 0
        self.residual: list[float] = []
        self.seconds: list[float] = []
        self.iteration: list[int] = []

    def record(self, residual: float, it: int) -> None:
        self.residual.append(float(residual))
        self.seconds.append(time.perf_counter() - self.t0)
        self.iteration.append(self.base + int(it))

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0


@dataclass(frozen=True)
class StopRule:
    """When a solver stops: absolute force and length tolerances and budgets."""

    force: float
    length: float
    max_iter: int
    max_seconds: float

    def met(self, residual: float, clamp_error: float) -> bool:
        return residual <= self.force and clamp_error <= self.length


@dataclass(frozen=True)
class Outcome:
    """What a method returns to :func:`relax`."""

    x: NDArray[np.float64]
    iterations: int
    converged: bool
    message: str = ""


Method = Callable[[Problem, NDArray, StopRule, Trace], Outcome]


def _newton(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    from .newton import newton

    return newton(problem, x, stop, trace)


def _fire(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    from .minimizers import fire

    return fire(problem, x, stop, trace)


def _lbfgs(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    from .minimizers import lbfgs

    return lbfgs(problem, x, stop, trace)


def _paper(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    from .minimizers import paper_adagrad

    return paper_adagrad(problem, x, stop, trace)


METHODS: dict[str, Method] = {"newton": _newton, "fire": _fire, "lbfgs": _lbfgs, "paper": _paper}
_DEFAULT_MAX_ITER = {"newton": 200, "fire": 200_000, "lbfgs": 50_000, "paper": 20_000}


def relax(
    net: SpringNetwork,
    pinned: Pins = None,
    clamped: Mapping[int, float] | None = None,
    x0: ArrayLike | None = None,
    method: str = "newton",
    tol: float = 1e-10,
    *,
    clamp: ClampMode = "exact",
    rod_stiffness: float = 1e10,
    ramp: int = 1,
    max_iter: int | None = None,
    max_seconds: float = 600.0,
) -> Equilibrium:
    """Find the mechanical equilibrium of ``net`` with pinned nodes and clamped springs.

    Parameters
    ----------
    net : SpringNetwork
    pinned : sequence of node indices, (n_nodes, 2) bool mask, or None
        Coordinates held at their values in ``x0``. None pins one node fully and one
        coordinate of a far node, chosen away from the clamped springs.
    clamped : {spring_index: length}, optional
        Springs held at a length (Eq. 25).
    x0 : (n_nodes, 2) float array, optional
        Starting positions (default ``net.positions``); pinned coordinates keep these values.
    method : {"newton", "fire", "lbfgs", "paper"}
        ``newton``: sparse Newton with exact clamps (default). ``fire`` and ``lbfgs``:
        first-order minimisers, exact clamps through an augmented Lagrangian. ``paper``: the
        seed paper's PyTorch Adagrad (learning rate 0.1) with rod clamps; it stalls and is
        kept as a baseline.
    tol : float
        Relative tolerance: converged when the residual is ``<= tol * F`` with
        ``F = mean(k) mean(L)`` and every clamp within ``tol * mean(L)`` of its length.
    clamp : {"exact", "rod"}
        Exact equality constraints, or the paper's stiff rods of ``rod_stiffness``.
        ``method="paper"`` always uses rods.
    ramp : int
        Strain continuation: approach the clamp lengths in ``ramp`` equal steps from the
        starting lengths, each relaxed in turn. At large strains the energy has several
        local minima and the one found depends on this path.
    max_iter, max_seconds : budgets; exceeding either raises :class:`EquilibriumError`.

    Returns
    -------
    Equilibrium

    Raises
    ------
    ValueError
        Bad input (named), or a floppy network (with its count of zero modes).
    EquilibriumError
        The method did not reach ``tol``; ``err.state`` holds the last iterate.
    """
    args = relax_arguments(
        net, methods=tuple(METHODS), method=method, tol=tol, clamp=clamp,
        rod_stiffness=rod_stiffness, ramp=ramp, max_iter=max_iter, max_seconds=max_seconds,
    )  # fmt: skip
    method, tol, ramp, max_iter, max_seconds = (
        args.method, args.tol, args.ramp, args.max_iter, args.max_seconds
    )  # fmt: skip
    if method == "paper":
        clamp = "rod"
    problem = Problem.build(
        net, pinned=pinned, clamped=clamped, clamp=clamp, rod_stiffness=rod_stiffness
    )
    floppy = problem.maxwell_zero_modes()
    if floppy:
        raise ValueError(
            f"network is floppy: at least {floppy} zero modes beyond rigid motion "
            f"({int(problem.free.sum())} free coordinates, {int((net.stiffness > 0).sum())} "
            f"springs with k > 0, {problem.n_clamps} clamps); add springs or pins"
        )
    lone_nodes(net, problem.free)
    stop = StopRule(
        force=tol * net.force_scale,
        length=tol * float(np.mean(net.rest_length)),
        max_iter=max_iter or _DEFAULT_MAX_ITER[method],
        max_seconds=float(max_seconds),
    )
    x = _start(problem, x0)
    trace = Trace()
    solve = METHODS[method]
    start_lengths = net.lengths(x)[problem.clamp_springs]
    iterations = 0
    outcome = Outcome(x, 0, True)
    for step in range(1, int(ramp) + 1):
        frac = step / ramp
        lengths = start_lengths + frac * (problem.clamp_lengths - start_lengths)
        stage = Problem(
            net, problem.free, problem.clamp_springs, lengths, problem.clamp, problem.rod_stiffness
        )
        trace.base = iterations
        outcome = solve(stage, stage.start(outcome.x), stop, trace)
        iterations += outcome.iterations
        if not outcome.converged:
            break
    # Default pins only remove rigid motion, so they must carry no load. After a large
    # deformation two of them can line up and act as a strut: choose them anew at the
    # deformed positions and relax again from there.
    for _ in range(3):
        if pinned is not None or not outcome.converged:
            break
        if _pin_reaction(problem, outcome.x) <= stop.force:
            break
        avoid = problem.clamp_springs
        free = ~default_pins(net.with_positions(outcome.x), avoid)
        problem = Problem(
            net,
            free,
            problem.clamp_springs,
            problem.clamp_lengths,
            problem.clamp,
            problem.rod_stiffness,
        )
        trace.base = iterations
        outcome = solve(problem, outcome.x, stop, trace)
        iterations += outcome.iterations
    return _finish(problem, outcome, iterations, method, stop, trace)


def _pin_reaction(problem: Problem, x: NDArray) -> float:
    """Largest force the pins exert on the network at ``x``, clamp forces removed."""
    pinned = np.flatnonzero(~problem.free.ravel())
    if not pinned.size:
        return 0.0
    everywhere = np.arange(problem.free.size)
    force, _ = problem.unbalanced_force(x, everywhere)
    return float(np.max(np.abs(force[pinned])))


def _start(problem: Problem, x0: ArrayLike | None) -> NDArray:
    if x0 is None:
        return problem.net.positions.copy()
    return check.float_array("x0", x0, (problem.net.n_nodes, 2))


def _finish(
    problem: Problem, outcome: Outcome, iterations: int, method: str, stop: StopRule, trace: Trace
) -> Equilibrium:
    x, net = outcome.x, problem.net
    finite = bool(np.all(np.isfinite(x)))
    if finite:
        residual, mu = problem.residual(x)
        violation = problem.clamp_violation(x)
        clamp_error = float(np.max(np.abs(violation))) if violation.size else 0.0
        energy = spring_energy(x, net.springs, net.stiffness, net.rest_length)
    else:
        residual, clamp_error, energy = np.inf, np.inf, np.inf
        mu = np.full(problem.n_clamps, np.inf)
    # a rod yields by its tension / rod_stiffness: only exact clamps are held to tol
    converged = (
        finite
        and outcome.converged
        and stop.met(residual, clamp_error if problem.clamp == "exact" else 0.0)
    )
    x = x.copy()
    x.setflags(write=False)
    state = Equilibrium(
        positions=x,
        energy=energy,
        residual=residual,
        clamp_error=clamp_error,
        clamp_force=-np.asarray(mu, dtype=np.float64),
        converged=converged,
        iterations=iterations,
        seconds=trace.elapsed(),
        method=method,
        residual_trace=np.asarray(trace.residual),
        seconds_trace=np.asarray(trace.seconds),
        iteration_trace=np.asarray(trace.iteration, dtype=np.int64),
    )
    if not converged:
        reason = outcome.message or "did not reach the requested residual"
        if not finite:
            reason = "iterate became non-finite; " + reason
        raise EquilibriumError(
            f"{method}: {reason} (wanted residual <= {stop.force:.3e}, "
            f"clamp error <= {stop.length:.3e})",
            state,
        )
    return state
