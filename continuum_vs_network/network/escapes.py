"""The second-order check of :func:`~.equilibrium.relax`: no saddle and no collapsed
spring is returned as an equilibrium (:func:`second_order`), and zero-length springs,
which have no force direction, are unfolded (:func:`unfold`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .checks import collapse_note, collapsed_springs, escape_direction, lowest_curvature
from .constraints import Problem
from .stopping import Outcome, StopRule, Trace

__all__ = ["DEFAULT_TOL", "Method", "second_order", "unfold"]

# f(problem, x, stop, trace): x (n_nodes, 2) may have its clamped springs off their lengths;
# each method sets them (Problem.start, Newton after its linear predictor)
Method = Callable[[Problem, NDArray, StopRule, Trace], Outcome]
DEFAULT_TOL = 1e-10  # relax's tol; also where the second-order check relaxes loose ones
_ESCAPES = 3
_CURVATURE_TOL = 1e-8  # smallest scaled reduced-Hessian eigenvalue accepted as >= 0


def second_order(
    problem: Problem, outcome: Outcome, solve: Method, stop: StopRule, trace: Trace, done: int
) -> tuple[Outcome, int]:
    """No saddle and no collapsed spring returned as an equilibrium: escape, or fail.

    A converged state with a spring of ``k > 0`` collapsed to (almost) zero length is
    unfolded (each collapsed spring's second node moved by 1e-3 of its rest length in a
    direction turned by the golden angle at each escape) and relaxed again; one whose scaled
    reduced Hessian has an eigenvalue ``lowest`` below ``-max(1e-8, tol)`` is moved by 1 %
    of the mean rest length along that eigenvector (the side of lower energy) and relaxed
    again, to a tol of at most ``-lowest / 10`` (at a loose tol, 1e-2, the moved state
    already met it, and every escape stopped where it started), and from the second escape
    on to at most the default 1e-10 (a Delaunay mesh escaped to ever more negative
    curvature: -0.05, -0.1, -0.16). Problems too large for eigenvectors, indefinite at a
    loose tol, are relaxed on to 1e-10 (the sparse factorisation then certifies them). A
    tighter solve that stops short of its own tol where the asked one is met (round-off, far
    from the origin) is judged again there. After three escapes the outcome is a failure.
    Returns the outcome and the iterations spent.
    """
    extra = 0
    asked = stop
    for escapes in range(_ESCAPES):
        if not outcome.converged:
            return outcome, extra
        x = outcome.x
        collapsed = collapsed_springs(problem, x)
        if collapsed.size:
            # a new direction at each escape: the first (the x axis for the first spring)
            # may lie on a line of symmetry that relaxing never leaves (a clamped triangle
            # started collinear, collapsed by its clamp, unfolded along its own line)
            y = unfold(problem, x, collapsed, escapes)
            left = collapse_note(collapsed)
        elif outcome.certified:
            return outcome, extra
        else:
            threshold = max(_CURVATURE_TOL, stop.tol)
            lowest = lowest_curvature(problem, x, threshold)
            if lowest is not None and lowest >= -threshold:
                return outcome, extra
            direction = escape_direction(problem, x)
            if direction is None and stop.tol > DEFAULT_TOL:
                # too large for eigenvectors, and indefinite at a loose tol: far from any
                # equilibrium, not necessarily at a saddle; relaxed on to the default tol
                stop = replace(stop, tol=DEFAULT_TOL)
                y = x
                left = "a point where the reduced Hessian is indefinite at tol"
            elif direction is None:
                return Outcome(
                    x, outcome.iterations, False, "saddle: the reduced Hessian is indefinite"
                ), extra
            else:
                assert lowest is not None  # dense: the eigenvalue came with its vector
                trials = [problem.start(x + s * 1e-2 * direction) for s in (1.0, -1.0)]
                y = min(trials, key=problem.energy)
                # relaxed until the curvature shows (a loose tol met by the moved state
                # would stop there)
                tighter = 0.1 * -lowest if escapes == 0 else DEFAULT_TOL
                stop = replace(stop, tol=min(stop.tol, tighter))
                left = f"a saddle (scaled reduced-Hessian eigenvalue {lowest:.1e})"
        trace.base = done + extra
        outcome = solve(problem, y, stop, trace)
        extra += outcome.iterations
        if not outcome.converged and stop.tol < asked.tol:
            # the tighter solve stopped short of its own tol (at round-off: a network far
            # from the origin), perhaps where the asked one is met: judged again there
            found = problem.residual(outcome.x)
            if asked.met(found.imbalance, found.clamp):
                outcome = Outcome(outcome.x, outcome.iterations, True)
        if not outcome.converged:  # the cause first: the solve that failed was an escape's
            why = f"the solve reached {left}; escaping it, the solve from there: "
            outcome = replace(outcome, message=why + outcome.message)
    if outcome.converged:
        reason = "a saddle or a collapsed spring persists after 3 escapes"
        return Outcome(outcome.x, outcome.iterations, False, reason), extra
    return outcome, extra


def unfold(problem: Problem, x: NDArray, collapsed: NDArray, turn: int) -> NDArray:
    """``x`` (n_nodes, 2) with each ``collapsed`` spring's second node (its first where the
    second is pinned) moved by 1e-3 of its rest length: a zero-length spring has no force
    direction. The i-th moves across the first other spring of nonzero length at its node
    (along the x axis where there is none), turned by ``i + turn`` golden angles: a
    collapse on a line of springs (a clamped triangle started collinear) is left off that
    line, which relaxing would not leave, in any frame."""
    y = np.array(x, dtype=np.float64, copy=True)
    net, free = problem.net, problem.free
    a, b = net.springs[collapsed].T
    moved = np.where(free[b].any(axis=1), b, a)
    # each node's first spring of nonzero length, in spring order: row r of ``ends`` is
    # spring r % s seen from node ends[r, 0] (one sort, not a search per collapsed spring)
    s = net.n_springs
    ends = np.concatenate([net.springs, net.springs[:, ::-1]])
    away = x[ends[:, 1]] - x[ends[:, 0]]
    rows = np.flatnonzero(np.hypot(away[:, 0], away[:, 1]) > 1e-9 * np.tile(net.rest_length, 2))
    rows = rows[np.argsort(ends[rows, 0] * s + rows % s, kind="stable")]
    nodes, first = np.unique(ends[rows, 0], return_index=True)
    across = np.full(net.n_nodes, -1)
    across[nodes] = rows[first]
    pick = across[moved]
    base = np.where(pick >= 0, np.arctan2(away[pick, 1], away[pick, 0]) + 0.5 * np.pi, 0.0)
    angle = base + 2.399963229728653 * (np.arange(collapsed.size) + turn)
    move = 1e-3 * net.rest_length[collapsed, None]
    move = move * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    np.add.at(y, b, move * free[b])
    np.add.at(y, a, -move * (free[a] & ~free[b]))
    return y
