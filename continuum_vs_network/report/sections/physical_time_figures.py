"""Figures of a physical_time scene (:mod:`.physical_time`)."""

from __future__ import annotations

import numpy as np

from ..document import Document
from ..figures import COLORS, Panel, Series

__all__ = ["bracket_closed", "figures", "first_draws"]

#: Relative errors above this are not drawn (a diverging run reaches 1e290 and beyond).
ERROR_CAP = 1e6


def first_draws(units: list) -> list:
    """The first draw of every size."""
    return [u for u in units if u.meta.get("draw", 0) == 0]


def bracket_closed(m) -> bool:
    """Whether a run unit's critical ratio is bracketed on both sides."""
    return m.get("critical_low", 0) > 0 and np.isfinite(m.get("critical_high", np.inf))


def figures(doc: Document, rules: dict, tasks: list, ratios: np.ndarray, names: dict) -> None:
    """Learning time against the ratio, error against time at the largest size, the
    critical ratio and the relaxation time against size (``names``: rule key -> label)."""
    panels = []
    for name, units in rules.items():
        series = []
        for j, u in enumerate(first_draws(units)):
            m = u.meta
            T = np.array([r["T"] for r in m["runs"]]) / m["tau"]
            Tq = np.array([r["T_qs"] for r in m["runs"]]) / m["tau"]
            c = COLORS[j % len(COLORS)]
            series.append(Series(ratios, T, f"N={m['n_nodes']}", marker="o", color=c))
            series.append(
                Series(ratios, Tq, f"N={m['n_nodes']}, quasi-static", style="--", color=c)
            )
        panels.append(
            Panel(series, names[name], "rho = alpha k tau", "T / tau", xscale="log", yscale="log")
        )
    doc.figure(
        "physical_time_speed",
        panels,
        "Learning time (in relaxation times) against the ratio of learning rate to relaxation "
        "rate, the first task draw of each size; dashed: the quasi-static limit of the same "
        "run. Points missing: the level was not reached.",
    )
    panels = []
    for name, units in rules.items():
        u = first_draws(units)[-1]
        series = []
        for i, ratio in enumerate(ratios):
            a = u.arrays
            c = COLORS[i % len(COLORS)]
            t = a[f"r{i}/times"] / u.meta["tau"]
            e = np.asarray(a[f"r{i}/error"], float)
            e = np.where(e <= ERROR_CAP, e, np.nan)  # diverging runs: drawn up to the cap
            series.append(Series(t, e, f"rho={ratio:g}", color=c))
            tq = a[f"r{i}/times_qs"] / u.meta["tau"]
            series.append(Series(tq, a[f"r{i}/error_qs"], "", style=":", color=c))
        panels.append(
            Panel(
                series,
                f"{names[name]}, N={u.meta['n_nodes']}",
                "t / tau",
                "error / initial",
                xscale="log",
                yscale="log",
            )
        )
    doc.figure(
        "physical_time_error",
        panels,
        "Error against time (in relaxation times) at the largest size (first task draw) for "
        f"every ratio; dotted: the quasi-static limit; errors above {ERROR_CAP:g} times the "
        "initial one (runs diverging without a failed step) are not drawn.",
    )
    panels = []
    for medium in ("network", "continuum"):
        series = []
        for j, (name, units) in enumerate(rules.items()):
            if units[0].meta.get("medium", "network") != medium:
                continue
            c = COLORS[j % len(COLORS)]
            ok = [u.meta for u in units if bracket_closed(u.meta)]
            sizes = sorted({m["n_nodes"] for m in ok})
            per = [[m for m in ok if m["n_nodes"] == n] for n in sizes]
            series.append(
                Series(
                    sizes,
                    [np.median([m["critical_ratio"] for m in p]) for p in per],
                    names[name],
                    lo=[min(m["critical_low"] for m in p) for p in per],
                    hi=[max(m["critical_high"] for m in p) for p in per],
                    marker="s",
                    color=c,
                )
            )
            series.append(
                Series(
                    [m["n_nodes"] for m in ok],
                    [m["critical_ratio"] for m in ok],
                    "",
                    style="",
                    marker=".",
                    color=c,
                )
            )
        if series:
            panels.append(
                Panel(
                    series,
                    f"critical ratio, {medium}",
                    "N (nodes)",
                    "rho*",
                    xscale="log",
                    yscale="log",
                )
            )
    if panels:
        doc.figure(
            "physical_time_critical",
            panels,
            "Critical ratio against size: dots, every task draw (the bracket's geometric mean); "
            "squares and line, the median over draws; band, from the smallest bracket low to "
            "the largest bracket high over draws (grid ratios "
            f"{', '.join(f'{r:g}' for r in ratios)}, bisected inside the bracket; brackets "
            "open on one side are not drawn).",
        )
    series = []
    for j, medium in enumerate(("network", "continuum")):
        have = [u for u in tasks if medium in u.meta]
        if not have:
            continue
        c = COLORS[j % len(COLORS)]
        sizes = sorted({u.meta["n_nodes"] for u in have})
        series.append(
            Series(
                sizes,
                [
                    np.median([u.meta[medium]["tau"] for u in have if u.meta["n_nodes"] == n])
                    for n in sizes
                ],
                f"{medium} tau (median)",
                marker="s",
                color=c,
            )
        )
        series.append(
            Series(
                [u.meta["n_nodes"] for u in have],
                [u.meta[medium]["tau"] for u in have],
                "",
                style="",
                marker=".",
                color=c,
            )
        )
    if series:
        doc.figure(
            "physical_time_tau",
            [Panel(series, "relaxation time", "N (nodes)", "tau", xscale="log", yscale="log")],
            "Relaxation time tau (target strains' 1 % settling time) against size: dots, every "
            "task draw; squares and line, the median over draws.",
        )
