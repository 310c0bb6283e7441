"""The runs of a physical_time scene (:mod:`.`) as the report reads and shows them: run units
per rule and task units from the stored units, the critical-ratio bracket of a run and the
rules' names; the summary table (median and range over draws per size, power-law fits over
all draws); the figures.
"""

from __future__ import annotations

import math

import numpy as np

from ....learning.coupling import COUPLED_AT, DECOUPLED_BELOW
from ....scenes.results import from_stored
from ....scenes.results.physical_time import MEDIA, TimeRunResult, TimeTaskResult
from ...document import Document, fmt
from ...figures import COLORS, Panel, Series

_NAMES = {
    "gcl": "GCL, twin networks",
    "gcl_phases": "GCL, free and nudged phases",
    "gpc": "GPC, continuous",
    "gcl/continuum": "GCL, twin continua",
    "gcl_phases/continuum": "GCL, phases, continuum",
    "gpc/continuum": "GPC, continuous, continuum",
}


def _runs(result) -> list[TimeRunResult]:
    """Every run unit of the scene, as :class:`TimeRunResult`."""
    return [
        from_stored(u, TimeRunResult)
        for key, u in result.select("physical_time/").items()
        if not key.endswith("/task")
    ]


def _not_learned(result) -> list[TimeRunResult]:
    """Run units of draws whose quasi-static reference did not learn (stiffness learning,
    :mod:`....scenes.units_time_reference`): no ratio was run."""
    return [u for u in _runs(result) if u.learned_qs is False]


def _by_rule(result) -> dict[str, list[TimeRunResult]]:
    """Run units per rule (``"gcl"``, ``"gcl/continuum"``, ...), by size then draw; units
    of draws not learned quasi-statically (:func:`_not_learned`) are left out."""
    out: dict[str, list[TimeRunResult]] = {}
    for u in _runs(result):
        if u.learned_qs is not False:
            out.setdefault(u.rule_key, []).append(u)
    for units in out.values():
        units.sort(key=lambda u: (u.n_nodes, u.draw))
    return out


def _tasks(result) -> list[TimeTaskResult]:
    """Task units (one per size and draw), by size then draw."""
    units = [
        from_stored(u, TimeTaskResult)
        for key, u in result.select("physical_time/").items()
        if key.endswith("/task")
    ]
    return sorted(units, key=lambda u: (u.n_nodes, u.draw))


def _bracket(m: TimeRunResult) -> str:
    """``"(lo, hi]"`` of a run unit's critical ratio."""
    lo, hi = m.critical_low, m.critical_high
    if not math.isfinite(hi):
        return f"> {fmt(lo)}"
    if lo == 0:
        return f"<= {fmt(hi)}"
    return f"({fmt(lo)}, {fmt(hi)}]"


def _spread(values) -> str:
    """``"median [min, max] (n)"``."""
    v = np.asarray(values, float)
    if v.size == 0:
        return "-"
    return f"{fmt(float(np.median(v)))} [{fmt(float(v.min()))}, {fmt(float(v.max()))}] ({v.size})"


def _summary(doc: Document, rules: dict, tasks: list) -> None:
    """Median and range over draws per size, and the fits over all draws."""
    media = [m for m in MEDIA if any(u.medium_times(m) is not None for u in tasks)]
    sizes = sorted({u.n_nodes for u in tasks})
    rows = []
    for medium in media:
        for key in ("tau", "tau_force"):
            rows.append(
                [f"{medium} {key}"]
                + [
                    _spread([u.medium_times(medium)[key] for u in tasks if u.n_nodes == n])
                    for n in sizes
                ]
            )
    for name, units in rules.items():
        rows.append(
            [f"rho*, {_NAMES[name]}"]
            + [
                _spread([u.critical_ratio for u in units if u.n_nodes == n and bracket_closed(u)])
                for n in sizes
            ]
        )
    for name, units in rules.items():
        rows.append(
            [f"source share, {_NAMES[name]}"]
            + [
                _spread(
                    [u.source_share for u in units if u.n_nodes == n and u.source_share is not None]
                )
                for n in sizes
            ]
        )
    doc.add(
        "Median [smallest, largest] (number of draws) per size; rho*: over the draws whose "
        "bracket is closed on both sides; source share: the coupling of the final learned "
        "state by the rule of `learning/coupling.py` (coupled from "
        f"{COUPLED_AT:g}, decoupled below {DECOUPLED_BELOW:g}; at the free state the run "
        "reads, a network's sources held by their lengths as rods), per draw the smallest over "
        "the ratios run:"
    )
    doc.table(["quantity"] + [f"N = {n}" for n in sizes], rows)
    parts = []
    for medium in media:
        N = [u.n_nodes for u in tasks]
        for key in ("tau", "tau_force"):
            t = [u.medium_times(medium)[key] for u in tasks]
            parts.append(f"{medium} {key}: {_fit(N, t, key)}")
    if parts:
        doc.add(
            "Relaxation times against N, least-squares fit of log tau on log N over every "
            f"size and draw ({len(tasks)} points; exponent +- its standard error). A trend "
            "('grows', 'falls') is claimed only when the exponent is more than two standard "
            "errors from 0 in the fit over every size and in each fit with one size left "
            "out in turn (`fits.robust_trend`), else 'no robust trend' with the range of the "
            "leave-one-size-out exponents: " + "; ".join(parts) + "."
        )
    fits = []
    for name, units in rules.items():
        ok = [u for u in units if bracket_closed(u)]
        open_ = [
            f"N = {u.n_nodes} draw {u.draw} ({_bracket(u)})" for u in units if not bracket_closed(u)
        ]
        left = f"; left out, bracket open: {', '.join(open_)}" if open_ else ""
        if len({m.n_nodes for m in ok}) >= 2:
            N = [m.n_nodes for m in ok]
            c = [m.critical_ratio for m in ok]
            fits.append(f"{_NAMES[name]} ({len(ok)} points{left}): {_fit(N, c, 'rho*')}")
        elif open_:
            fits.append(f"{_NAMES[name]}: fewer than two sizes with a closed bracket{left}")
    if fits:
        doc.add(
            "Critical ratio against N, least-squares fit of log rho* on log N over every "
            "size and draw with a bracket closed on both sides (same conventions): "
            + "; ".join(fits)
            + "."
        )


