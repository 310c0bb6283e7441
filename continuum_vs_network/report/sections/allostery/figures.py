"""Figures of the ``allostery`` section (:mod:`.`), drawn from stored units: the
feasibility map, C/C0 against steps and seconds, the source sweeps, and a render of one
trained network coloured by its learned change of stiffness.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ....learning.coupling import MET_AT
from ....scenes.units_allostery import SCALES
from ...figures import COLORS, Panel, Series, _pyplot, _save
from .data import RULE_NAMES, Group

__all__ = ["curve_panels", "map_panel", "render", "sweep_panels"]


def map_panel(fmap: dict, scene, title: str) -> Panel:
    """Share of draws the optimum solves against the (median measured) source-target
    distance, one line per response ratio."""
    a = scene.allostery
    series = [
        Series(
            fmap["distance"][:, j],
            fmap["share"][:, j],
            f"|S_T/S_S| = {q:g}",
            marker="o",
            color=COLORS[j % len(COLORS)],
        )
        for j, q in enumerate(a.map_ratios)
    ]
    return Panel(
        series,
        title,
        "source-target distance (box sizes)",
        "share feasible (optimum C/C0 <= 1e-3)",
    )


def _curve(u, x_key: str) -> tuple[np.ndarray, np.ndarray]:
    """C/C0 of a run against its steps (``x_key`` "steps") or a trace of it."""
    e = np.asarray(u.error, dtype=float)
    x = np.arange(e.size, dtype=float) if x_key == "steps" else np.asarray(getattr(u, x_key))
    return x, e / e[0]


def _median_curve(curves: list[tuple[np.ndarray, np.ndarray]], steps: bool):
    """Median C/C0 over draws at each step; against seconds, at each draw's median time."""
    n = min(c[1].size for c in curves)
    y = np.nanmedian(np.stack([c[1][:n] for c in curves]), axis=0)
    x = np.nanmedian(np.stack([c[0][:n] for c in curves]), axis=0)
    return (np.arange(n, dtype=float) if steps else x), y


def curve_panels(group: Group, rules, opt_ratio: float) -> list[Panel]:
    """C/C0 against steps (first row) and against the rule's own seconds (second row): one
    thin line per feasible draw and rule, the median bold, the optimum's median dashed."""
    panels = []
    for x_key, label in (("steps", "learning step"), ("rule_seconds_trace", "wall-clock time (s)")):
        series, xmax, xmin = [], 1.0, np.inf
        for r, rule in enumerate(rules):
            color = COLORS[r % len(COLORS)]
            curves = [
                _curve(u, x_key)
                for u, ok in zip(group.train[rule], group.feasible, strict=True)
                if ok
            ]
            for x, y in curves:
                series.append(Series(x, y, color=color, width=0.6, alpha=0.35))
                fin = x[np.isfinite(x) & (x > 0)]
                if fin.size:
                    xmax, xmin = max(xmax, fin.max()), min(xmin, fin.min())
            if curves:
                x, y = _median_curve(curves, x_key == "steps")
                series.append(Series(x, y, RULE_NAMES[rule], color=color, width=2.2))
        xmin = 1.0 if not np.isfinite(xmin) else xmin
        series.append(
            Series(
                [xmin, xmax],
                [opt_ratio] * 2,
                "optimum (median)",
                style="--",
                color="0.2",
                width=1.2,
            )
        )
        panels.append(
            Panel(
                series,
                f"C/C0 against {label.split(' (')[0]}",
                label,
                "C / C0",
                xscale="log",
                yscale="log",
                hlines=(MET_AT,),
            )
        )
    return panels


def _normalised(sweep, rest, desired) -> np.ndarray:
    """``(S_T(lambda) - rest) / (desired - rest)`` of the first target, (n_scales,)."""
    s = np.asarray(sweep, dtype=float)[:, 0]
    return (s - rest[0]) / (desired[0] - rest[0])


def sweep_panels(group: Group, rules) -> list[Panel]:
    """Target response against the source scale lambda, one panel per rule: the trained
    networks of the feasible draws (colour) and the untrained ones (grey); a learned target
    runs from 0 at lambda = 0 to 1 at lambda = 1 (the diagonal)."""
    lam = np.asarray(SCALES)
    panels = []
    for r, rule in enumerate(rules):
        series: list[Series] = []
        for u, o, ok in zip(group.train[rule], group.opt, group.feasible, strict=True):
            if not ok:
                continue
            rest, desired = np.asarray(o.rest), np.asarray(o.desired)
            first = not series
            series.append(
                Series(
                    lam,
                    _normalised(o.sweep0, rest, desired),
                    "untrained" if first else "",
                    color="0.6",
                    width=0.8,
                    marker=".",
                )
            )
            series.append(
                Series(
                    lam,
                    _normalised(u.sweep, rest, desired),
                    "trained" if first else "",
                    color=COLORS[r % len(COLORS)],
                    width=1.2,
                    marker="o",
                )
            )
        panels.append(
            Panel(
                series,
                f"{RULE_NAMES[rule]}: source sweep",
                "source scale lambda (S_S / task S_S)",
                "(S_T - S_T rest) / (desired - rest)",
                diagonal=True,
            )
        )
    return panels


def render(unit, path: Path, title: str, dpi: int) -> Path:
    """The trained network of ``unit`` as lines coloured by log10(k / k0) (diverging map
    centred at 0), sources (green) and targets (black) drawn thick."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import TwoSlopeNorm

    plt = _pyplot()
    pos, springs = np.asarray(unit.positions), np.asarray(unit.springs)
    change = np.log10(np.asarray(unit.k, dtype=float) / np.asarray(unit.k0, dtype=float))
    lim = max(float(np.max(np.abs(change))), 1e-6)
    segs = pos[springs]
    fig, ax = plt.subplots(figsize=(5.6, 4.8), layout="constrained")
    try:
        lc = LineCollection(segs, cmap="RdBu_r", norm=TwoSlopeNorm(0.0, -lim, lim), lw=1.3)
        lc.set_array(change)
        ax.add_collection(lc)
        for idx, color, label in (
            (unit.sources, "tab:green", "source"),
            (unit.targets, "black", "target"),
        ):
            ax.add_collection(
                LineCollection(segs[np.asarray(idx)], colors=color, lw=4.0, label=label)
            )
        ax.autoscale()
        ax.set_aspect("equal")
        cb = fig.colorbar(lc, ax=ax, shrink=0.85)
        cb.set_label("learned change log10(k / k0)", fontsize=8)
        ax.set_xlabel("x (small-disc diameters)", fontsize=9)
        ax.set_ylabel("y (small-disc diameters)", fontsize=9)
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, frameon=False, loc="upper right")
        return _save(fig, path, dpi)
    finally:
        plt.close(fig)
