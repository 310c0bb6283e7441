"""The summary table of the physical_time section (:mod:`.physical_time`): median and range
over draws per size, and the power-law fits over all draws.
"""

from __future__ import annotations

import numpy as np

from ...learning.coupling import COUPLED_AT, DECOUPLED_BELOW
from ..document import Document, fmt
from .physical_time_figures import bracket_closed
from .physical_time_units import _NAMES, _bracket


def _spread(values) -> str:
    """``"median [min, max] (n)"``."""
    v = np.asarray(values, float)
    if v.size == 0:
        return "-"
    return f"{fmt(float(np.median(v)))} [{fmt(float(v.min()))}, {fmt(float(v.max()))}] ({v.size})"


def _summary(doc: Document, rules: dict, tasks: list) -> None:
    """Median and range over draws per size, and the fits over all draws."""
    media = [m for m in ("network", "continuum") if any(m in u.meta for u in tasks)]
    sizes = sorted({u.meta["n_nodes"] for u in tasks})
    rows = []
    for medium in media:
        for key in ("tau", "tau_force"):
            rows.append(
                [f"{medium} {key}"]
                + [
                    _spread([u.meta[medium][key] for u in tasks if u.meta["n_nodes"] == n])
                    for n in sizes
                ]
            )
    for name, units in rules.items():
        rows.append(
            [f"rho*, {_NAMES[name]}"]
            + [
                _spread(
                    [
                        u.meta["critical_ratio"]
                        for u in units
                        if u.meta["n_nodes"] == n and bracket_closed(u.meta)
                    ]
                )
                for n in sizes
            ]
        )
    for name, units in rules.items():
        rows.append(
            [f"source share, {_NAMES[name]}"]
            + [
                _spread(
                    [
                        u.meta["source_share"]
                        for u in units
                        if u.meta["n_nodes"] == n and u.meta.get("source_share") is not None
                    ]
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
        N = [u.meta["n_nodes"] for u in tasks]
        for key in ("tau", "tau_force"):
            t = [u.meta[medium][key] for u in tasks]
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
        ok = [u.meta for u in units if bracket_closed(u.meta)]
        open_ = [
            f"N = {u.meta['n_nodes']} draw {u.meta.get('draw', 0)} ({_bracket(u.meta)})"
            for u in units
            if not bracket_closed(u.meta)
        ]
        left = f"; left out, bracket open: {', '.join(open_)}" if open_ else ""
        if len({m["n_nodes"] for m in ok}) >= 2:
            N = [m["n_nodes"] for m in ok]
            c = [m["critical_ratio"] for m in ok]
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
    from ...fits import robust_trend

    try:
        return robust_trend(n_nodes, values).describe(quantity, "N")
    except ValueError:
        return f"{quantity}: one size only (no fit)"
