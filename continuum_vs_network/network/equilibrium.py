"""Mechanical equilibrium of a pinned, clamped spring network: ``cvn.relax``.

Every method minimises the same :class:`~.constraints.Problem` and is judged by the same
local stop rule (:mod:`.stopping`): the net force on each free coordinate, clamp-normal
components (the Lagrange multipliers, a least-squares fit weighted by ``1 / f_i``) removed,
relative to the force scale of that node's own springs ``f_i = sum_j k_j L_j``; clamp
lengths relative to the clamped spring's rest length.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from .arguments import relax_arguments
from .checks import (
    clamp_roundoff_floor,
    collapse_note,
    collapsed_springs,
    dependent_clamps,
    refuse_floppy,
    roundoff_floor,
)
from .constraints import ClampMode, Pins, Problem, Residual, default_pins
from .energy import spring_energy
from .escapes import DEFAULT_TOL, Method, second_order, unfold
from .minimizers import fire, lbfgs, paper_adagrad
from .model import SpringNetwork
from .newton import newton
from .pin_load import pin_reaction, pins_loaded, residual_and_reaction
from .placement import lever_frame, place_on_pins
from .reachable import refuse_unreachable_clamps
from .stopping import Outcome, StopRule, Trace
from .trust import TR_DENSE_MAX

__all__ = ["METHODS", "Equilibrium", "EquilibriumError", "relax"]


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """Result of :func:`relax`.

    Attributes
    ----------
    positions : (n_nodes, 2) float array
    energy : float
        Elastic energy of the network's springs (Eq. 11), rods excluded.
    residual : float
        Largest absolute net force on a free coordinate, clamp-normal forces removed
        (force units).
    relative_residual : float
        Largest relative imbalance ``max_ic |F_ic| / f_i`` with ``f_i = sum_j k_j L_j``
        over node ``i``'s springs: the quantity ``tol`` bounds (see :func:`relax`).
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
        Relative residual (as ``relative_residual``) at each recorded iteration and the
        wall-clock time at which it was reached, for error-against-run-time plots.
    iteration_trace : (n_records,) int array
        The iteration (counted over every stage of the solve) of each record: Newton
        records every iteration, FIRE, L-BFGS and Adagrad every tenth and the last.
        Default: ``arange(n_records)`` (one record per iteration).
    """

    positions: NDArray[np.float64]
    energy: float
    residual: float
    relative_residual: float
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
    roundoff : bool
        ``tol`` is below float64's reach at ``state``: its residual or clamp error is
        within 10x of what moving every coordinate by one rounding unit changes
        (:func:`~.checks.roundoff_floor`, :func:`~.checks.clamp_roundoff_floor`), so no
        solver, start or continuation does better in float64.
    """

    def __init__(
        self, reason: str, state: Equilibrium | None = None, *, roundoff: bool = False
    ) -> None:
        self.reason = reason
        self.state = state
        self.roundoff = roundoff
        detail = ""
        if state is not None:
            detail = (
                f" (method={state.method}, iterations={state.iterations}, "
                f"residual={state.residual:.3e}, relative_residual="
                f"{state.relative_residual:.3e}, clamp_error={state.clamp_error:.3e}, "
                f"seconds={state.seconds:.3g})"
            )
        super().__init__(reason + detail)


METHODS: dict[str, Method] = {
    "newton": newton,
    "fire": fire,
    "lbfgs": lbfgs,
    "paper": paper_adagrad,
}
_PIN_ROUNDS = 3  # re-pinnings of the default pins while they carry load
_PIN_TIGHTEST = 1e-3  # the most one re-pinning's solve tightens the tolerance by
_DEFAULT_MAX_ITER = {"newton": 2000, "fire": 200_000, "lbfgs": 50_000, "paper": 20_000}


