"""Rows of a sweep's table: its columns, and one scene result reduced to rows.

:func:`point_rows` turns a learning scene's result into one row per learning run and trial,
:func:`allostery_rows` an allostery scene's into one per run and draw; :data:`COLUMNS` names
and explains the columns that follow the swept keys (:mod:`.sweep` writes the table).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["COLUMNS", "allostery_rows", "point_rows"]

#: Columns of the sweep table after the swept keys, with their meaning.
COLUMNS = {
    "point": "index of the grid point (first swept key slowest)",
    "solver": "equilibrium method of the learning run",
    "rule": "learning rule",
    "noise": "relative read-out noise of the learning run",
    "trial": "trial index within the point",
    "seed": "the trial's seed",
    "strain_reference": "strain convention of the task error (initial or current rest lengths)",
    "initial_error": "task error (Eq. 26, in strain_reference) of the initial network",
    "final_error": "task error after the last completed step",
    "relative_error": "final_error / initial_error",
    "steps_to_threshold": "first step with error <= threshold x initial error (empty: never)",
    "completed": "learning steps completed (fewer than asked: stopped, see stop_reason)",
    "stop_reason": "why the trial stopped early ('' when it did not)",
    "wall_seconds": "wall-clock seconds of the trial",
    "solves": "equilibrium solves of the trial",
    "iterations": "solver iterations of the trial",
    "factorisations": "Hessian factorisations of the trial",
    "max_residual": "largest free-state residual over the trial's measurements",
    "source_share": "part of the learned target change delivered by a changed response to "
    "the sources (learning.coupling; empty: not measured)",
    "coupling": "coupling verdict of the trained network: coupled, partially coupled, "
    "decoupled or not measured (learning.coupling)",
    "outcome": "relative_error and coupling together: learned (coupled), learned, partially "
    "coupled, met trivially (decoupled), not met or not measured (learning.coupling.outcome)",
}


def _finite(x: Any) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def allostery_rows(result, threshold: float) -> list[dict[str, Any]]:
    """Table rows of an allostery scene's result: one per run and draw (``trial`` = draw).

    ``relative_error`` is the run's final C/C0 (its rest example included); a draw whose
    bounded optimum shows it infeasible gets the outcome ``"infeasible"``.
    """
    from .results import from_stored
    from .results.allostery import AllosteryOptimumResult, AllosteryTrainResult
    from .units_allostery import runs

    scene = result.scene
    a = scene.allostery
    rows = []
    for n in a.n_nodes:
        for task in a.tasks:
            for dof in a.dofs:
                for i in range(a.draws):
                    base = f"n{n}/{task}/{dof}/draw{i}"
                    opt = result.units.get(f"allostery/opt/{base}")
                    feasible = (
                        None
                        if opt is None
                        else bool(from_stored(opt, AllosteryOptimumResult).feasible)
                    )
                    for run in runs(scene):
                        u = result.units[f"allostery/train/{base}/{run.name}"]
                        m = from_stored(u, AllosteryTrainResult)
                        r = np.asarray(m.error, dtype=float)
                        r = r / r[0] if r[0] > 0 else r * np.nan
                        below = np.flatnonzero(r[: m.completed + 1] <= threshold)
                        rows.append(
                            {
                                "solver": "newton",
                                "rule": run.name,
                                "noise": float(run.noise),
                                "trial": i,
                                "seed": int(scene.seed),
                                "strain_reference": "initial",
                                "initial_error": _finite(m.error[0]),
                                "final_error": _finite(m.error[m.completed]),
                                "relative_error": _finite(m.ratio),
                                "steps_to_threshold": int(below[0]) if below.size else None,
                                "completed": int(m.completed),
                                "stop_reason": m.stop_reason,
                                "wall_seconds": float(u.seconds),
                                "solves": None,
                                "iterations": None,
                                "factorisations": None,
                                "max_residual": None,
                                "source_share": _finite(m.share),
                                "coupling": m.coupling,
                                "outcome": "infeasible" if feasible is False else m.outcome,
                            }
                        )
    return rows


def point_rows(result, threshold: float) -> list[dict[str, Any]]:
    """Table rows of a learning scene's result: one per learning run and trial (an
    allostery scene's: :func:`allostery_rows`)."""
    from ..learning.coupling import outcome
    from .results import from_stored
    from .results.learning import CouplingResult

    scene = result.scene
    if scene.kind == "allostery":
        return allostery_rows(result, threshold)
    L = scene.learning
    rows = []
    for group, h in result.histories.items():
        stored = result.units.get(f"coupling/{group}")
        coupling = None if stored is None else from_stored(stored, CouplingResult)
        solver, rule, noise_key = group.split("/")
        noise = L.noise[int(noise_key[len("noise") :])]
        err = np.asarray(h.task_error(h.strain_reference), dtype=float)
        for k in range(h.trials):
            done = int(h.completed[k])
            first, last = err[k, 0], err[k, done]
            below = np.flatnonzero(err[k, : done + 1] <= threshold * first)
            stats = {
                name: (int(h.data[name][k, done]) if name in h.data else None)
                for name in ("solves", "iterations", "factorisations")
            }
            residual = h.data.get("residual")
            share, verdict = None, "not measured"
            if coupling is not None:
                share = _finite(coupling.share[k])
                verdict = coupling.verdicts[k]
            ratio = _finite(last / first) if first > 0 else None
            rows.append(
                {
                    "solver": solver,
                    "rule": rule,
                    "noise": float(noise),
                    "trial": k,
                    "seed": int(h.seeds[k]),
                    "strain_reference": h.strain_reference,
                    "initial_error": _finite(first),
                    "final_error": _finite(last),
                    "relative_error": ratio,
                    "steps_to_threshold": int(below[0]) if below.size and first > 0 else None,
                    "completed": done,
                    "stop_reason": h.stop_reason[k],
                    "wall_seconds": float(result.units[f"train/{group}/trial{k}"].seconds),
                    **stats,
                    "max_residual": (
                        _finite(np.nanmax(residual[k, : done + 1]))
                        if residual is not None and np.isfinite(residual[k, : done + 1]).any()
                        else None
                    ),
                    "source_share": share,
                    "coupling": verdict,
                    "outcome": outcome(ratio, None if verdict == "not measured" else verdict),
                }
            )
    return rows
