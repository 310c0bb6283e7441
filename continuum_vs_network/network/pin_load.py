"""The load on :func:`~.equilibrium.relax`'s default pins, which must carry none.

Default pins only remove rigid motion; where they hold a net force (two of them lined up
as a strut after a large deformation, or the free nodes' residual forces adding up),
``relax`` chooses them anew and solves further (``docs/solver-notes.md#equilibrium``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem, Residual
from .energy import spring_gradient

__all__ = ["pin_reaction", "pins_loaded", "residual_and_reaction"]


def pins_loaded(reaction: float, rounds: int) -> str:
    """The reason given when the default pins still carry load after ``rounds`` re-pinnings."""
    return (
        f"the default pins carry a net force of {reaction:.1e} of their nodes' sum k L "
        f"after {rounds} re-pinnings (they should only remove rigid motion): the free "
        "nodes' residual forces add up to it"
    )


def residual_and_reaction(problem: Problem, x: NDArray) -> tuple[Residual, float]:
    """``problem.residual(x)`` and :func:`pin_reaction` at ``x`` from one spring gradient
    (the clamp tensions are fitted on each coordinate set, free and all, as those do)."""
    net = problem.net
    grad = spring_gradient(x, net.springs, net.stiffness, net.rest_length).ravel()
    free, pinned = problem.free_flat, np.flatnonzero(~problem.free.ravel())
    if problem.n_clamps:
        res = problem.residual(x, force=problem.unbalanced_force(x, free, grad=grad))
        if not pinned.size:
            return res, 0.0
        every = np.arange(grad.size)
        force = problem.unbalanced_force(x, every, grad=grad)[0]
        return res, pin_reaction(problem, x, force)
    force = np.abs(grad)
    relative = force / problem.scale  # the same numbers Problem.residual and pin_reaction use
    res = Residual(
        float(np.max(relative[free])) if free.size else 0.0,
        float(np.max(force[free])) if free.size else 0.0,
        0.0,
        np.empty(0),
    )
    return res, float(np.max(relative[pinned])) if pinned.size else 0.0


def pin_reaction(problem: Problem, x: NDArray, force: NDArray | None = None) -> float:
    """Largest force the pins exert on the network at ``x``, clamp forces removed,
    relative to the pinned coordinates' local force scale (``force``: the unbalanced
    force on every coordinate, when known)."""
    pinned = np.flatnonzero(~problem.free.ravel())
    if not pinned.size:
        return 0.0
    if force is None:
        force, _ = problem.unbalanced_force(x, np.arange(problem.free.size))
    return float(np.max(np.abs(force[pinned]) / problem.scale[pinned]))