def relax(
    net: SpringNetwork,
    pinned: Pins = None,
    clamped: Mapping[int, float] | None = None,
    x0: ArrayLike | None = None,
    method: str = "newton",
    tol: float = DEFAULT_TOL,
    *,
    clamp: ClampMode = "exact",
    rod_stiffness: float = 1e10,
    ramp: int = 1,
    max_iter: int | None = None,
    max_seconds: float = 600.0,
    sparse_solver: str = "auto",
) -> Equilibrium:
    """Find the mechanical equilibrium of ``net`` with pinned nodes and clamped springs.

    Parameters
    ----------
    net : SpringNetwork
    pinned : sequence of integer node indices, (n_nodes, 2) bool mask, or None
        Anything else (a 0/1 integer or float array of that shape, float indices, a
        flattened 0/1 mask) raises :class:`~continuum_vs_network._validate.ArgumentError`.
        Coordinates held at their values in ``x0``. None pins one node fully and one
        coordinate of a far node, chosen away from the clamped springs; they only remove
        rigid motion: Newton on up to ``TR_DENSE_MAX`` coordinates removes it itself, other
        solves hold the far node on the line through the first in their start direction
        (:func:`~.placement.lever_frame`); the result is placed on the pins: the node in
        place, the coordinate kept, or, when the network shrank below that offset, the
        pair's start orientation. They carry no load: every node's net force, theirs
        included, is within ``tol`` (while they carry more, they are chosen anew and the
        solve goes further below ``tol``, up to three times; else EquilibriumError).
    clamped : {spring_index: length}, optional
        Springs held at a length (Eq. 25).
    x0 : (n_nodes, 2) float array, optional
        Starting positions (default ``net.positions``); pinned coordinates keep these values.
        Where ``x0`` is ``net.positions`` with only pinned nodes moved (a source displaced
        and held), Newton above the dense size starts from the linear elastic response to
        that displacement when it lowers the energy (:func:`~.newton._pin_predictor`).
    method : {"newton", "fire", "lbfgs", "paper"}
        ``newton``: sparse Newton with exact clamps (default). ``fire`` and ``lbfgs``:
        first-order minimisers, exact clamps through an augmented Lagrangian. ``paper``: the
        seed paper's PyTorch Adagrad (learning rate 0.1) with rod clamps; it stalls and is
        kept as a baseline.
    tol : float
        Relative tolerance, judged locally. With ``F = grad E + A^T mu`` the net force on
        the free coordinates (clamp-normal components removed; a rod's axial force counts
        as one), the state is an equilibrium when for every free coordinate ``(i, c)`` of
        every node ``i`` ``|F_ic| <= tol * f_i`` with ``f_i = sum_j k_j L_j`` over the
        springs at node ``i`` (rods and clamps excluded; ``mean(k) mean(L)`` where that sum
        is 0), and every exact clamp ``c`` has ``|r_c - l_c| <= tol * L_c`` (``L_c`` the
        clamped spring's rest length); a rod is held to the length at which its own force
        balances the clamp tension, ``|r_c - l_c - mu_c / k_rod| <= tol * L_c``. The
        tensions ``mu`` are fitted to all clamps at once by least squares over the free
        coordinates *in the judged units*: they minimise ``sum_ic (F_ic / f_i)^2`` (``A``
        the clamps' length gradient restricted to the free coordinates), so the stiff end
        of a clamp does not set the balance judged at its soft end. ``relative_residual``
        is ``max_ic |F_ic| / f_i`` at these ``mu``: never below the least that any tensions
        give, and at most ``sqrt(n_free)`` times it (0.14 % above it on
        ``tests/data/relax_case_9.npz``, where a fit to the absolute forces reports 76x
        more although tensions meeting ``tol`` exist). Every method uses this rule.
    clamp : {"exact", "rod"}
        Exact equality constraints, or the paper's stiff rods of ``rod_stiffness``.
        ``method="paper"`` always uses rods.
    ramp : int
        Strain continuation: approach the clamp lengths in ``ramp`` equal steps from the
        starting lengths, each relaxed in turn. At large strains the energy has several
        local minima and the one found depends on this path.
    max_iter, max_seconds : budgets; exceeding either raises :class:`EquilibriumError`
        (Newton's default of 2000 iterations is a safety net, not a working limit:
        ``docs/solver-notes.md#equilibrium``).
        ``max_iter`` bounds each solve (a ramp stage, an escape, a solve with pins chosen
        anew), so the reported iterations, their sum, can exceed it; ``max_seconds`` bounds
        the whole call.
    sparse_solver : {"auto", "pardiso", "superlu"}
        The sparse factorisation of every solve (:data:`~..linalg.spd.SPARSE_SOLVERS`;
        "auto": PARDISO when ``pypardiso`` imports, else SuperLU or the banded Cholesky).

    A converged state is also checked to second order: a saddle (the reduced Hessian of
    the Lagrangian, scaled by node stiffness, with an eigenvalue below ``-max(1e-8,
    tol)``: a loose ``tol`` leaves curvature within it unresolved) or a state with a
    collapsed spring (``k > 0``, length ``<= 1e-9 L``) is escaped (a step along the lowest
    eigenvector, or the collapsed springs unfolded) and relaxed again, at most three
    times, else :class:`EquilibriumError`. Networks whose rigidity matrix is
    rank deficient at a generic configuration (a dangling node, a hinge) are refused with a
    ``ValueError`` even when Maxwell's count passes.

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
    method, tol, ramp, max_iter, max_seconds, rod_stiffness = (
        args.method, args.tol, args.ramp, args.max_iter, args.max_seconds, args.rod_stiffness
    )  # fmt: skip
    if method == "paper":
        clamp = "rod"
    problem = Problem.build(
        net, pinned=pinned, clamped=clamped, clamp=clamp, rod_stiffness=rod_stiffness,
        sparse_solver=sparse_solver,
    )  # fmt: skip
    refuse_floppy(problem)
    stop = problem.stop_rule(
        tol, max_iter=int(max_iter or _DEFAULT_MAX_ITER[method]), max_seconds=max_seconds
    )
    x = _start(problem, x0)
    refuse_unreachable_clamps(problem, x)
    collapsed = collapsed_springs(problem, x)
    if collapsed.size:  # coincident nodes: no force direction, unfolded before any solve
        x = unfold(problem, x, collapsed, 0)
    trace = Trace()
    solve = METHODS[method]
    start_lengths = net.lengths(x, problem.clamp_springs) if problem.n_clamps else None
    iterations = 0
    outcome = Outcome(x, 0, True)
    reaction = None  # the pins' reaction at outcome.x, when known
    known = None  # (problem, x, its Residual): computed once, reused by _finish
    # Default pins only remove rigid motion. The dense trust-region Newton removes it
    # itself when nothing is pinned (a pin pair whose lever shortens in a large deformation
    # leaves a nearly free rotation that it would otherwise creep along); other solves run
    # in the pins' lever frame (placement.lever_frame: a shrinking network cannot turn
    # the pins into a strut). Either result is then placed rigidly on the default pins.
    floating = pinned is None and method == "newton" and problem.free.size <= TR_DENSE_MAX
    solved, frame = problem, None
    if floating:
        solved = problem.with_free(np.ones_like(problem.free))
    elif pinned is None and (turned := lever_frame(problem, x)) is not None:
        solved, frame = turned
        outcome = Outcome(frame.into(x), 0, True)
    for step in range(1, int(ramp) + 1):
        frac = step / ramp
        lengths = start_lengths + frac * (problem.clamp_lengths - start_lengths)
        stage = solved.with_clamp_lengths(lengths) if problem.n_clamps else solved
        trace.base = iterations
        outcome = solve(stage, outcome.x, stop, trace)
        iterations += outcome.iterations
        if not outcome.converged:
            break
    checked = None  # an outcome already judged to second order (placed rigidly since)
    if solved is not problem:  # second order judged in the solve's frame, then placed
        outcome, extra = second_order(solved, outcome, solve, stop, trace, iterations)
        iterations += extra
        back = frame.back(outcome.x) if frame is not None else outcome.x
        if np.isfinite(back).all():
            back = place_on_pins(back, x, problem.free)
        outcome = replace(outcome, x=back)
        if outcome.converged:
            outcome = checked = replace(outcome, certified=True)
            placed, reaction = residual_and_reaction(problem, outcome.x)
            known = (problem, outcome.x, placed)
            if not stop.met(placed.imbalance, placed.clamp):  # turned: round-off, polish
                trace.base = iterations
                outcome = replace(solve(problem, outcome.x, stop, trace), certified=True)
                iterations += outcome.iterations
                reaction = None
    # Default pins only remove rigid motion, so they must carry no load. After a large
    # deformation two of them can line up and act as a strut: choose them anew at the
    # deformed positions and relax again from there. Pins with a lever carry what the free
    # coordinates' residual forces add up to (their net force and torque): on a network
    # of thousands of nodes, each within tol, that can exceed tol (see
    # docs/solver-notes.md#equilibrium). From the second re-pinning on (from the first
    # where the pins chosen anew are the same), each solve therefore goes as far below the
    # residual reached as the reaction was above tol.
    target = stop.tol  # the tolerance of the last solve
    named = False  # the outcome's message already names the pins' load
    for rounds in range(_PIN_ROUNDS + 1):
        if pinned is not None or not outcome.converged:
            break
        if reaction is None or outcome is not checked:
            found, reaction = residual_and_reaction(problem, outcome.x)
            known = (problem, outcome.x, found)  # _finish's residual, if x stays
        if reaction <= stop.tol:
            break
        if rounds == _PIN_ROUNDS:
            outcome = replace(outcome, converged=False, message=pins_loaded(reaction, rounds))
            named = True
            break
        free = ~default_pins(net.with_positions(outcome.x), problem.clamp_springs)
        if rounds or np.array_equal(free, problem.free):
            # below the residual the state has, not only the tolerance it met: a target
            # above it takes no step, and the pins' load would stay
            reached = known[2].imbalance
            target = min(target, reached) * max(0.5 * stop.tol / reaction, _PIN_TIGHTEST)
        problem = problem.with_free(free)
        trace.base = iterations
        outcome = solve(problem, outcome.x, replace(stop, tol=target), trace)
        iterations += outcome.iterations
        if not outcome.converged and target < stop.tol:
            why = f"; the solve to tol {target:.1e} from there stopped: {outcome.message}"
            outcome = replace(outcome, message=pins_loaded(reaction, rounds + 1) + why)
            named = True
    extra = 0
    if outcome is not checked:  # a placed outcome has the lengths just judged
        outcome, extra = second_order(problem, outcome, solve, stop, trace, iterations)
    res = known[2] if known and known[0] is problem and known[1] is outcome.x else None
    name_load = pinned is None and not named  # _finish names a load the pins still carry
    return _finish(problem, outcome, iterations + extra, method, stop, trace, res, name_load)


def _start(problem: Problem, x0: ArrayLike | None) -> NDArray:
    if x0 is None:
        return problem.net.positions.copy()
    return check.float_array("x0", x0, (problem.net.n_nodes, 2))


def _finish(
    problem: Problem,
    outcome: Outcome,
    iterations: int,
    method: str,
    stop: StopRule,
    trace: Trace,
    res: Residual | None = None,
    name_pin_load: bool = False,
) -> Equilibrium:
    """The :class:`Equilibrium` of ``outcome`` (``res``: its residual, when known;
    ``name_pin_load``: the pins are relax's default ones, which must carry no load, and a
    failure's reason should name a load they carry)."""
    x, net = outcome.x, problem.net
    finite = bool(np.isfinite(x).all())
    if finite:
        res = problem.residual(x) if res is None else res
        residual, relative, mu = res.force, res.imbalance, res.multipliers
        violation = problem.clamp_violation(x)
        clamp_error = float(np.max(np.abs(violation))) if violation.size else 0.0
        clamp_relative = res.clamp
        energy = spring_energy(x, net.springs, net.stiffness, net.rest_length)
    else:
        residual = relative = clamp_error = clamp_relative = energy = np.inf
        mu = np.full(problem.n_clamps, np.inf)
    converged = finite and outcome.converged and stop.met(relative, clamp_relative)
    x = x.copy()
    x.setflags(write=False)
    state = Equilibrium(
        positions=x,
        energy=energy,
        residual=residual,
        relative_residual=relative,
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
        roundoff = False  # the state is an equilibrium as far as float64 can tell
        reason = outcome.message or "did not reach the requested residual"
        if not finite:
            reason = "iterate became non-finite; " + reason
        elif (dependent := dependent_clamps(problem, x)).size:  # the cause, named first
            reason += (
                f"; the clamps on springs {dependent.tolist()} are degenerate here: their "
                "directions are linearly dependent, so no finite clamp tensions balance "
                "the forces across them (e.g. clamped springs in a straight line between "
                "pinned nodes, their lengths adding up to the distance); rods "
                "(clamp='rod') stretch instead"
            )
        elif clamp_relative > 1e-3 and "cannot all be met" not in reason:
            # exact clamps that no chain forbids passed refuse_unreachable_clamps: only the
            # plane can forbid them; rods stretch, and are not checked there
            why = (
                "no chain of clamps or pins forbids them, so either the solve has not got "
                "there or they cannot all be met in the plane"
                if problem.clamp == "exact"
                else "they may not all be reachable together, or with the pins (e.g. rods "
                "between pinned nodes whose lengths add up to less than the pins' distance)"
            )
            reason += (
                f"; the clamps are far from their lengths (relative error {clamp_relative:.1e}): "
                + why
            )
        elif outcome.stalled and stop.tol < relative <= 10.0 * (
            floor := roundoff_floor(problem, x)
        ):  # 10x: the solver's own iterates carry several rounding units
            roundoff = True
            reason += (
                f"; tol is below float64's reach at this state: moving every coordinate by "
                f"one rounding unit changes the relative residual by up to {floor:.1e}"
            )
        elif (
            relative
            <= stop.tol
            < clamp_relative
            <= 10.0 * (floor := clamp_roundoff_floor(problem, x))
        ):
            roundoff = True
            reason += (
                f"; tol is below float64's reach for the clamp lengths at this state: "
                f"moving every coordinate (up to {float(np.max(np.abs(x))):.1e}) by one "
                f"rounding unit changes the relative clamp error by up to {floor:.1e} (the "
                f"clamped rest lengths are down to {float(np.min(stop.clamp_scale)):.1e})"
            )
        if finite and (collapsed := collapsed_springs(problem, x)).size:
            reason += "; " + collapse_note(collapsed)
        if (
            finite
            and name_pin_load
            and (load := pin_reaction(problem, x)) > max(relative, stop.tol)
        ):
            reason += (
                f"; the default pins (which should only remove rigid motion) hold a net force "
                f"of {load:.1e} x their nodes' sum k L: the network is loaded through them"
            )
        raise EquilibriumError(
            f"{method}: {reason} (wanted every net force <= {stop.tol:.1e} of its node's "
            f"sum k L, got {relative:.3e}; relative clamp error {clamp_relative:.3e})",
            state,
            roundoff=roundoff,
        )
    return state
