"""Transmission scenes: how strain travels from a clamped spring, network and continuum."""

from __future__ import annotations

import numpy as np

from ...scenes.results import from_stored
from ...scenes.results.physics import TransmissionResult
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
    runs = [from_stored(u, TransmissionResult) for u in result.select("transmission/").values()]
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
    for r in runs:
        row = [r.n, r.n_nodes, _exponent(r, "network"), fmt(r.network_seconds)]
        floor = 1e-9 * float(np.max(np.abs(r.network_strain)))
        series = [
            Series(
                r.distance,
                above(np.abs(r.network_strain), floor),
                "network",
                style="",
                marker=".",
                alpha=0.5,
            )
        ]
        if cont:
            row += [
                _exponent(r, "continuum"),
                fmt(r.correlation, 4),
                fmt(r.continuum_seconds),
            ]
            series.append(
                Series(
                    r.distance,
                    above(np.abs(r.continuum_strain), floor),
                    "continuum",
                    style="",
                    marker=".",
                    alpha=0.5,
                )
            )
        series += _binned(r.distance, np.abs(r.network_strain), floor)
        if np.isfinite(r.network_exponent):  # the r^-2 guide only where a decay is fitted
            d = np.linspace(1.0, float(np.max(r.distance)), 50)
            ref = np.nanmedian(np.abs(r.network_strain)[np.abs(r.distance - 2) < 0.6])
            series.append(Series(d, ref * (d / 2.0) ** -2, "r^-2", style="--", color="0.3"))
        panels.append(
            Panel(
                series,
                f"n = {r.n} (N = {r.n_nodes})",
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
        f"{medium} n = {r.n}: {_against_two(*fit)}"
        for r in runs
        for medium in ("network", "continuum")
        if (fit := r.exponent(medium)) is not None and np.isfinite(fit[0])
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
        last = runs[-1]
        doc.figure(
            "transmission_scatter",
            [
                Panel(
                    [
                        Series(
                            last.network_strain,
                            last.continuum_strain,
                            "springs",
                            style="",
                            marker=".",
                            alpha=0.5,
                        )
                    ],
                    f"n = {last.n}: every spring",
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


def _exponent(run: TransmissionResult, medium: str) -> str:
    """``"2.01 +- 0.03"``: a medium's decay exponent and its standard error."""
    value, error = run.exponent(medium)
    return f"{fmt(value)} +- {fmt(error)}" if np.isfinite(error) else fmt(value)


def _against_two(exponent: float, error: float) -> str:
    """A decay exponent against 2 by the two-standard-error rule."""
    from ...fits import PowerLaw, against

    return against(PowerLaw(exponent, error, 1.0, 0, 0.0), 2.0)
