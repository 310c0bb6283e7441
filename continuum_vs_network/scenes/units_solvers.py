"""Units of stability and solver scenes: one equilibrium method on one problem each.

These units are timed, so they always run one at a time in the main process (never in
parallel workers), after a warm-up solve of every method (the paper's method imports
torch on first use).

Stability (``stability/<case>/<method>``), on an ``n x n`` lattice (``[network] size``)
with the spring nearest the centre clamped:

* ``stiff_<r>``: a random ``stiff_fraction`` of the springs ``r`` times stiffer; the soft
  spring nearest the centre clamped at ``[task] strain``;
* ``rod_<k>``: the paper's clamp rod of stiffness ``k`` at ``[task] strain``;
* ``strain_<s>``: an exact clamp at the extreme strain ``s`` (``[solver] ramp``
  continuation steps).

Each records converged, residual, clamp error, time and iterations, or the error raised.

Solvers (``solvers/n<n>/<method>``): the centre spring of an ``n x n`` lattice clamped at
``[task] strain``, solved to ``[solver] tol`` within ``max_seconds``; the residual at every
recorded iteration, that iteration's number and the wall-clock time it was reached
(``Equilibrium.residual_trace``, ``iteration_trace``, ``seconds_trace``), for error
against iterations and against run time.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .schema import Scene
from .units import Unit, UnitContext
from .units_physics import centre_spring, lattice

__all__ = ["cases", "plan_solvers"]

_WARM: set[str] = set()


def cases(scene: Scene) -> list[tuple[str, float]]:
    """Stability cases ``(kind, value)``: stiffness ratios, rod stiffnesses, strains."""
    out = [("stiff", float(r)) for r in scene.network.stiffness_ratios]
    out += [("rod", float(k)) for k in scene.solver.rod_stiffnesses]
    if scene.task is not None:
        out += [("strain", float(s)) for s in scene.task.strains]
    return out


def case_name(kind: str, value: float) -> str:
    return f"{kind}_{value:g}"


def plan_solvers(scene: Scene) -> list[Unit]:
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "solver") if k in d}
    units = []
    if scene.kind == "stability":
        for kind, value in cases(scene):
            for method in scene.solver.methods:
                units.append(
                    Unit(
                        key=f"stability/{case_name(kind, value)}/{method}",
                        func=stability_unit,
                        params={"case": kind, "value": value, "method": method},
                        depends=depends,
                        parallel=False,
                    )
                )
    else:
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


def _warm_up(method: str) -> None:
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


def _stability_problem(scene: Scene, kind: str, value: float):
    net = lattice(scene, scene.network.size, default_noise=0.1)
    options: dict[str, Any] = {}
    strain = scene.task.strain
    if kind == "stiff":
        rng = np.random.default_rng([scene.seed, 1])
        stiff = rng.random(net.n_springs) < scene.network.stiff_fraction
        net = net.with_stiffness(np.where(stiff, value, 1.0))
        x = net.positions
        mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
        dist = np.where(stiff, np.inf, np.hypot(*(mid - x.mean(axis=0)).T))
        spring = int(np.argmin(dist))
    else:
        spring = centre_spring(net)
        if kind == "rod":
            options.update(clamp="rod", rod_stiffness=value)
        else:
            strain = value
            options.update(ramp=scene.solver.ramp)
    return net, {spring: float(net.clamp_length(spring, strain))}, options


def stability_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One method on one stiff or extreme case; the error raised is recorded, not raised."""
    from ..network.equilibrium import EquilibriumError, relax

    method = params["method"]
    _warm_up(method)
    net, clamped, options = _stability_problem(scene, params["case"], params["value"])
    s = scene.solver
    meta: dict[str, Any] = {
        "case": params["case"],
        "value": params["value"],
        "method": method,
        "n_nodes": net.n_nodes,
        "force_scale": net.force_scale,
        "error": "",
    }
    try:
        eq = relax(
            net, clamped=clamped, method=method, tol=s.tol, max_seconds=s.max_seconds, **options
        )
    except EquilibriumError as err:
        eq = err.state
        meta["error"] = f"EquilibriumError: {err.reason}"
    except Exception as err:  # a stability table reports every failure
        meta["error"] = f"{type(err).__name__}: {err}"
        meta.update(
            converged=False,
            residual=float("nan"),
            clamp_error=float("nan"),
            seconds=float("nan"),
            iterations=0,
        )
        return {}, meta
    meta.update(
        converged=bool(eq.converged),
        residual=eq.residual / net.force_scale,
        clamp_error=eq.clamp_error / float(np.mean(net.rest_length)),
        seconds=eq.seconds,
        iterations=int(eq.iterations),
    )
    return {}, meta


def solver_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Residual against iterations and wall-clock time of one method at one size."""
    from ..network.equilibrium import EquilibriumError, relax

    method = params["method"]
    _warm_up(method)
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
    F = net.force_scale
    arrays = {
        "residual": np.asarray(eq.residual_trace) / F,
        "seconds": np.asarray(eq.seconds_trace),
        "iteration": np.asarray(eq.iteration_trace),
    }
    meta = {
        "n": params["n"],
        "method": method,
        "n_nodes": net.n_nodes,
        "n_springs": net.n_springs,
        "converged": bool(eq.converged),
        "residual": eq.residual / F,
        "iterations": int(eq.iterations),
        "seconds": eq.seconds,
        "error": error,
    }
    return arrays, meta
