"""Units of solver scenes: one equilibrium method on one lattice size each.

These units are timed, so they always run one at a time in the main process (never in
parallel workers), after a warm-up solve of every method (the paper's method imports
torch on first use).

Solvers (``solvers/n<n>/<method>``): the centre spring of an ``n x n`` lattice clamped at
``[task] strain``, solved to ``[solver] tol`` within ``max_seconds``; the residual at every
recorded iteration, that iteration's number and the wall-clock time it was reached
(``Equilibrium.residual_trace``, ``iteration_trace``, ``seconds_trace``), for error
against iterations and against run time. Stability scenes are in :mod:`.units_stability`.
"""

from __future__ import annotations

import numpy as np

from .results.solvers import SolverResult
from .schema import Scene
from .timing import single_threaded
from .units import Unit, UnitContext
from .units_physics import centre_spring, lattice

__all__ = ["plan_solvers", "warm_up"]

_WARM: set[str] = set()


def plan_solvers(scene: Scene) -> list[Unit]:
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "solver") if k in d}
    units = []
    for n in scene.network.sizes:
        for method in scene.solver.methods:
            units.append(
                Unit(
                    key=f"solvers/n{n}/{method}",
                    func=solver_unit,
                    params={"n": int(n), "method": method},
                    depends={**depends, "records": "iteration"},
                    parallel=False,
                )
            )
    return units


def warm_up(method: str) -> None:
    """One tiny solve, so that imports and first-call costs are not timed."""
    if method in _WARM:
        return
    from ..network.builders import triangular_lattice
    from ..network.equilibrium import EquilibriumError, relax

    net = triangular_lattice(3, 3)
    try:
        relax(net, clamped={0: 1.05 * float(net.rest_length[0])}, method=method, max_seconds=2.0)
    except EquilibriumError:
        pass
    _WARM.add(method)


@single_threaded
def solver_unit(scene: Scene, params: dict, ctx: UnitContext) -> SolverResult:
    """Residual against iterations and wall-clock time of one method at one size."""
    from ..network.equilibrium import EquilibriumError, relax

    method = params["method"]
    warm_up(method)
    net = lattice(scene, params["n"], default_noise=0.0)
    src = centre_spring(net)
    s = scene.solver
    error = ""
    try:
        eq = relax(
            net,
            clamped={src: float(net.clamp_length(src, scene.task.strain))},
            method=method,
            tol=s.tol,
            max_seconds=s.max_seconds,
        )
    except EquilibriumError as err:
        eq = err.state
        error = err.reason
    return SolverResult(
        n=params["n"],
        method=method,
        n_nodes=net.n_nodes,
        n_springs=net.n_springs,
        converged=bool(eq.converged),
        residual=eq.relative_residual,
        iterations=int(eq.iterations),
        seconds=eq.seconds,
        error=error,
        residual_trace=np.asarray(eq.residual_trace),
        seconds_trace=np.asarray(eq.seconds_trace),
        iteration_trace=np.asarray(eq.iteration_trace),
    )
