"""FIRE (Bitzek et al., PRL 97, 170201, 2006) on the objective of :mod:`.objective`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem
from .objective import RECORD_EVERY, InnerResult, Objective, minimise
from .stopping import Outcome, StopRule, Trace

__all__ = ["fire"]

# FIRE parameters of Bitzek et al. (2006)
_N_MIN = 5
_F_INC = 1.1
_F_DEC = 0.5
_ALPHA_START = 0.1
_F_ALPHA = 0.99
_DT_FACTOR = 1.4  # dt_max = _DT_FACTOR / sqrt(Gershgorin bound); see _fire_dt_max


def _fire_dt_max(obj: Objective, x: NDArray) -> float:
    """FIRE's largest time step at ``x``: ``1.4 / sqrt(bound)`` (unit masses).

    The explicit (semi-implicit Euler) step is stable for ``dt < 2 / sqrt(lambda_max)``, and
    ``lambda_max`` is at most the Gershgorin ``bound`` of :meth:`Objective.hessian_bound`
    (``2 max_nodes sum_incident k`` for springs near their rest lengths, with augmented
    clamps adding ``rho`` to their spring). At ``2 / sqrt(bound)`` itself a stiff, localised
    mode (a clamp penalty, a rod), for which the bound is nearly tight, sits at the edge of
    stability: its undamped period-2 oscillation dominates the power ``F.V`` and FIRE resets
    every ~10 steps. The factor 1.4 (about sqrt 2) keeps it stable at little cost in speed
    (``docs/solver-notes.md#fire``). Rods of stiffness 1e10 enter the bound and make FIRE's
    steps tiny.
    """
    return _DT_FACTOR / np.sqrt(max(obj.hessian_bound(x), 1e-300))


@dataclass
class _FireStats:
    """Diagnostics of one FIRE run: velocity resets (``P = F.V <= 0``) and where the first was."""

    resets: int = 0
    first_reset_x: NDArray | None = None


def _fire_inner(
    obj: Objective,
    x: NDArray,
    tol: float,
    stop: StopRule,
    trace: Trace,
    budget: int,
    stats: _FireStats | None = None,
) -> InnerResult:
    """FIRE (Bitzek et al. 2006) with semi-implicit Euler steps and unit masses.

    Stops when the stop rule is met (``status="stop"``) or, for the augmented inner
    problem, when ``max |grad L| <= tol`` on free coordinates (``status="tol"``).

    The state is kept on all 2 n_nodes coordinates with the gradient zeroed on the pinned
    ones, so pinned velocities stay 0 and pinned positions never move: no gathers or
    scatters between free and full vectors. Each iteration reads the cheap part of the stop
    test (:meth:`Objective.rest_imbalance`, the imbalance on coordinates no clamp touches);
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
        record = it % RECORD_EVERY == 0
        if not math.isfinite(rest):
            trace.record(rest, it)
            return InnerResult(x, it, "failed", "FIRE: forces became non-finite")
        if rest <= threshold or record:
            residual, clamp_error = obj.check(x, G, rest)
            if stop.met(residual, clamp_error):
                trace.record(residual, it)
                return InnerResult(x, it, "stop")
            if obj.inner_met(G, tol, rest):
                trace.record(residual, it)
                return InnerResult(x, it, "tol")
            if record:
                trace.record(residual, it)
        if it == budget:
            break
        if trace.elapsed() > stop.max_seconds:
            residual = obj.check(x, G, rest)[0]
            trace.record(residual, it)
            return InnerResult(
                x, it, "budget", f"FIRE: time budget of {stop.max_seconds:g} s exceeded"
            )

        # F = -G: power P = F.V, mixing V <- (1 - alpha) V + alpha |V| F / |F|, then the
        # step V <- V + dt F, X <- X + dt V (mixing and kick fused: one pass over V)
        P = -float(G @ v)
        if P > 0.0:
            mix = alpha * math.sqrt(v @ v) / math.sqrt(G @ G)
            v *= 1.0 - alpha
            if n_pos > _N_MIN:
                dt = min(dt * _F_INC, dt_max)
                alpha *= _F_ALPHA
            n_pos += 1
        else:
            mix = 0.0
            if moving:  # uphill (or stopped): freeze, shrink the step, restart the mixing
                if stats is not None:
                    stats.resets += 1
                    if stats.first_reset_x is None:
                        stats.first_reset_x = x.copy()
                n_pos = 0
                dt *= _F_DEC
                alpha = _ALPHA_START
                v[:] = 0.0
        v -= np.multiply(G, mix + dt, out=step)
        flat += np.multiply(v, dt, out=step)
        moving = True
    residual = obj.check(x, G)[0]
    trace.record(residual, budget)
    return InnerResult(x, budget, "budget", f"FIRE: no convergence in {stop.max_iter} iterations")


def fire(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """FIRE minimisation of ``problem`` from ``x`` (n_nodes, 2).

    Standard parameters (Bitzek et al. 2006): ``dt_start = 0.1 dt_max``, ``N_min = 5``,
    ``f_inc = 1.1``, ``f_dec = 0.5``, ``alpha_start = 0.1``, ``f_alpha = 0.99``, power
    ``P = F . V``, unit masses; ``dt_max = 1.4 / sqrt(bound)`` from the Gershgorin bound on
    the Hessian's largest eigenvalue (``2 max_nodes sum_incident k``; see ``_fire_dt_max``).
    Exact clamps by the augmented Lagrangian of :mod:`.objective`.
    """
    return minimise(problem, x, stop, trace, _fire_inner)
