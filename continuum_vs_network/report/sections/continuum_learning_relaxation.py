"""Relaxation of the learned material in the ``continuum_learning`` section
(:mod:`.continuum_learning`): target strains against time after the sources switch on.
"""

from __future__ import annotations

import numpy as np

from ..document import fmt
from ..figures import Panel, Series


def _relaxation(doc, units) -> None:
    """Target strains against time after the sources switch on, both trained media."""
    u = units.get("continuum_learning/relaxation")
    if u is None:
        return
    a, m = u.arrays, u.meta
    doc.heading("Relaxation of the learned material", 3)
    strain_clamp = "network_nodes_settle" in m
    if strain_clamp:
        drive = (
            "Both media are driven by a strain clamp: the continuum holds the source springs' "
            "strains as exact constraints, the network holds each source spring as a stiff "
            f"rod (stiffness {m['rod_factor']:.0e} x the mean k, rest length the clamp "
            "length; backward Euler, L-stable), its end nodes free otherwise (the rods' "
            f"largest strain error {m['rod_strain_error']:.1e}). For comparison, the network "
            "is also run with its clamps as prescribed end-node displacements (both end nodes "
            "held, so a source spring cannot rotate or translate)"
        )
    else:
        drive = (
            "The continuum holds exact clamps; the network holds its clamps as prescribed "
            "end-node displacements"
        )
    doc.add(
        f"The trained network and the trained continuum (rule `{m['rule']}`, on the lattice "
        "triangles) start at rest with the sources off; at t = 0 the sources switch on and "
        "both creep against node drag c = 1 (the continuum: its equivalent substrate drag; "
        f"the network: overdamped dynamics). {drive}. dt = {m['dt']:g}, time in units of "
        "c / k."
    )
    runs = [("network, strain clamp" if strain_clamp else "network", "network", "network")]
    if strain_clamp:
        runs.append(("network, end nodes held", "network_nodes", "network_nodes"))
    runs.append(("continuum h, strain clamp", "continuum", None))
    panels, rows = [], []
    for name, key, arr in runs:
        t = a[f"{arr}_times"] if arr else a["times"]
        s = np.asarray(a[f"{arr}_strain"] if arr else a["continuum_strain"])
        d = np.linalg.norm(s - s[-1], axis=1)
        panels.append(Series(t, d / d[0], name))
        rows.append([name, fmt(m[f"{key}_settle"]), fmt(m[f"{key}_gap"]), fmt(m[f"{key}_seconds"])])
    doc.table(
        [
            "medium",
            "time to settle within 10 % of the end values",
            "gap at the end to the exact-clamp free state",
            "seconds",
        ],
        rows,
    )
    caption = (
        "Distance of the target strains from their values at the end of the run after the "
        "sources switch on, trained network and trained continuum (one run each). "
    )
    if strain_clamp:
        caption += (
            "Driven alike (strain clamps), the network and the continuum approach their end "
            "values along similar paths (not identical: the continuum's drag goes by node area "
            "and its boundary edges are softer); holding the network's source springs by their "
            "end nodes changes the path and the end state (its gap in the table)."
        )
    else:
        caption += (
            "The network's clamps move the source springs' end nodes, the continuum's fix "
            "only their strain: the two relax along different paths."
        )
    doc.figure(
        "continuum_relaxation",
        [
            Panel(
                panels,
                "approach of the target strains",
                "time (c / k)",
                "|S(t) - S(end)| / |S(0) - S(end)|",
                yscale="log",
                hlines=(0.1,),
            )
        ],
        caption,
    )
