"""Studies on learning runs: source sweeps, the exact-gradient comparison, read-out noise,
equilibrium solvers compared.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ....scenes.results import from_stored
from ....scenes.results.learning import GradientResult, SweepsResult
from ...document import (
    Document,
    fmt,
    normalised,
    quiet,
    stats,
    summary_text,
)
from ...figures import COLORS, Panel, Series


def sweeps(doc: Document, result, solver: str) -> None:
    doc.heading("Source sweeps (Fig. 5 and appendix B)")
    doc.add(
        "The trained network's target strain for other source strains (blue) against the "
        "trivial, decoupled response that stays at the desired strain (orange); the "
        "black dot is the task: its source strain and the desired target strain (where a "
        "met task's curve passes)."
    )
    for rule in result.scene.learning.rules:
        sw = from_stored(result.units[f"sweeps/{solver}/{rule}"], SweepsResult)
        panels = []
        for i in range(sw.source_strain.shape[0]):
            s, t = sw.source_strain[i], sw.target_strain[i]
            panels.append(
                Panel(
                    [
                        Series(s, t, "network", marker="o"),
                        Series(s, np.full_like(s, sw.desired[i]), "decoupled", style="--"),
                        Series(
                            [sw.task_source[i]],
                            [sw.desired[i]],
                            "task",
                            style="",
                            marker="o",
                            color="black",
                        ),
                    ],
                    f"{rule}, trial {i}" + ("" if np.isfinite(t).any() else " (not solved)"),
                    "source strain",
                    "target strain",
                    legend=(i == 0),
                )
            )
        doc.figure(
            f"sweeps_{rule}",
            panels,
            f"Source sweeps of {rule} (every trial; Fig. 5 is trial 0).",
            ncols=5,
            panel_size=(2.8, 2.3),
        )


def gradient(doc: Document, result, h) -> None:
    doc.heading("Comparison with the exact gradient")
    doc.add(
        "Cosine between each rule's learning step and the exact gradient step "
        "(`ExactGradient`, the same springs learning, exact equilibria) at every trial's "
        "initial and final network; 1 means the local rule moves the rest lengths exactly "
        "downhill on the task error."
    )
    rows = []
    for u in result.select("gradient/").values():
        g = from_stored(u, GradientResult)
        c = g.cosine
        rows.append([g.rule, _cos_text(c[:, 0]), _cos_text(c[:, 1]), g.cost])
    doc.table(
        [
            "rule",
            "cos at the initial network: median [min, max]",
            "cos at the final network",
            "cost",
        ],
        rows,
    )
    if "exact" in result.scene.learning.rules:
        solver = (result.scene.solver.methods if result.scene.solver else ("newton",))[0]
        rows = [
            [
                r,
                summary_text(
                    h(solver, r).task_error(h(solver, r).strain_reference), h(solver, r).completed
                ),
            ]
            for r in result.scene.learning.rules
        ]
        doc.add(
            "Final `C/C0` of every rule next to `exact`, a fixed-step exact-gradient descent "
            "(`ExactGradient` at the scene's raw rate, the same steps): a rule at that rate, "
            "not the task's optimum (what the task allows is `exact_optimum`'s, reported by "
            "the allostery scene):",
            "",
        )
        doc.table(["rule", "final C/C0 median [quartiles]"], rows)


def _cos_text(c: NDArray) -> str:
    ok = c[np.isfinite(c)]
    if not ok.size:
        return "-"
    return f"{np.median(ok):.3f} [{ok.min():.3f}, {ok.max():.3f}]"


def noise(doc: Document, result, h, solver: str) -> None:
    from ....learning.metrics import final_values

    L = result.scene.learning
    doc.heading("Robustness to read-out noise")
    doc.add(
        "Every length a rule reads is `r (1 + noise xi)`, `xi ~ N(0, 1)`; the error is "
        "measured without noise."
    )
    series, rows = [], []
    levels = np.array(L.noise)
    positive = levels[levels > 0]
    x0 = positive.min() / 10 if positive.size else 1e-4
    xs = np.where(levels > 0, levels, x0)
    from ....scenes.units_learning import run_names

    for j, rule in enumerate(run_names(result.scene)):
        med, lo, hi, cells = [], [], [], []
        for i in range(len(L.noise)):
            hist = h(solver, rule, i)
            err = hist.task_error(hist.strain_reference)
            f = final_values(normalised(err), hist.completed)
            f = f[np.isfinite(f)]
            med.append(np.median(f) if f.size else np.nan)
            lo.append(np.quantile(f, 0.25) if f.size else np.nan)
            hi.append(np.quantile(f, 0.75) if f.size else np.nan)
            cells.append(summary_text(err, hist.completed))
        series.append(Series(xs, med, rule, lo, hi, marker="o", color=COLORS[j % 10]))
        rows.append([rule, *cells])
    doc.figure(
        "noise",
        [
            Panel(
                series,
                "final error against read-out noise",
                f"noise (0 drawn at {x0:g})",
                "final C / C0",
                xscale="log",
                yscale="log",
                hlines=(1.0,),
            )
        ],
        "Final normalised error (median, quartiles) against the read-out noise.",
        ncols=1,
    )
    doc.table(["rule", *[f"noise {n:g}" for n in L.noise]], rows)


def solver_comparison(doc: Document, result, h, solvers: Sequence[str]) -> None:
    from ....scenes.units_learning import run_names
    from .checks import EQUILIBRIUM_RESIDUAL, not_equilibria, residual_range

    doc.heading("Exact equilibria against the paper's relaxation")
    doc.add(
        "The same networks and tasks (same seeds), trained with each equilibrium solver. "
        "Free-state residual: the smallest and largest net force on a free coordinate of "
        "the stored free states over every step of every trial, and the largest as a "
        "fraction of the trial's force scale (the largest norm of the learning springs' "
        f"tensions |dE/dL|); states above {EQUILIBRIUM_RESIDUAL:g} of it are not equilibria."
    )
    rows, panels = [], []
    for rule in run_names(result.scene):
        cells = []
        step_s, time_s = [], []
        for j, solver in enumerate(solvers):
            hist = h(solver, rule)
            done = np.maximum(hist.completed, 1)
            last = np.array(
                [hist.seconds[i, min(hist.completed[i], hist.steps)] for i in range(hist.trials)]
            )
            err = hist.task_error(hist.strain_reference)
            lo, hi = residual_range(hist)
            rhi = residual_range(hist, relative=True)[1]
            cells += [
                summary_text(err, hist.completed),
                fmt(float(np.median(last / done))),
                f"{fmt(lo)} to {fmt(hi)}"
                + (f" (up to {fmt(rhi)} of the force scale)" if np.isfinite(rhi) else "")
                + (" (not equilibria)" if not_equilibria(hist) else ""),
            ]
            st = stats(normalised(err))
            style = "-" if j == 0 else "--"
            step_s.append(
                Series(
                    np.arange(hist.steps + 1),
                    st["median"],
                    solver,
                    st["q25"],
                    st["q75"],
                    style=style,
                    color=COLORS[j],
                )
            )
            time_s.append(
                Series(
                    quiet(np.nanmedian, hist.seconds, axis=0),
                    st["median"],
                    solver,
                    style=style,
                    color=COLORS[j],
                )
            )
        rows.append([rule, *cells])
        panels += [
            Panel(step_s, f"{rule}: vs step", "learning step", "C / C0", yscale="log"),
            Panel(time_s, f"{rule}: vs seconds", "seconds", "C / C0", xscale="log", yscale="log"),
        ]
    headers = ["rule"]
    for s in solvers:
        headers += [f"{s}: final C/C0", f"{s}: s/step", f"{s}: free-state residual"]
    doc.table(headers, rows)
    doc.figure(
        "solvers",
        panels,
        "Error against learning steps and wall-clock seconds with "
        "each equilibrium solver (median, quartiles).",
        ncols=2,
    )