def _fit(n_nodes, values, quantity: str) -> str:
    """The power law of ``values`` against N and whether its trend survives leaving out each
    size (:func:`~continuum_vs_network.fits.robust_trend`)."""
    from ....fits import robust_trend

    try:
        return robust_trend(n_nodes, values).describe(quantity, "N")
    except ValueError:
        return f"{quantity}: one size only (no fit)"


__all__ = ["bracket_closed", "figures", "first_draws"]

#: Relative errors above this are not drawn (a diverging run reaches 1e290 and beyond).
ERROR_CAP = 1e6


def first_draws(units: list) -> list:
    """The first draw of every size."""
    return [u for u in units if u.draw == 0]


def bracket_closed(m: TimeRunResult) -> bool:
    """Whether a run unit's critical ratio is bracketed on both sides."""
    return m.bracket_closed()


def figures(doc: Document, rules: dict, tasks: list, ratios: np.ndarray, names: dict) -> None:
    """Learning time against the ratio, error against time at the largest size, the
    critical ratio and the relaxation time against size (``names``: rule key -> label)."""
    panels = []
    for name, units in rules.items():
        series = []
        for j, u in enumerate(first_draws(units)):
            m = u
            T = np.array([r["T"] for r in m.runs]) / m.tau
            Tq = np.array([r["T_qs"] for r in m.runs]) / m.tau
            c = COLORS[j % len(COLORS)]
            series.append(Series(ratios, T, f"N={m.n_nodes}", marker="o", color=c))
            series.append(Series(ratios, Tq, f"N={m.n_nodes}, quasi-static", style="--", color=c))
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
            a = u.curve(i)
            c = COLORS[i % len(COLORS)]
            t = a["times"] / u.tau
            e = np.asarray(a["error"], float)
            e = np.where(e <= ERROR_CAP, e, np.nan)  # diverging runs: drawn up to the cap
            series.append(Series(t, e, f"rho={ratio:g}", color=c))
            tq = a["times_qs"] / u.tau
            series.append(Series(tq, a["error_qs"], "", style=":", color=c))
        panels.append(
            Panel(
                series,
                f"{names[name]}, N={u.n_nodes}",
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
            if units[0].medium != medium:
                continue
            c = COLORS[j % len(COLORS)]
            ok = [u for u in units if bracket_closed(u)]
            sizes = sorted({m.n_nodes for m in ok})
            per = [[m for m in ok if m.n_nodes == n] for n in sizes]
            series.append(
                Series(
                    sizes,
                    [np.median([m.critical_ratio for m in p]) for p in per],
                    names[name],
                    lo=[min(m.critical_low for m in p) for p in per],
                    hi=[max(m.critical_high for m in p) for p in per],
                    marker="s",
                    color=c,
                )
            )
            series.append(
                Series(
                    [m.n_nodes for m in ok],
                    [m.critical_ratio for m in ok],
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
        have = [u for u in tasks if u.medium_times(medium) is not None]
        if not have:
            continue
        c = COLORS[j % len(COLORS)]
        sizes = sorted({u.n_nodes for u in have})
        series.append(
            Series(
                sizes,
                [
                    np.median([u.medium_times(medium)["tau"] for u in have if u.n_nodes == n])
                    for n in sizes
                ],
                f"{medium} tau (median)",
                marker="s",
                color=c,
            )
        )
        series.append(
            Series(
                [u.n_nodes for u in have],
                [u.medium_times(medium)["tau"] for u in have],
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
