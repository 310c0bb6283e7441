"""Solver scenes: every equilibrium method's residual against iterations and seconds."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ...scenes.results import from_stored
from ...scenes.results.solvers import SolverResult
from ..document import (
    Document,
    fmt,
)
from ..figures import COLORS, Panel, Series


# -- solvers -----------------------------------------------------------------------------------
def time_to(residual: NDArray, seconds: NDArray, tol: float) -> float:
    """Seconds at which the best residual so far first reaches ``tol`` (NaN: never)."""
    best = np.minimum.accumulate(residual)
    hit = np.flatnonzero(best <= tol)
    return float(seconds[hit[0]]) if hit.size else math.nan


def section(doc: Document, result) -> None:
    """Residual against iterations and seconds, work-precision, the table."""
    scene = result.scene
    methods = scene.solver.methods
    sizes = scene.network.sizes
    doc.add(
        f"The spring nearest the centre of an n x n triangular lattice clamped at strain "
        f"{scene.task.strain:g}, solved by every method to a relative residual of "
        f"{scene.solver.tol:g} within {scene.solver.max_seconds:g} s. The relative residual "
        "is the quantity `relax`'s tolerance bounds (its stop rule, the same for every "
        "method; see `cvn.relax`). Every method records it at its iterations (Newton every "
        "one, the others every tenth), with the iteration number and the wall-clock time it "
        "was reached (a warm-up solve first, so imports are not timed; one BLAS thread, "
        "as in every timed unit)."
    )
    runs = {
        (n, method): from_stored(result.units[f"solvers/n{n}/{method}"], SolverResult)
        for n in sizes
        for method in methods
    }
    rows = []
    it_panels, t_panels = [], []
    for n in sizes:
        it_s, t_s = [], []
        for j, method in enumerate(methods):
            r = runs[n, method]
            # the solver's own iteration count of each record
            it_s.append(Series(r.iteration_trace, r.residual_trace, method, color=COLORS[j]))
            t_s.append(Series(r.seconds_trace, r.residual_trace, method, color=COLORS[j]))
            rows.append(
                [
                    n,
                    r.n_nodes,
                    method,
                    "yes" if r.converged else "no",
                    r.iterations,
                    fmt(r.seconds),
                    fmt(r.residual),
                    r.error[:100],
                ]
            )
        N = runs[n, methods[0]].n_nodes
        it_panels.append(
            Panel(
                it_s,
                f"N = {N}: residual vs iterations",
                "iteration",
                "relative residual",
                xscale="log",
                yscale="log",
                hlines=(scene.solver.tol,),
            )
        )
        t_panels.append(
            Panel(
                t_s,
                f"N = {N}: residual vs wall-clock time",
                "seconds",
                "relative residual",
                xscale="log",
                yscale="log",
                hlines=(scene.solver.tol,),
            )
        )
    ncols = min(3, len(sizes))
    doc.figure(
        "solvers_iterations",
        it_panels,
        "Residual against the solver's iteration number, every method and size (dotted: "
        "the tolerance; FIRE, L-BFGS and Adagrad record every tenth iteration and the last; "
        "the starting residual, iteration 0, is off the log axis).",
        ncols=ncols,
    )
    doc.figure("solvers_seconds", t_panels, "Residual against wall-clock seconds.", ncols=ncols)
    tols = np.logspace(-2, math.log10(scene.solver.tol), 9)
    wp, scale, reached = [], [], {}
    n_last = sizes[-1]
    nodes = [runs[n, methods[0]].n_nodes for n in sizes]
    for j, method in enumerate(methods):
        last = runs[n_last, method]
        times = [time_to(last.residual_trace, last.seconds_trace, t) for t in tols]
        wp.append(Series(times, tols, method, marker="o", color=COLORS[j]))
        reach = []
        for n in sizes:
            r = runs[n, method]
            reach.append(time_to(r.residual_trace, r.seconds_trace, scene.solver.tol))
        scale.append(Series(nodes, reach, method, marker="o", color=COLORS[j]))
        reached[method] = reach
    doc.figure(
        "work_precision",
        [
            Panel(
                wp,
                f"work-precision, N = {nodes[-1]}",
                "seconds to reach the residual",
                "relative residual reached",
                xscale="log",
                yscale="log",
            ),
            Panel(
                scale,
                f"time to reach {scene.solver.tol:g}",
                "N (nodes)",
                "seconds",
                xscale="log",
                yscale="log",
            ),
        ],
        "Work-precision: the wall-clock time each method needs for each residual (left, "
        "largest size; missing points were not reached within the budget) and the time to the "
        "tolerance against network size (right).",
    )
    doc.table(
        ["n", "N", "method", "converged", "iterations", "seconds", "relative residual", "message"],
        rows,
    )
    doc.summary(
        "time_to_tolerance",
        f"Seconds until the recorded relative residual first reaches {scene.solver.tol:g} "
        f"(one clamped spring at strain {scene.task.strain:g}; '-': not reached within "
        f"{scene.solver.max_seconds:g} s; a method stops later when its clamp error is not "
        "yet within tolerance: its stop time is in the section's table), every method "
        "measured in the same run",
        ["N", *methods],
        [[N, *(fmt(reached[m][i], 2) for m in methods)] for i, N in enumerate(nodes)],
    )
