"""L-BFGS-B (scipy) on the objective of :mod:`.objective`."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem
from .objective import RECORD_EVERY, InnerResult, Objective, minimise
from .stopping import Outcome, StopRule, Trace

__all__ = ["lbfgs"]


def _one_blas_thread():
    """Pin BLAS to one thread (multithreaded OpenBLAS slows L-BFGS-B's tiny products)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


class _StopNow(Exception):
    pass


def _lbfgs_inner(
    obj: Objective, x: NDArray, tol: float, stop: StopRule, trace: Trace, budget: int
) -> InnerResult:
    """scipy's L-BFGS-B on the free coordinates, restarted when its line search stalls."""
    from scipy.optimize import minimize

    free = obj.free_flat
    x = x.copy()
    flat = x.ravel()
    cache: dict = {}
    done = {"iterations": 0, "status": "", "message": ""}

    def fun(y: NDArray) -> tuple[float, NDArray]:
        flat[free] = y
        e, G = obj.change_and_grad(x, ref)
        cache["y"], cache["G"] = y.copy(), G
        return e, G.ravel()[free]

    def test(y: NDArray, step: bool) -> None:
        if "y" not in cache or not np.array_equal(cache["y"], y):
            fun(y)
        flat[free] = y
        residual, clamp_error = obj.check(x, cache["G"])
        done["iterations"] += int(step)
        it = done["iterations"]
        final = False
        if not np.isfinite(residual):
            done.update(status="failed", message="L-BFGS: forces became non-finite")
            final = True
        elif stop.met(residual, clamp_error):
            done["status"] = "stop"
            final = True
        elif obj.inner_met(cache["G"], tol):
            done["status"] = "tol"
            final = True
        elif trace.elapsed() > stop.max_seconds:
            message = f"L-BFGS: time budget of {stop.max_seconds:g} s exceeded"
            done.update(status="budget", message=message)
            final = True
        elif it >= budget:
            message = f"L-BFGS: no convergence in {stop.max_iter} iterations"
            done.update(status="budget", message=message)
            final = True
        if final or not step or it % RECORD_EVERY == 0:
            trace.record(residual, it)
        if final:
            raise _StopNow

    def callback(intermediate_result) -> None:
        test(np.asarray(intermediate_result.x), True)

    y = flat[free].copy()
    ref = obj.reference(x)
    stalls = 0
    with _one_blas_thread():
        try:
            test(y, False)  # the starting point may already satisfy the stop rule
            while True:
                start_iterations = done["iterations"]
                flat[free] = y
                ref = obj.reference(x)  # energies are measured from the restart point
                res = minimize(
                    fun,
                    y,
                    jac=True,
                    method="L-BFGS-B",
                    callback=callback,
                    options={
                        "maxiter": max(budget - done["iterations"], 1),
                        "maxcor": 10,
                        "gtol": 0.0,
                        "ftol": 0.0,
                        "maxfun": 20 * budget + 100,
                    },
                )
                y = np.asarray(res.x)
                # scipy stopped by itself (line search at round-off): restart with fresh memory
                test(y, False)
                stalls = stalls + 1 if done["iterations"] - start_iterations <= 2 else 0
                if stalls >= 3:
                    why = str(res.message).rstrip(": ") or "no reason given"
                    message = (
                        "L-BFGS: stalled (scipy's L-BFGS-B stopped within 2 iterations of "
                        f"3 restarts in a row: {why}; no step lowered the energy)"
                    )
                    done.update(status="stalled", message=message)
                    raise _StopNow
        except _StopNow:
            pass
    return InnerResult(x, done["iterations"], done["status"], done["message"])


def lbfgs(problem: Problem, x: NDArray, stop: StopRule, trace: Trace) -> Outcome:
    """L-BFGS-B (scipy, memory 10) on the free coordinates of ``problem`` from ``x``.

    ``gtol`` and ``ftol`` are zero so that scipy never stops before the stop rule; our own
    test runs in the callback after every iteration. When scipy's line search stalls at
    round-off the method restarts with fresh memory, and reports failure after three
    restarts without progress. BLAS is pinned to one thread when ``threadpoolctl`` is
    installed. Exact clamps by the augmented Lagrangian of :mod:`.objective`.
    """
    return minimise(problem, x, stop, trace, _lbfgs_inner)
