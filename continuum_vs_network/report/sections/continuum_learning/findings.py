"""What the ``continuum_learning`` section (:mod:`.`) measures on the stored units and the
findings it states from them, each by its stated rule.

Measures: steps to ``C / C0 <= TOLERANCE``, the learned field's change under refinement, its
correlation with the network's and its localisation, and the thresholds. Findings: each rule
learns the task in both media, coupling verdicts agree, fields match and converge and
localise, and two rules learn the same continuum field.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fits import power_law
from ....learning.coupling import DECOUPLED_BELOW
from ...document import coupling_text, fmt, mesh_name
from ...findings import CONTRADICTED, NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding

__all__ = [
    "LOCALISED",
    "SETTLED",
    "SHRINK",
    "TOLERANCE",
    "agreed_coupling",
    "field_summary",
    "fields_agree_verdict",
    "refinement_verdict",
    "steps_to",
]

TOLERANCE = 1e-3  # C / C0 a run must reach to count as having learned the task
SHRINK = 1.5  # a field converges when successive refinements change it less by this factor
SETTLED = 0.1  # ... and the last refinement changes it by at most this (relative L2)
LOCALISED = 0.1  # localisation threshold: a fraction of the largest change


def steps_to(error: NDArray, tol: float = TOLERANCE) -> float:
    """First step with ``error <= tol * error[0]`` (NaN when never reached)."""
    e = np.asarray(error, dtype=float)
    hit = np.flatnonzero(e <= tol * e[0])
    return float(hit[0]) if hit.size else math.nan


def _magnitude(eps: NDArray) -> NDArray:
    from ....continuum.learned_fields import field_magnitude

    return field_magnitude(eps)


def field_summary(units: dict[str, Any], rule: str, refine: int) -> dict[str, list[float]]:
    """Per refinement ``r``: relative L2 change of the field on the lattice triangles from
    ``r - 1`` (area-weighted), correlation with the network's field, and the area fraction
    whose change exceeds ``LOCALISED`` of the largest (native mesh)."""
    net = units[f"continuum_learning/network/{rule}"]
    out: dict[str, list[float]] = {"change": [], "correlation": [], "localised": []}
    prev = None
    area0 = None
    for r in range(refine + 1):
        a = units[f"continuum_learning/refine{r}/{rule}"]
        coarse = np.asarray(a.coarse)
        if area0 is None:
            area0 = np.asarray(a.area)
        w = np.sqrt(area0)[:, None]
        norm = float(np.linalg.norm(coarse * w))
        if prev is None or norm == 0:
            out["change"].append(math.nan)
        else:
            out["change"].append(float(np.linalg.norm((coarse - prev) * w)) / norm)
        prev = coarse
        c = np.corrcoef(coarse.ravel(), np.asarray(net.coarse).ravel())[0, 1]
        out["correlation"].append(float(c))
        mag = _magnitude(np.asarray(a.field))
        area = np.asarray(a.area)
        top = float(mag.max())
        out["localised"].append(
            float(np.sum(area[mag > LOCALISED * top]) / np.sum(area)) if top > 0 else math.nan
        )
    return out


def _verdicts(doc, rule, units, summary, needed, R: int) -> list[str]:
    """Findings of one rule (registered on ``doc``) and the sentences that show them."""
    lines = [""]
    final = {
        name: float(np.asarray(units[key].error)[-1] / np.asarray(units[key].error)[0])
        for name, key in (
            ("network", f"continuum_learning/network/{rule}"),
            ("continuum h", f"continuum_learning/refine0/{rule}"),
        )
    }
    metas = {
        "network": units[f"continuum_learning/network/{rule}"],
        "continuum h": units[f"continuum_learning/refine0/{rule}"],
    }
    learned = all(v <= TOLERANCE for v in final.values()) and all(
        m.source_share >= DECOUPLED_BELOW for m in metas.values()
    )
    doc.finding(
        Finding(
            source="check",
            claim=f"one rule object ({rule}) learns one task, not trivially, in a lattice and in "
            "its continuum",
            metric="final C/C0 and source share of the network and of the continuum on the "
            "lattice triangles",
            measured={
                **{f"C/C0 {k}": v for k, v in final.items()},
                **{f"share {k}": m.source_share for k, m in metas.items()},
            },
            verdict=REPRODUCED if learned else NOT_REPRODUCED,
            rule=f"reproduced when both reach C/C0 <= {TOLERANCE:g} and neither is decoupled "
            f"(source share >= {DECOUPLED_BELOW:g}); a decoupled medium met the task by "
            "prestressing its targets",
        )
    )
    doc.finding(
        Finding(
            source="check",
            claim=f"the continuum gets the network's coupling verdict ({rule})",
            metric="source share of the trained media (learning.coupling; 'coupled' >= "
            f"0.5, 'decoupled' < {DECOUPLED_BELOW:g})",
            measured={f"share {k}": m.source_share for k, m in metas.items()},
            verdict=REPRODUCED if _same_coupling(metas) else NOT_REPRODUCED,
            rule="reproduced when both media get the same coupling verdict; "
            + agreed_coupling(metas),
        )
    )
    corr = summary["correlation"][0]
    # a decoupled medium's learned field is prestress of its targets: nothing to compare
    decoupled = any(m.source_share < DECOUPLED_BELOW for m in metas.values())
    unless = "; not comparable when either medium is decoupled (its field is prestress)"
    doc.finding(
        Finding(
            source="check",
            claim=f"at the lattice's resolution the continuum's learned field matches the "
            f"network's ({rule})",
            metric="correlation of the learned rest strains on the lattice triangles",
            measured={"correlation": corr},
            verdict=NOT_COMPARABLE
            if decoupled
            else (REPRODUCED if corr >= 0.9 else NOT_REPRODUCED),
            rule="reproduced when the correlation is >= 0.9" + unless,
        )
    )
    change = [c for c in summary["change"][1:] if np.isfinite(c)]
    if len(change) >= 2:
        verdict = refinement_verdict(change, decoupled=decoupled)
        doc.finding(
            Finding(
                source="check",
                claim=f"the learned field converges under refinement ({rule})",
                metric="relative L2 change of the field on the lattice triangles per halving of h",
                measured={f"change h/{2 ** (i + 1)}": c for i, c in enumerate(change)},
                verdict=verdict,
                rule=f"reproduced when every halving changes it at least {SHRINK:g} times less "
                f"than the one before and the last change is <= {SETTLED:g}; contradicted "
                "when the changes grow" + unless,
            )
        )
        lines.append(
            f"- **Refinement.** Successive changes of the field on the lattice triangles: "
            f"{', '.join(fmt(c, 2) for c in change)} ({verdict} by the rule in the findings)."
        )
    loc = summary["localised"]
    if len(loc) >= 2 and all(np.isfinite(loc)):
        falls = all(b < a for a, b in itertools.pairwise(loc))
        doc.finding(
            Finding(
                source="check",
                claim=f"the learned change localises as the mesh is refined ({rule})",
                metric=f"area fraction whose change exceeds {LOCALISED:g} of the largest",
                measured={mesh_name(r): x for r, x in enumerate(loc)},
                verdict=NOT_COMPARABLE if decoupled else (REPRODUCED if falls else NOT_REPRODUCED),
                rule="reproduced when the fraction falls at every refinement" + unless,
            )
        )
        lines.append(
            f"- **Localisation.** Area fraction whose rest strain changed by more than "
            f"{LOCALISED:g} of the largest change: {' -> '.join(fmt(x, 2) for x in loc)}."
        )
    cont = np.array(needed[1:], dtype=float)
    if np.all(np.isfinite(cont)) and cont.size >= 2 and np.all(cont > 0):
        h = 0.5 ** np.arange(cont.size)
        fit = power_law(h, cont)
        lines.append(
            f"- **Steps needed.** Steps to C/C0 <= {TOLERANCE:g}: "
            f"{', '.join(fmt(c) for c in cont)} from h to h/{2**R}, by least squares "
            f"{fit.describe('steps', 'h')} with the element size h (whole step counts: the "
            f"standard error is a lower bound) (network: {fmt(needed[0])} steps)."
        )
    lines.append(
        f"- **Coupling.** Network: {metas['network'].outcome}; continuum at h: "
        f"{metas['continuum h'].outcome} (source shares "
        f"{fmt(metas['network'].source_share, 2)} and "
        f"{fmt(metas['continuum h'].source_share, 2)}). A decoupled solution meets the "
        "task by prestressing the targets, not by transmitting the sources' strain. "
        f"Coupling verdicts: {agreed_coupling(metas)}."
    )
    lines.append(
        f"- **Same triangles.** Correlation of the network's and the continuum's learned "
        f"rest strains on the lattice triangles at h: {fmt(corr, 2)}."
    )
    return [*lines, ""]


def _same_coupling(metas: dict[str, Any]) -> bool:
    return len({m.coupling for m in metas.values()}) == 1


def agreed_coupling(metas: dict[str, Any]) -> str:
    """What two or more media's coupling verdicts say, in words (``metas``: name -> a run
    with ``coupling``): the agreement, or the disagreement, stated plainly."""
    verdicts = {k: m.coupling for k, m in metas.items()}
    if _same_coupling(metas):
        (v,) = set(verdicts.values())
        many = len(verdicts) > 2
        what = f"here {'all' if many else 'both'} {v}"
        if v == "decoupled":
            what += (
                f": what is agreed is that {'every medium' if many else 'both media'} met "
                "the task (if at all) by prestressing the targets, not that any learned it"
            )
        return what
    return "here " + ", ".join(f"{k} {v}" for k, v in verdicts.items())


def _rules_agree(doc, units, rules, R: int) -> None:
    """GCL and the exact gradient, both from zero eigenstrain on a linear body, descend a
    least-squares problem inside the range of the same Jacobian: they converge to the same
    (minimum-norm) field whatever the weighting of the targets."""
    if "gcl" not in rules or "exact" not in rules:
        return
    fields = [
        np.asarray(units[f"continuum_learning/refine{R}/{r}"].field).ravel()
        for r in ("gcl", "exact")
    ]
    diff = float(np.linalg.norm(fields[0] - fields[1]) / np.linalg.norm(fields[1]))
    metas = {r: units[f"continuum_learning/refine{R}/{r}"] for r in ("gcl", "exact")}
    verdict = fields_agree_verdict(diff, [m.source_share for m in metas.values()])
    doc.finding(
        Finding(
            source="check",
            claim="coupled learning and the exact gradient learn the same continuum field",
            metric=f"relative difference of the learned eigenstrain at continuum {mesh_name(R)}",
            measured={
                "relative difference": diff,
                **{f"share {r}": m.source_share for r, m in metas.items()},
            },
            verdict=verdict,
            rule="reproduced when the fields differ by <= 1 % (both runs converged); not "
            f"comparable when either run is decoupled (source share < {DECOUPLED_BELOW:g}: its "
            "field is prestress of the targets, and two descents of one linear least-squares "
            "problem from zero reach its minimum-norm solution whatever they learn)",
        )
    )
    doc.add(
        f"GCL and the exact gradient learn fields that differ by {fmt(diff, 2)} (relative) at "
        f"continuum {mesh_name(R)}: from zero eigenstrain both descend a linear least-squares "
        "problem within the "
        "range of one Jacobian, so both converge to its minimum-norm solution; the targets' "
        "weighting (effective stiffness for GCL) changes the path, not the end. Source shares "
        + ", ".join(f"{r} {coupling_text(m)}" for r, m in metas.items())
        + (
            f": **{verdict}** as evidence that the two rules learn alike, since a decoupled "
            "field is prestress, the same minimum-norm solution for any descent."
            if verdict == NOT_COMPARABLE
            else "."
        ),
        "",
    )


def refinement_verdict(change, *, decoupled: bool) -> str:
    """Verdict of "the learned field converges under refinement": ``change``, the relative
    L2 changes of the field per halving of h (at least 2, coarsest first); ``decoupled``,
    whether either medium is decoupled. Not comparable when decoupled (the field is
    prestress of the targets); reproduced when every change is at least ``SHRINK`` times
    smaller than the one before and the last is <= ``SETTLED``; contradicted when they grow."""
    if decoupled:
        return NOT_COMPARABLE
    shrinks = all(b * SHRINK <= a for a, b in itertools.pairwise(change))
    grows = all(b > a for a, b in itertools.pairwise(change))
    if shrinks and change[-1] <= SETTLED:
        return REPRODUCED
    return CONTRADICTED if grows else NOT_REPRODUCED


def fields_agree_verdict(diff: float, shares) -> str:
    """Verdict of "two rules learn the same field": relative difference ``diff`` of the
    fields, source shares of the runs. Not comparable when any run is decoupled."""
    if any(s < DECOUPLED_BELOW for s in shares):
        return NOT_COMPARABLE
    return REPRODUCED if diff <= 1e-2 else NOT_REPRODUCED
