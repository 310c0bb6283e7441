"""Stability scenes: stiff and extreme cases against every equilibrium method."""

from __future__ import annotations

import math

import numpy as np

from ..document import (
    Document,
    fmt,
)
from ..figures import heatmap


# -- stability -----------------------------------------------------------------------------
def section(doc: Document, result) -> None:
    """Every stiff and extreme case against every method: converged, residual, time."""
    from ...scenes.units_solvers import case_name, cases

    scene = result.scene
    methods = scene.solver.methods
    doc.add(
        f"A {scene.network.size} x {scene.network.size} triangular lattice (position noise) "
        "with one spring clamped: `stiff_r` has a random "
        f"{scene.network.stiff_fraction:g} of the springs r times stiffer (a soft spring "
        f"clamped at strain {scene.task.strain:g}); `rod_k` clamps with the paper's rod of "
        "stiffness k; `strain_s` clamps exactly at the extreme strain s. Tolerance "
        f"{scene.solver.tol:g} (relative to mean(k) mean(L)), budget "
        f"{scene.solver.max_seconds:g} s per solve. Residuals are relative to the force "
        "scale, clamp errors to the mean rest length. For `stiff_r` the force scale "
        "grows with r, so the same relative tolerance is a looser absolute one."
    )
    rows, names, values, text = [], [], [], []
    for kind, value in cases(scene):
        name = case_name(kind, value)
        names.append(name)
        vrow, trow = [], []
        for method in methods:
            m = result.units[f"stability/{name}/{method}"].meta
            rows.append(
                [
                    name,
                    method,
                    "yes" if m["converged"] else "no",
                    fmt(m["residual"]),
                    fmt(m["clamp_error"]),
                    fmt(m["seconds"]),
                    m["iterations"],
                    m["error"][:120] or "",
                ]
            )
            r = m["residual"]
            vrow.append(
                math.log10(r) if np.isfinite(r) and r > 0 else (-16.0 if r == 0 else np.nan)
            )
            trow.append(("ok " if m["converged"] else "FAIL ") + fmt(m["seconds"], 2) + " s")
        values.append(vrow)
        text.append(trow)
    path = heatmap(
        values,
        names,
        list(methods),
        doc.folder / "fig_stability.png",
        text=text,
        title="residual / force scale (log10); converged and time",
        colorbar="log10 residual / F",
        dpi=doc.dpi,
    )
    doc.image(
        path,
        "Every stiff and extreme case against every method: colour is the final "
        "residual, text says whether the tolerance was met and how long it took.",
    )
    doc.table(
        [
            "case",
            "method",
            "converged",
            "residual / F",
            "clamp error / L",
            "seconds",
            "iterations",
            "error raised",
        ],
        rows,
    )
