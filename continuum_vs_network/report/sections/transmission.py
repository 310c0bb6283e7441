"""Transmission scenes: how strain travels from a clamped spring, network and continuum."""

from __future__ import annotations

import numpy as np

from ..document import (
    Document,
    above,
    fmt,
)
from ..figures import Panel, Series
from .renders import side_by_side


# -- transmission --------------------------------------------------------------------------
def section(doc: Document, result) -> None:
    """Strain against distance, network and continuum; decay exponents; renders."""
    scene = result.scene
    units = result.select("transmission/")
    cont = scene.continuum is not None
    doc.add(
        f"The spring nearest the centre of an n x n triangular lattice (spacing 1, k = 1) "
        f"is clamped at strain {scene.task.strain:g}; every other spring's strain is read "
        "against its distance from the source"
        + (
            ", in the network and in the finite-element continuum of the same shape "
            f"(P{scene.continuum.order}, {scene.continuum.refine} refinement(s), "
            f"{scene.continuum.material} material, two rigid patches of radius "
            f"{scene.continuum.patch_radius:g} L moved apart)."
            if cont
            else "."
        )
    )
    rows = []
    panels = []
    for u in units.values():
        m, a = u.meta, u.arrays
        row = [m["n"], m["n_nodes"], _exponent(m, "network"), fmt(m["network_seconds"])]
        floor = 1e-9 * float(np.max(np.abs(a["network_strain"])))
        series = [
            Series(
                a["distance"],
                above(np.abs(a["network_strain"]), floor),
                "network",
                style="",
                marker=".",
                alpha=0.5,
            )
        ]
        if cont:
            row += [
                _exponent(m, "continuum"),
                fmt(m["correlation"], 4),
                fmt(m["continuum_seconds"]),
            ]
            series.append(
                Series(
                    a["distance"],
                    above(np.abs(a["continuum_strain"]), floor),
                    "continuum",
                    style="",
                    marker=".",
                    alpha=0.5,
                )
            )
        series += _binned(a["distance"], np.abs(a["network_strain"]), floor)
        if np.isfinite(m["network_exponent"]):  # the r^-2 guide only where a decay is fitted
            r = np.linspace(1.0, float(np.max(a["distance"])), 50)
            ref = np.nanmedian(np.abs(a["network_strain"])[np.abs(a["distance"] - 2) < 0.6])
            series.append(Series(r, ref * (r / 2.0) ** -2, "r^-2", style="--", color="0.3"))
        panels.append(
            Panel(
                series,
                f"n = {m['n']} (N = {m['n_nodes']})",
                "distance from the source",
                "|strain|",
                xscale="log",
                yscale="log",
            )
        )
        rows.append(row)
    headers = ["n", "N", "network decay exponent", "network s"]
    if cont:
        headers += ["continuum decay exponent", "correlation network/continuum", "continuum s"]
    doc.table(headers, rows)
    comparisons = [
        f"{medium} n = {m['n']}: {_against_two(m, medium)}"
        for m in (u.meta for u in units.values())
        for medium in ("network", "continuum")
        if f"{medium}_exponent" in m and np.isfinite(m[f"{medium}_exponent"])
    ]
    doc.add(
        "Strains below 1e-9 of the largest (round-off; springs that only rotate) are not "
        "drawn. Decay exponents are fitted to |strain| binned in distance between 2 "
        "spacings and 0.3 n (a force dipole in an infinite 2D body decays as r^-2), with "
        "the least-squares standard error over the bins (the scatter about the fit only, "
        "not the choice of bins or of the fitted range); '-' where the lattice is too small "
        "for a fit."
        + (
            " Against the infinite body's 2 (two-standard-error rule): "
            + "; ".join(comparisons)
            + "."
            if comparisons
            else ""
        ),
        "",
    )
    doc.figure(
        "transmission",
        panels,
        "Strain against distance from the source spring.",
        ncols=min(3, len(panels)),
    )
    if cont:
        last = list(units.values())[-1]
        a = last.arrays
        doc.figure(
            "transmission_scatter",
            [
                Panel(
                    [
                        Series(
                            a["network_strain"],
                            a["continuum_strain"],
                            "springs",
                            style="",
                            marker=".",
                            alpha=0.5,
                        )
                    ],
                    f"n = {last.meta['n']}: every spring",
                    "network strain",
                    "continuum chord strain",
                    diagonal=True,
                )
            ],
            "Network against continuum strain of every spring (largest lattice).",
            ncols=1,
        )
    side_by_side(doc, result, "transmission/", "transmission")


def _binned(distance, strain, floor: float) -> list[Series]:
    """The network's median |strain| in logarithmic distance bins (>= 3 springs a bin)."""
    d = np.asarray(distance, dtype=float)
    v = np.asarray(strain, dtype=float)
    ok = (d > 0) & (v > floor)
    if ok.sum() < 6:
        return []
    edges = np.logspace(np.log10(d[ok].min()), np.log10(d[ok].max()), 12)
    which = np.digitize(d[ok], edges)
    xs, ys = [], []
    for b in np.unique(which):
        sel = which == b
        if sel.sum() >= 3:
            xs.append(float(np.median(d[ok][sel])))
            ys.append(float(np.median(v[ok][sel])))
    return [Series(np.array(xs), np.array(ys), "network, binned median", color="black")]


def _exponent(meta: dict, medium: str) -> str:
    """``"2.01 +- 0.03"``: a medium's decay exponent and its standard error."""
    value = fmt(meta[f"{medium}_exponent"])
    error = meta.get(f"{medium}_exponent_error", float("nan"))
    return f"{value} +- {fmt(error)}" if np.isfinite(error) else value


def _against_two(meta: dict, medium: str) -> str:
    """A medium's decay exponent against 2 by the two-standard-error rule."""
    from ...fits import PowerLaw, against

    error = meta.get(f"{medium}_exponent_error", float("nan"))
    return against(PowerLaw(meta[f"{medium}_exponent"], error, 1.0, 0, 0.0), 2.0)
