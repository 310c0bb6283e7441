"""Relaxation of the learned material in the ``continuum_learning`` section
(:mod:`.continuum_learning`): target strains against time after the sources switch on.
"""

from __future__ import annotations

import numpy as np

from ..figures import Panel, Series
from .continuum_learning_format import _g


def _relaxation(doc, units) -> None:
    """Target strains against time after the sources switch on, both trained media."""
    u = units.get("continuum_learning/relaxation")
    if u is None:
        return
    a, m = u.arrays, u.meta
    doc.heading("Relaxation of the learned material", 3)
    doc.add(
        f"The trained network and the trained continuum (rule `{m['rule']}`, on the lattice "
        "triangles) start at rest with the sources off; at t = 0 the sources switch on and "
        "both creep against node drag c = 1 (the continuum: its equivalent substrate drag, "
        f"exact clamps; the network: overdamped dynamics, clamps as prescribed end-node "
        f"displacements), dt = {m['dt']:g}, time in units of c / k."
    )
    panels, rows = [], []
    for name, key, t, s in (
        ("network", "network", a["network_times"], a["network_strain"]),
        ("continuum h", "continuum", a["times"], a["continuum_strain"]),
    ):
        s = np.asarray(s)
        d = np.linalg.norm(s - s[-1], axis=1)
        panels.append(Series(t, d / d[0], name))
        rows.append([name, _g(m[f"{key}_settle"]), _g(m[f"{key}_gap"]), _g(m[f"{key}_seconds"])])
    doc.table(
        [
            "medium",
            "time to settle within 10 % of the end values",
            "gap at the end to the exact-clamp free state",
            "seconds",
        ],
        rows,
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
        "Distance of the target strains from their values at the end of the run after the "
        "sources switch on, trained network and trained continuum (one run each). The "
        "network's clamps move the source springs' end nodes, the continuum's fix only their "
        "strain: the two relax along different paths.",
    )
