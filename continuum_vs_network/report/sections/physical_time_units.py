"""The stored units of a physical_time scene as the report reads them (:mod:`.physical_time`):
run units per rule, task units, the critical-ratio bracket of a run, the rules' names.
"""

from __future__ import annotations

import math

from ..document import fmt

_NAMES = {
    "gcl": "GCL, twin networks",
    "gcl_phases": "GCL, free and nudged phases",
    "gpc": "GPC, continuous",
    "gcl/continuum": "GCL, twin continua",
    "gcl_phases/continuum": "GCL, phases, continuum",
    "gpc/continuum": "GPC, continuous, continuum",
}


def _not_learned(result) -> list:
    """Run units of draws whose quasi-static reference did not learn (stiffness learning,
    :mod:`...scenes.units_time_reference`): no ratio was run."""
    return [
        u
        for u in result.select("physical_time/").values()
        if u.meta.get("kind") == "run" and u.meta.get("learned_qs") is False
    ]


def _by_rule(result) -> dict[str, list]:
    """Run units per rule (``"gcl"``, ``"gcl/continuum"``, ...), by size then draw; units
    of draws not learned quasi-statically (:func:`_not_learned`) are left out."""
    out: dict[str, list] = {}
    for u in result.select("physical_time/").values():
        if u.meta.get("kind") == "task" or u.meta.get("learned_qs") is False:
            continue
        medium = u.meta.get("medium", "network")
        key = u.meta["rule"] if medium == "network" else f"{u.meta['rule']}/{medium}"
        out.setdefault(key, []).append(u)
    for units in out.values():
        units.sort(key=lambda u: (u.meta["n_nodes"], u.meta.get("draw", 0)))
    return out


def _tasks(result) -> list:
    """Task units (one per size and draw), by size then draw."""
    units = [u for u in result.select("physical_time/").values() if u.meta.get("kind") == "task"]
    return sorted(units, key=lambda u: (u.meta["n_nodes"], u.meta["draw"]))


def _bracket(m) -> str:
    """``"(lo, hi]"`` of a run unit's critical ratio."""
    lo, hi = m.get("critical_low", math.nan), m.get("critical_high", math.nan)
    if not math.isfinite(hi):
        return f"> {fmt(lo)}"
    if lo == 0:
        return f"<= {fmt(hi)}"
    return f"({fmt(lo)}, {fmt(hi)}]"
