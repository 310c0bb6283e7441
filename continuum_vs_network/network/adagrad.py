"""The seed paper's equilibrium method, kept as an untuned baseline.

PyTorch Adagrad, learning rate 0.1, rod clamps of stiffness 1e10. It typically stalls far
from equilibrium because the rods make the problem extremely ill-conditioned. PyTorch is
imported only when the method runs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem
from .objective import RECORD_EVERY, Objective
from .stopping import Outcome, StopRule, Trace

__all__ = ["paper_adagrad"]

_PAPER_LR = 0.1


def paper_adagrad(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """The seed paper's equilibrium method: PyTorch Adagrad, learning rate 0.1, float64.

    Minimises the total energy with rod clamps (``problem.clamp == "rod"``; ``relax`` forces
    it for ``method="paper"``) over the free coordinates, one Adagrad step per iteration,
    until the stop rule, ``stop.max_iter`` or ``stop.max_seconds``. Kept untuned as a
    baseline: it stalls far from equilibrium on stiff (rod) problems.
    """
    import torch

    if problem.exact:
        raise ValueError("paper_adagrad needs rod clamps (problem.clamp == 'rod')")
    obj = Objective(problem)
    free = obj.free_flat
    x = problem.start(x)  # the rods set to their clamp lengths (a copy)
    springs = torch.tensor(obj.springs, dtype=torch.int64)
    a, b = springs[:, 0], springs[:, 1]
    k = torch.tensor(obj.k, dtype=torch.float64)
    L = torch.tensor(obj.L, dtype=torch.float64)
    base = torch.as_tensor(x.ravel().copy(), dtype=torch.float64)
    free_t = torch.as_tensor(free, dtype=torch.int64)
    p = torch.nn.Parameter(base[free_t].clone())
    opt = torch.optim.Adagrad([p], lr=_PAPER_LR)
    G = np.zeros_like(x)
    residual = np.inf
    for it in range(stop.max_iter + 1):
        opt.zero_grad()
        pos = base.index_put((free_t,), p).view(-1, 2)
        d = pos[b] - pos[a]
        r = torch.sqrt((d * d).sum(dim=1))
        energy = 0.5 * (k * (r - L) ** 2).sum()
        energy.backward()
        x.ravel()[free] = p.detach().numpy()
        G.ravel()[free] = p.grad.detach().numpy()
        residual, clamp_error = obj.check(x, G)
        final = True
        if not np.isfinite(residual):
            message, converged = "paper: forces became non-finite", False
        elif stop.met(residual, clamp_error):
            message, converged = "", True
        elif it == stop.max_iter:
            message = f"paper (Adagrad): no convergence in {stop.max_iter} iterations"
            converged = False
        elif trace.elapsed() > stop.max_seconds:
            message = f"paper (Adagrad): time budget of {stop.max_seconds:g} s exceeded"
            converged = False
        else:
            final = False
        if final or it % RECORD_EVERY == 0:
            trace.record(residual, it)
        if final:
            return Outcome(x, it, converged, message)
        opt.step()
    return Outcome(x, stop.max_iter, False, "paper (Adagrad): no convergence")
