"""The findings of the physical_time section (:mod:`.`), each by its stated
rule: whether the learning rate speeds learning up, converges to the quasi-static result,
and where learning stops working. The claims about learning (speed-up, Stern's critical
ratio) need a coupling measurement (:func:`coupling_reason`); the comparison with the
quasi-static result compares two computations of one dynamics and does not.
"""

from __future__ import annotations

import math

import numpy as np

from ....learning.coupling import DECOUPLED_BELOW
from ...document import Document
from ...findings import CONTRADICTED, NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding
from .runs import _NAMES, bracket_closed

#: Speed-up (learning time at the smallest ratio over the shortest) that counts as "the
#: learning rate speeds learning up", and below which it does not.
SPEEDUP_YES, SPEEDUP_NO = 3.0, 1.5
#: Largest |e - e_qs| (relative errors) at the smallest ratio for "converges to the
#: quasi-static result".
QS_AGREEMENT = 0.05
#: "A ratio of order one" (Stern et al. 2022): a critical ratio between these.
ORDER_ONE = (0.1, 10.0)


def _speedups(units, *, below_critical: bool = False) -> list[float]:
    """Learning time at the smallest ratio over the shortest one, per unit, over every ratio
    run (the grid and the bisection inside the bracket); with ``below_critical``, only over
    the ratios up to the bracket's low end (not past)."""
    out = []
    for u in units:
        runs = sorted([*u.runs, *u.bisection], key=lambda r: r["ratio"])
        T = np.array([r["T"] for r in runs], float)
        if below_critical and math.isfinite(u.critical_high):
            ratio = np.array([r["ratio"] for r in runs], float)
            T = T[ratio <= u.critical_low]
        out.append(float(T[0] / np.min(T)) if T.size and np.isfinite(T[0]) else math.nan)
    return out


def _lo_force(units) -> dict[str, float]:
    """Smallest and largest bracket low end in units of the net-force time, lo tau_force / tau
    (units with a low end above 0)."""
    v = [u.critical_low * u.tau_force / u.tau for u in units if u.critical_low > 0]
    if not v:
        return {}
    return {"smallest lo x tau_force/tau": min(v), "largest lo x tau_force/tau": max(v)}


def decoupled_count(units) -> int | None:
    """How many of ``units`` (physical_time run units) are decoupled (meta ``"coupling"``);
    None when there are none or any has no coupling measurement."""
    verdicts = [u.coupling for u in units]
    if not verdicts or None in verdicts:
        return None
    return verdicts.count("decoupled")


def coupling_reason(units) -> str:
    """Why a claim about learning over ``units`` (physical_time units, one per size and
    draw) is not comparable, or "" when it can be judged: a claim about learning counts only
    runs that are not decoupled (as in :mod:`...verdicts.claims`), so every unit needs a
    coupling verdict (meta ``"coupling"``, :mod:`....learning.coupling`) and none may be
    decoupled. A unit's verdict is that of its smallest source share over its runs
    (:mod:`....scenes.units_time_coupling`)."""
    n = decoupled_count(units)
    if n is None:
        return "coupling not measured: the task may be met trivially by prestress"
    if n:
        return (
            f"{n} of {len(units)} sizes x draws decoupled (source share < "
            f"{DECOUPLED_BELOW:g}): what they learned is prestress, not a response to the sources"
        )
    return ""


def _shares(units) -> dict[str, float]:
    """Smallest and largest unit source share (units with one; a unit's share is the least
    over its ratios), for the measured numbers."""
    v = [u.source_share for u in units if u.source_share is not None]
    if not v:
        return {}
    return {
        "smallest source share (per draw, least over its ratios)": min(v),
        "largest source share (per draw, least over its ratios)": max(v),
    }


#: The clause every claim about learning adds to its rule (:func:`coupling_reason`).
UNLESS_DECOUPLED = (
    "; not comparable when any size or draw has no coupling measurement or is decoupled "
    "(a claim about learning counts only runs that are not decoupled)"
)


def _median(values: list) -> float:
    """Median, nan for none."""
    return float(np.median(values)) if values else math.nan


def basis(units) -> str:
    """What a claim about learning over ``units`` rests on: "coupled" when every unit's
    verdict (least source share over its runs) is coupled, "met trivially" when any is
    decoupled, "" otherwise (partially coupled or not measured)."""
    verdicts = [u.coupling for u in units]
    if verdicts and all(v == "coupled" for v in verdicts):
        return "coupled"
    if "decoupled" in verdicts:
        return "met trivially"
    return ""


def _counts(units) -> dict[str, float]:
    """Coupled and decoupled run units (size x draw) a verdict counts."""
    v = [u.coupling for u in units]
    return {"coupled units": v.count("coupled"), "decoupled units": v.count("decoupled")}


