"""Directed aging against GPC, GCL and the exact gradient (:mod:`.`): final
error, coupling and outcome of every default rule on each anchored task beside the optimum
of its dof, and the identity of rest-length aging and GPC at uniform stiffness.
"""

from __future__ import annotations

import math

import numpy as np

from ....learning.coupling import MET_AT
from ....scenes.results.beyond_paper import CompareResult, OptimumResult
from ...document import coupling_text, fmt
from ...figures import COLORS, Panel, Series
from ...findings import (
    CONTRADICTED,
    NOT_COMPARABLE,
    NOT_REPRODUCED,
    REPRODUCED,
    Finding,
    reasoned,
    runs_basis,
)

SAME = 1e-6  # relative difference of two error curves that counts as identical
TASK_NAMES = {"paper": "the paper's task", "lattice": "Rocks et al.'s task on the lattice"}
#: whose claim "rule learns the task" is: the paper's own rule, the field's, the package's
SOURCES = {"gpc": "paper", "exact": "check"}
RULE_NAMES = {
    "aging": "directed aging of rest lengths",
    "aging_k": "directed aging of stiffnesses",
    "gpc": "GPC of rest lengths",
    "gcl": "GCL of rest lengths",
    "gcl_both": "GCL of rest lengths and stiffnesses",
    "exact": "the exact gradient of rest lengths",
    "gcl_k": "GCL of stiffnesses",
}


def rule_verdict(run: CompareResult, opt: OptimumResult | None) -> tuple[str, str]:
    """Verdict of "the rule learns the task" from its run (``outcome``) and the optimum of
    its dof (``outcome``, ``feasible``, ``dof``, ``worst_example``), and
    the reason when not comparable: infeasible (the optimum misses ``FEASIBLE``: counted
    apart), met trivially, or no optimum; reproduced when learned (``C/C0 <= MET_AT``, not
    decoupled), not reproduced when a feasible task is not met in the budget."""
    from ....scenes.units_beyond import FEASIBLE

    if opt is None or opt.outcome == "stopped":
        return NOT_COMPARABLE, "the optimum of this dof could not be found"
    if not opt.feasible:
        return NOT_COMPARABLE, (
            f"infeasible, the optimum of {opt.dof} leaves its worst example at C_e/C_e0 = "
            f"{fmt(opt.worst_example)} > {FEASIBLE:g} (counted apart)"
        )
    if run.outcome.startswith("learned"):
        return REPRODUCED, ""
    if run.outcome.startswith("met trivially"):
        return NOT_COMPARABLE, "met by prestress (decoupled), not learned"
    return NOT_REPRODUCED, ""


def _compare(doc, scene, units) -> None:
    from ....scenes.units_beyond import DOFS, FEASIBLE, LATTICE_TASK, compare_rules

    L = scene.learning
    rules = compare_rules(scene)
    doc.heading("Directed aging, GPC, GCL and the exact gradient", 3)
    doc.add(
        "Directed aging (Pashine et al. 2019; Hexner et al. 2020) is a clamped-only rule: "
        "sources and targets are held at the task's strains and the material ages under the "
        "stress this applies, rest lengths creeping `dL = alpha (r^C - L)` (`aging`) or "
        "stiffnesses weakening `dk = -(alpha/2) k (r^C/L - 1)^2` (`aging_k`). The paper's GPC "
        "rest-length rule `dL = alpha k (r^C - L)` is directed aging of rest lengths with a "
        "k-weighted rate. Every rule is the package's default object: GCL (nudge "
        f"{L.eta:g}) and the exact gradient step by their per-spring adaptive rate, GPC and "
        "aging by their scaled rate (alpha fixed at the first step so that the largest change "
        "is the same fraction of the dof's scale); nothing is tuned. `gcl_both` learns rest "
        "lengths and stiffnesses together, `gcl_k` stiffnesses only. Each task is trained "
        "with its *rest example* (sources off, targets asked to stay at their untrained "
        "strains), so prestress alone cannot meet it: a network that transmits nothing leaves "
        "C/C0 near 0.5. The lattice task is Rocks et al.'s: one source strained by "
        f"{LATTICE_TASK['source_strain']:g}, one target {LATTICE_TASK['distance']:g} of the "
        f"box away asked for +{LATTICE_TASK['ratio']:g} of it. Beside every rule, the optimum "
        "of its dof (L-BFGS-B on the exact gradient, within the same ranges, at most "
        f"{L.steps} iterations, as many as the rules' steps): a task whose optimum leaves an "
        f"example above C_e/C_e0 = {FEASIBLE:g} is *infeasible* for that dof and counted "
        "apart.",
        "",
    )
    panels = []
    for task in L.compare_tasks:
        rows, series = [], []
        metas: dict[str, CompareResult] = {r: units[f"beyond/compare/{task}/{r}"] for r in rules}
        opts: dict[str, OptimumResult] = {
            d: units[f"beyond/optimum/{task}/{d}"] for d in {DOFS[r] for r in rules}
        }
        groups: dict[str, list[str]] = {}
        for i, r in enumerate(rules):
            m, o = metas[r], opts[DOFS[r]]
            e = np.asarray(m.error, dtype=float)
            verdict, reason = rule_verdict(m, o)
            rows.append([
                r, m.dof, fmt(m.ratio), coupling_text(m),
                m.outcome, f"{fmt(o.worst_example)} ({o.outcome})",
                fmt(m.seconds), (m.stop_reason or "")[:80],
            ])  # fmt: skip
            series.append(Series(np.arange(e.size), e / e[0], r, color=COLORS[i % len(COLORS)]))
            group = "infeasible" if reason.startswith("infeasible") else m.outcome
            groups.setdefault(group, []).append(r)
            doc.finding(
                Finding(
                    claim=f"{RULE_NAMES[r]} learns {TASK_NAMES[task]} (with its rest example)",
                    metric=f"final C/C0 after {m.steps} steps, coupling verdict "
                    "(learning.coupling), and the optimum of the same dof",
                    measured={
                        "C/C0": m.ratio,
                        "source share": m.source_share,
                        "optimum worst C_e/C_e0": o.worst_example,
                    },
                    verdict=verdict,
                    rule=reasoned(
                        f"reproduced when C/C0 <= {MET_AT:g} and the network is not decoupled; "
                        "not reproduced when the task is feasible for the dof (optimum <= "
                        f"{FEASIBLE:g}) and the rule does not meet it in its steps; not "
                        "comparable when the optimum shows the task infeasible",
                        verdict,
                        reason,
                    ),
                    source=SOURCES.get(r, "field"),
                    basis=runs_basis([m]),
                )
            )
        first = metas[rules[0]]
        doc.add(
            f"**{TASK_NAMES[task]}** ({first.n_nodes} nodes, {first.n_springs} springs; "
            f"source strain {', '.join(fmt(s) for s in first.source_strain)}, desired "
            f"target strain {', '.join(fmt(s) for s in first.target_strain)}):"
        )
        doc.table(
            ["rule", "learns", "C/C0 at the end", "source share (coupling)", "outcome",
             "optimum of its dof: worst C_e/C_e0", "seconds", "stopped"],
            rows,
        )  # fmt: skip
        doc.add(
            "; ".join(f"{g}: {', '.join(rs)}" for g, rs in groups.items())
            + ". Optimum per dof: "
            + "; ".join(
                f"{d} {fmt(o.worst_example)} in {_or_dash(o.iterations)} iterations "
                f"({fmt(o.seconds, 2)} s)"
                for d, o in sorted(opts.items())
            )
            + ".",
            "",
        )
        panels.append(
            Panel(series, TASK_NAMES[task], "step", "C / C0", yscale="log", hlines=(MET_AT,))
        )
    doc.figure(
        "beyond_compare",
        panels,
        "Task error (with the rest example) against steps of every default rule, one run "
        "each, bulk learning"
        + (" (one panel per task)" if len(panels) > 1 else "")
        + _hidden(panels)
        + ".",
    )
    _aging_is_gpc(doc, scene, units)


