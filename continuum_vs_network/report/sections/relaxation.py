"""Relaxation scenes: relaxation time against size, network and continuum."""

from __future__ import annotations

import numpy as np

from ...fits import against, power_law
from ...scenes.results import from_stored
from ...scenes.results.physics import RelaxationResult
from ..document import (
    Document,
    fmt,
)
from ..figures import COLORS, Panel, Series
from .renders import side_by_side


# -- relaxation ----------------------------------------------------------------------------
def section(doc: Document, result) -> None:
    """Relaxation times against size, the decay of the displacement; renders."""
    scene = result.scene
    dyn = scene.dynamics
    cont = scene.continuum is not None
    runs = [from_stored(u, RelaxationResult) for u in result.select("relaxation/").values()]
    doc.add(
        f"The left side of an n x n triangular lattice (k = 1, unit node masses "
        f"{'with' if dyn.inertia else 'without'} inertia, node drag c = {dyn.damping:g}) is "
        f"held and the right side stepped inwards by {dyn.step:g} of the width; the "
        f"relaxation time is when the displacement to the final state stays below "
        f"{dyn.fraction:g} of its start. The slowest-mode time is 1 / (smallest decay "
        "rate) of the linearised equations."
        + (
            " The continuum has the node drag smeared over the area per node "
            f"(P{scene.continuum.order}, {scene.continuum.refine} refinement(s), "
            f"{scene.continuum.material} material)."
            if cont
            else ""
        )
    )
    n = np.array([r.n for r in runs], dtype=float)
    rows = []
    for r in runs:
        row = [r.n, r.n_nodes, fmt(r.network_tau_mode), fmt(r.network_tau), fmt(r.network_seconds)]
        if cont:
            row += [
                fmt(r.continuum_tau_mode),
                fmt(r.continuum_tau),
                fmt(r.continuum_seconds),
                r.continuum_dofs,
            ]
        rows.append(row)
    headers = ["n", "N", "network slowest-mode time", "network relaxation time", "network s"]
    if cont:
        headers += [
            "continuum slowest-mode time",
            "continuum relaxation time",
            "continuum s",
            "continuum DOFs",
        ]
    doc.table(headers, rows)
    series = []
    fits = []
    names = [
        ("network_tau_mode", "network, slowest mode", "-"),
        ("network_tau", "network, measured", ""),
    ]
    if cont:
        names += [
            ("continuum_tau_mode", "continuum, slowest mode", "--"),
            ("continuum_tau", "continuum, measured", ""),
        ]
    for j, (k, label, style) in enumerate(names):
        t = np.array([getattr(r, k) for r in runs], dtype=float)
        ok = np.isfinite(t) & (t > 0)
        if ok.sum() >= 2:
            fit = power_law(n[ok], t[ok])
            fits.append(f"{label}: {fit.describe('tau', 'n')}; exponent {against(fit, 2.0)}")
            label = f"{label} (n^{fit.exponent:.2f})"
        series.append(
            Series(
                n, t, label, style=style or "", marker="o" if not style else "s", color=COLORS[j]
            )
        )
    curves = []
    for j, r in enumerate(runs):
        d = r.network_deviation
        curves.append(Series(r.network_times, d / d[0], f"network n={r.n}", color=COLORS[j % 10]))
        if cont:
            c = r.continuum_deviation
            curves.append(
                Series(
                    r.continuum_times,
                    c / c[0],
                    f"continuum n={r.n}",
                    style="--",
                    color=COLORS[j % 10],
                )
            )
    # model units: spacing 1, k = 1, drag c; unit node masses when inertial
    unit = "units of sqrt(m / k)" if dyn.inertia else f"units of c / k, c = {dyn.damping:g}"
    unit = unit if not dyn.inertia else unit + f", c = {dyn.damping:g}"
    doc.figure(
        "relaxation",
        [
            Panel(
                series,
                "relaxation time against size",
                "n (lattice side)",
                f"time ({unit})",
                xscale="log",
                yscale="log",
            ),
            Panel(
                curves,
                "displacement to the final state",
                f"time ({unit})",
                "max |u(t) - u(end)| / start",
                yscale="log",
                hlines=(dyn.fraction,),
            ),
        ],
        "Left: relaxation times against the lattice side n (overdamped diffusion predicts "
        "n^2). Right: the relaxing displacement against time for every size.",
    )
    if fits:
        doc.add(
            "Fitted scaling (least squares on logarithms; +- the exponent's standard error, "
            "a trend only beyond two standard errors, and the exponent against overdamped "
            "diffusion's 2 by the same rule; the standard error is the fit's scatter only, "
            "so a finite-size drift of the exponent shows as a difference): "
            + " / ".join(fits)
            + "."
        )
    side_by_side(doc, result, "relaxation/", "relaxation")