def _findings(doc: Document, rules: dict, ratios: np.ndarray) -> None:
    from ....scenes.units_time import OSCILLATION, SLOWDOWN

    findings = []
    for name, units in rules.items():
        why = coupling_reason(units)
        rests = basis(units)
        here = f" (here: {why})" if why else ""
        sp = _speedups(units, below_critical=True)
        worst = min(sp) if sp and all(np.isfinite(sp)) else math.nan
        best = max(sp) if sp else math.nan
        if np.isfinite(worst) and worst >= SPEEDUP_YES:
            verdict = CONTRADICTED
        elif np.isfinite(best) and best < SPEEDUP_NO:
            verdict = REPRODUCED
        else:
            verdict = NOT_REPRODUCED
        sizes = sorted({u.n_nodes for u in units})
        measured = {
            f"smallest speed-up N={n}": min(s for u, s in zip(units, sp) if u.n_nodes == n)
            for n in sizes
        }
        findings.append(
            Finding(
                claim=(
                    "paper, discussion: the speed of learning cannot be addressed by "
                    f"increasing the learning rate ({_NAMES[name]})"
                ),
                metric=(
                    "speed-up = learning time at the smallest ratio / shortest learning time "
                    f"over the ratios run ({ratios[0]:g}..{ratios[-1]:g} and the bisection) "
                    "that are not past the quasi-static regime (up to the bracket's low end: "
                    "a run that rebounds or oscillates has not learned faster), per size and "
                    "task draw. By construction a run not past learns less than "
                    f"{SLOWDOWN:g} times slower than its quasi-static reference, whose T_qs "
                    "scales as 1 / alpha, so this speed-up is at least about lo / "
                    f"({SLOWDOWN:g} x the smallest ratio) wherever lo is above it; lo x "
                    "tau_force / tau is the bracket's low end in units of the fast (net-force) "
                    "relaxation time"
                ),
                measured={**measured, **_lo_force(units), **_shares(units), **_counts(units)},
                verdict=NOT_COMPARABLE if why else verdict,
                source="paper",
                basis=rests,
                rule=(
                    f"contradicted when the speed-up is >= {SPEEDUP_YES:g} at every size and "
                    f"draw, reproduced when it is < {SPEEDUP_NO:g} at every size and draw, "
                    f"otherwise not reproduced{UNLESS_DECOUPLED}{here}"
                ),
            )
        )
        by = [u.critical_by for u in units]
        below = _speedups(units, below_critical=True)
        worst_below = min(below) if below and all(np.isfinite(below)) else math.nan
        osc = ("oscillation", "both")
        ok = all(bracket_closed(u) for u in units) and all(b in osc for b in by)
        ok = ok and np.isfinite(worst_below) and worst_below >= SPEEDUP_YES
        closed = [u.critical_ratio for u in units if bracket_closed(u)]
        ok = ok and all(ORDER_ONE[0] <= r <= ORDER_ONE[1] for r in closed)
        findings.append(
            Finding(
                claim=(
                    "Stern et al. 2022: learning speeds up with the learning rate until a "
                    "critical ratio of learning rate to relaxation rate, beyond which the "
                    f"error oscillates ({_NAMES[name]})"
                ),
                metric=(
                    "rho* bracket per size and draw (median over closed brackets per size), "
                    "the criterion its upper end met, speed-up up to its lower end"
                ),
                measured={
                    **{
                        f"median rho* N={n}": _median(
                            [
                                u.critical_ratio
                                for u in units
                                if u.n_nodes == n and bracket_closed(u)
                            ]
                        )
                        for n in sizes
                    },
                    "closed brackets": sum(bracket_closed(u) for u in units),
                    "met by oscillation": sum(b in osc for b in by),
                    "sizes x draws": len(units),
                    "smallest speed-up below rho*": worst_below,
                    **_shares(units),
                    **_counts(units),
                },
                verdict=NOT_COMPARABLE if why else (REPRODUCED if ok else NOT_REPRODUCED),
                source="field",
                basis=rests,
                rule=(
                    "reproduced when at every size and draw the bracket is closed on both "
                    "sides inside the tested range, its upper end met by oscillation (error "
                    f"rebound >= {OSCILLATION:g} above the quasi-static run's error; alone or "
                    "with the slowdown), and the speed-up up to its lower end is >= "
                    f"{SPEEDUP_YES:g}, and every closed bracket's rho* is of order one "
                    f"({ORDER_ONE[0]:g} to {ORDER_ONE[1]:g}); "
                    f"otherwise not reproduced{UNLESS_DECOUPLED}{here}"
                ),
            )
        )
        gaps = [
            math.inf
            if u.runs[0]["diverged"]
            else abs(u.runs[0]["error_at_qs_end"] - u.runs[0]["error_qs_end"])
            for u in units
        ]
        findings.append(
            Finding(
                claim=(
                    "package: learning in physical time tends to the quasi-static result as "
                    f"the ratio goes to 0 ({_NAMES[name]})"
                ),
                metric=(
                    f"|error - quasi-static error| at t_qs at the smallest ratio ({ratios[0]:g}), "
                    "relative errors, largest over sizes and draws"
                ),
                measured={"largest gap": max(gaps)},
                verdict=REPRODUCED if max(gaps) < QS_AGREEMENT else NOT_REPRODUCED,
                rule=f"reproduced when the gap is < {QS_AGREEMENT:g} at every size and draw",
            )
        )
    for f in findings:
        doc.finding(f)
    doc.findings_table(findings)
