"""Sentences of the physical_time section (:mod:`.physical_time`) that state the settings
the runs used: GCL phase length, learning steps, quasi-static rebound, continuum tau over
network tau, task draws per size.
"""

from __future__ import annotations

from ..document import Document, fmt
from .physical_time_units import _tasks


def _all_runs(units) -> list[dict]:
    """Every ratio run of the units (grid and bisection)."""
    return [r for u in units for r in (*u.meta["runs"], *u.meta.get("bisection", []))]


def _phase_text(rules: dict) -> str:
    """The GCL phase length as the runs used it (half the learning step), per ratio."""
    c = [
        0.5 * r["dt_learn"] * r["ratio"] / u.meta["tau"]
        for name, units in rules.items()
        if name.startswith("gcl_phases")
        for u in units
        for r in (*u.meta["runs"], *u.meta.get("bisection", []))
    ]
    if not c:
        return ""
    lo, hi = min(c), max(c)
    smallest = min(r["ratio"] for units in rules.values() for r in _all_runs(units))
    if hi <= lo * (1 + 1e-6):
        return (
            f" of {fmt(lo)} tau / ratio (half of every phase run's learning step): shorter "
            f"than one relaxation time at every ratio above {fmt(lo)}"
            + (
                ", so the material never settles within a phase at the ratios run"
                if smallest > lo
                else ""
            )
        )
    return f" of {fmt(lo)} to {fmt(hi)} tau / ratio (half of each phase run's learning step)"


def _qs_rebound_text(rules: dict) -> str:
    """Range of the quasi-static runs' own rebound over the windows run."""
    q = [r["rebound_qs"] for units in rules.values() for r in _all_runs(units) if "rebound_qs" in r]
    if not q:
        return ""
    return (
        f" (the quasi-static runs' own rebound over the windows run: {fmt(min(q))} to "
        f"{fmt(max(q))})"
    )


def _steps_text(rules: dict) -> str:
    """The distinct learning steps alpha k dt_learn (k = 1) over the ratios run."""
    steps = sorted(
        {round(r["alpha"] * r["dt_learn"], 9) for u in rules.values() for r in _all_runs(u)}
    )
    if not steps:
        return ""
    return f", which takes the values {', '.join(fmt(x) for x in steps)} over the ratios run"


def _tau_ratio_text(result) -> str:
    """Range of continuum tau / network tau over every task draw of the run."""
    q = [
        u.meta["continuum"]["tau"] / u.meta["network"]["tau"]
        for u in _tasks(result)
        if "continuum" in u.meta and "network" in u.meta
    ]
    if not q:
        return ""
    return (
        f"; over every size and task draw of this run continuum tau / network tau runs from "
        f"{fmt(min(q))} to {fmt(max(q))} ({len(q)} draws)"
        + (
            ", so the 20 % agreement does not carry over to the study's clamps"
            if max(q) > 1.2 or min(q) < 1 / 1.2
            else ""
        )
    )


def _draws_text(doc: Document, tasks: list) -> None:
    """How many task draws each size has (from the task units)."""
    counts: dict[int, int] = {}
    for u in tasks:
        counts[u.meta["n_nodes"]] = counts.get(u.meta["n_nodes"], 0) + 1
    if not counts:
        return
    text = ", ".join(f"N = {n}: {c}" for n, c in counts.items())
    most = max(counts.values())
    fewer = [n for n, c in counts.items() if c < most]
    one = [n for n in fewer if counts[n] == 1]
    doc.add(
        f"Task draws (random sources, targets and strains; the same lattice) per size: {text}."
        + (
            f" Fewer draws at N = {', '.join(map(str, fewer))} (the scene's `draws`, set by "
            "run time), so the spread over draws rests on fewer tasks there"
            + (f"; at N = {', '.join(map(str, one))} one draw, no spread" if one else "")
            + "."
            if fewer
            else ""
        )
    )