def _or_dash(value) -> object:
    """``value``, or "-" when it is not recorded (None)."""
    return "-" if value is None else value


def _hidden(panels) -> str:
    """Which curves lie on top of one another (within 1e-6 relative at every step), so the
    caption can say that a line hidden under another is drawn."""
    pairs = []
    for panel in panels:
        drawn = [(s.label, np.asarray(s.y, dtype=float)) for s in panel.series]
        for i, (a, ya) in enumerate(drawn):
            for b, yb in drawn[:i]:
                both = np.isfinite(ya) & np.isfinite(yb)
                if (
                    ya.shape == yb.shape
                    and both.any()
                    and np.allclose(ya[both], yb[both], rtol=1e-6, atol=0.0)
                ):
                    pairs.append(f"{a} lies under {b}")
    return f"; on top of one another (drawn, hidden): {', '.join(pairs)}" if pairs else ""


def _aging_is_gpc(doc, scene, units) -> None:
    L = scene.learning
    if "aging" not in L.rules or "gpc" not in L.rules:
        return
    for task in L.compare_tasks:
        meta: CompareResult = units[f"beyond/compare/{task}/aging"]
        a = np.asarray(meta.error, dtype=float)
        g = np.asarray(units[f"beyond/compare/{task}/gpc"].error, dtype=float)
        both = np.isfinite(a) & np.isfinite(g)
        diff = float(np.max(np.abs(a[both] - g[both]) / a[0])) if both.any() else math.nan
        if meta.uniform_stiffness and np.isfinite(diff):
            verdict = REPRODUCED if diff <= SAME else CONTRADICTED
        else:
            verdict = NOT_COMPARABLE
        reason = (
            "k is not uniform, so the two rules differ by the k weighting"
            if not meta.uniform_stiffness
            else "a run stopped before its first step"
        )
        doc.finding(
            Finding(
                claim="GPC of rest lengths is directed aging of rest lengths with a k-weighted "
                f"rate ({TASK_NAMES[task]})",
                metric="largest difference of the two error curves over C0",
                measured={"difference": diff, "uniform k": float(meta.uniform_stiffness)},
                verdict=verdict,
                rule=reasoned(
                    "with uniform k, both at their scaled rate (alpha fixed at the first step "
                    "so that the largest change is the same), the steps are the same: "
                    f"reproduced when the curves agree to {SAME:g}, contradicted otherwise",
                    verdict,
                    reason,
                ),
                source="check",
            )
        )
        doc.add(
            f"- {TASK_NAMES[task]}: aging and GPC error curves differ by at most {fmt(diff, 2)} "
            f"of C0 ({'uniform' if meta.uniform_stiffness else 'non-uniform'} k; "
            f"{verdict} by the rule in the findings)."
        )
    doc.add("")
