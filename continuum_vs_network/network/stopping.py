"""What every equilibrium method shares: the local stop rule, the trace and the outcome.

The stop rule judges equilibrium *locally* (the same definition for ``newton``, ``fire``,
``lbfgs``, ``paper`` and the learning tracker). For a free coordinate ``(i, c)`` of node
``i`` the imbalance is

    e_ic = |F_ic| / f_i,      f_i = sum over the springs j at node i of k_j L_j,

where ``F = grad E + A^T mu`` is the net force with the clamp-normal components removed
(``mu`` the clamp tensions minimising ``sum (F_ic / f_i)^2`` over the free coordinates, all
clamps at once; a rod's axial force is such a component too) and ``f_i`` is the force the
node's own springs exert at unit strain (network springs only:
rods and exact clamps are constraints, so the scale is the same in both clamp modes). A
node whose springs all have ``k = 0`` (held by a clamp alone) takes the network's mean
scale ``mean(k) mean(L)``. A clamp is met when ``|r_c - l_c| <= tol L_c`` with ``L_c`` the
rest length of the clamped spring. A state is an equilibrium when ``max e_ic <= tol`` and
every clamp is met: a soft region beside a stiff one balances to the same relative
accuracy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Outcome", "StopRule", "Trace", "coordinate_scale"]


def coordinate_scale(
    springs: NDArray, stiffness: NDArray, rest_length: NDArray, n_nodes: int
) -> NDArray[np.float64]:
    """Local force scale of every coordinate, (2 n_nodes,) float array (force units).

    ``f_i = sum_{j at i} k_j L_j`` repeated for the x and y coordinate of node ``i``
    (flat order ``x0, y0, x1, ...``); nodes with ``f_i = 0`` take ``mean(k) mean(L)``
    (1 when that is 0 too).
    """
    w = np.asarray(stiffness, float) * np.asarray(rest_length, float)
    f = np.bincount(springs[:, 0], w, n_nodes) + np.bincount(springs[:, 1], w, n_nodes)
    low = f <= 0
    if low.any():  # the fallback only where needed (np.mean costs more than the rest)
        fallback = float(np.mean(stiffness) * np.mean(rest_length)) if len(w) else 1.0
        f[low] = fallback if fallback > 0 else 1.0
    return np.repeat(f, 2)


@dataclass(frozen=True, eq=False)
class StopRule:
    """When a solver stops: the local relative tolerance and the budgets.

    Attributes
    ----------
    tol : float
        Relative tolerance (see the module docstring).
    scale : (2 n_nodes,) float array
        Force scale ``f_i`` of every flat coordinate (:func:`coordinate_scale`).
    clamp_scale : (m,) float array
        Length scale of every clamp (the clamped spring's rest length).
    max_iter : int
    max_seconds : float
    """

    tol: float
    scale: NDArray[np.float64]
    clamp_scale: NDArray[np.float64]
    max_iter: int
    max_seconds: float

    def imbalance(self, force: NDArray, coords: NDArray) -> float:
        """``max |force_k| / scale[coords_k]``: the largest relative imbalance (0 if empty)."""
        if not force.size:
            return 0.0
        return float(np.max(np.abs(force) / self.scale[coords]))

    def clamp_error(self, violation: NDArray) -> float:
        """``max |r_c - l_c| / L_c`` (0 without clamps)."""
        if not violation.size:
            return 0.0
        return float(np.max(np.abs(violation) / self.clamp_scale))

    def met(self, imbalance: float, clamp_error: float) -> bool:
        """Both relative measures at most ``tol``."""
        return imbalance <= self.tol and clamp_error <= self.tol


class Trace:
    """Residuals against wall-clock time and iteration, recorded by a solver as it iterates.

    ``residual`` holds the largest relative imbalance (:meth:`StopRule.imbalance`). A
    solver records ``record(residual, it)`` with its own iteration count ``it``; the caller
    that chains solves (stages, inner loops, escapes) sets ``base`` to the iterations done
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
class Outcome:
    """What a method returns to :func:`~.equilibrium.relax`.

    ``certified``: the method has already shown the reduced Hessian to be positive
    definite at the last iterates (a Newton step with an exact, positive-definite
    factorisation), so :func:`relax` skips its own second-order check. ``stalled``: it
    stopped because no step lowered its merit (not on a budget), so :func:`relax` asks
    whether rounding put ``tol`` out of reach.
    """

    x: NDArray[np.float64]
    iterations: int
    converged: bool
    message: str = ""
    certified: bool = False
    stalled: bool = False
