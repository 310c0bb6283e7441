"""physical_time scenes: learning concurrent with the dynamics against the ratio of learning
rate to relaxation rate, the critical ratio against size, and the verdicts.

This module writes the section in order; its parts: :mod:`.physical_time_units` (reading the
stored units), :mod:`.physical_time_text` (settings as the runs used them),
:mod:`.physical_time_tables` (summary and fits), :mod:`.physical_time_figures`,
:mod:`.physical_time_findings` (the verdict rules), :mod:`.physical_time_modes` (the linear
modes behind the relaxation times, against the `relaxation` scene).
"""

from __future__ import annotations

import math

import numpy as np

from ..document import Document, fmt
from .physical_time_figures import figures, first_draws
from .physical_time_findings import QS_AGREEMENT as QS_AGREEMENT
from .physical_time_findings import SPEEDUP_NO as SPEEDUP_NO
from .physical_time_findings import SPEEDUP_YES as SPEEDUP_YES
from .physical_time_findings import _findings, decoupled_count
from .physical_time_modes import modes_section
from .physical_time_tables import _summary
from .physical_time_text import (
    _draws_text,
    _phase_text,
    _qs_rebound_text,
    _steps_text,
    _tau_ratio_text,
    stiffness_intro,
)
from .physical_time_units import _NAMES, _bracket, _by_rule, _not_learned, _tasks


def section(doc: Document, result) -> None:
    """Tables, figures and findings of a physical_time scene."""
    scene = result.scene
    spec = scene.physical_time
    rules = _by_rule(result)
    vis = f"node drag c = {spec.drag:g}"
    if spec.dashpot:
        vis += f", spring dashpots gamma = {spec.dashpot:g}"
    if spec.arm_stiffness:
        vis += f", Maxwell arms k2 = {spec.arm_stiffness:g}, gamma2 = {spec.arm_dashpot:g}"
    if spec.dof == "stiffness":
        stiffness_intro(doc, scene, rules, _not_learned(result), vis)
    else:
        _rest_length_intro(doc, scene, spec, rules, result, vis)
    _after_intro(doc, scene, spec, rules, result)


def _rest_length_intro(doc: Document, scene, spec, rules, result, vis: str) -> None:
    """The opening paragraph of a scene that learns rest lengths (Stern tasks)."""
    from ...scenes.units_time import FLOOR, OSCILLATION, SLOWDOWN

    doc.add(
        "Learning runs concurrently with the overdamped dynamics of the lattice "
        f"({vis}; k = 1), as one system of ODEs "
        "(`learning/physical_time.py`): GPC with sources and targets held and "
        "`dL/dt = alpha k (r - L)` while the nodes move; GCL as twin networks (a free and a "
        "nudged copy evolving together, the update from their difference) or with free and "
        f"nudged phases{_phase_text(rules)}. Stern-scale tasks "
        f"({scene.task.n_sources} sources, {scene.task.n_targets} target(s)), bulk learning "
        "(sources and targets frozen), strains against the initial rest lengths, a clamp "
        "holding only the clamped spring's length (a stiff rod, no node held). The ratio "
        "is rho = alpha k tau, with tau the relaxation time after the source step, "
        "measured for each size: the time after which the target strains "
        "(what learning reads) stay within 1 % of their total change of their new "
        "equilibrium (Euclidean norm over the targets; the change from the state before the "
        "step, the equilibrium an exact solve with the sources clamped). tau_force, the time "
        "for the largest net force to stay below 1 % of its start, is shown beside it: local "
        "modes dominate it, so it does not follow the slow modes that the targets do. The "
        "quasi-static limit is the same run with an equilibrium at every step. Errors are "
        "Eq. 26 at the equilibrium free state of the parameters learned so far, relative to "
        "the initial error. Learning time T: when the error has made all but "
        f"{spec.fraction:g} of its quasi-static drop (in the same run length). A run is "
        f"past the quasi-static regime when T is {SLOWDOWN:g} times the quasi-static T "
        f"(within the first learning time) or when it oscillates: its error climbs back to "
        f"{OSCILLATION:g} times its running minimum (the minimum floored at {FLOOR:g} of the "
        "initial error, the solver's floor) at a time when it is also above the quasi-static "
        "run's error at that time. The quasi-static run covers the same window as the "
        "physical one with the same steps (it depends on alpha only through alpha k dt_learn"
        f"{_steps_text(rules)}; one quasi-static run per value over the longest window, in "
        "units of 1 / (alpha k), serves every ratio, compared step for step): a rebound the "
        "quasi-static "
        "run shares is the discrete learning step's, not the breakdown of quasi-staticity"
        f"{_qs_rebound_text(rules)}. The criterion "
        "need not be monotone in the ratio, so the critical ratio rho* is a bracket "
        "(lo, hi] by this rule: lo is the largest ratio run that is not past, hi the next "
        "ratio run, so hi and every ratio run above it are past; ratios below lo that are "
        "past are counted ('non-monotone') but do not move the bracket. The bracket from "
        "the grid ratios is narrowed by "
        + (
            f"{spec.bisections} bisections in log scale (the rule applied again to every ratio run)"
            if spec.bisections
            else "no bisection (bisections = 0)"
        )
        + "; rho* as a number is the bracket's geometric mean (only brackets closed on "
        "both sides are fitted). '<= r': the smallest ratio is already past; '> r': none is."
        + (
            " The continuum (rows '... continuum'): the lattice's own triangles (P1, lattice "
            "Lamé parameters), learning its eigenstrain with the same rule objects, the same "
            "task's material springs clamped exactly (Lagrange multipliers), "
            "against the lattice's node drag mapped to a substrate drag; its tau and tau_force "
            "by the same criteria (`continuum/damped_states.py`); rho = alpha k tau with the "
            "lattice's k = 1. Both hold a clamp by its length "
            "only; the two media's tau still differ by modelling, not by error: the P1 body "
            "counts boundary springs at half stiffness and its drag by node area; with these "
            "matched on the lattice, the two settle within 20 % of each other "
            "(`tests/test_relaxation_clamps.py`, which checks task draw 0 at n = 8 and 16 "
            f"only){_tau_ratio_text(result)}."
            if "continuum" in spec.media
            else ""
        )
    )


def _after_intro(doc: Document, scene, spec, rules, result) -> None:
    """Coupling, draws, tables, figures and findings (both dofs)."""
    ratios = np.asarray(spec.ratios, float)
    doc.add(_coupling_summary(rules))
    tasks = _tasks(result)
    _draws_text(doc, tasks)
    rows = []
    for name, units in rules.items():
        for u in first_draws(units):
            m = u.meta
            for r in m["runs"]:
                rows.append(
                    [
                        _NAMES[name],
                        m["n_nodes"],
                        fmt(m["tau"]),
                        fmt(r["ratio"]),
                        fmt(r["T"] / m["tau"]),
                        fmt(r["T_qs"] / m["tau"]),
                        fmt(r["slowdown"]),
                        fmt(r["error_at_qs_end"]),
                        fmt(r["error_qs_end"]),
                        fmt(r["error_final"]),
                        "diverged" if r["diverged"] else fmt(r["rebound"]),
                        fmt(r.get("rebound_qs", math.nan)),
                        fmt(r["seconds"] + r["seconds_qs"]),
                    ]
                )
    doc.add("Every grid ratio, the first task draw of each size (all draws: `report.json` units).")
    doc.table(
        [
            "rule",
            "N",
            "tau",
            "rho",
            "T / tau",
            "T_qs / tau",
            "T / T_qs",
            "error at t_qs",
            "quasi-static error",
            "final error",
            "rebound",
            "QS rebound",
            "s",
        ],
        rows,
    )
    doc.add(
        "t_qs = learning_times / (alpha k), the quasi-static learning window (T_qs and the "
        "quasi-static error are taken there); each physical run lasts max(t_qs, "
        f"{spec.relaxation_times:g} tau), and its quasi-static reference the same. 'rebound': "
        "the oscillation criterion's factor (only where the run is above the quasi-static "
        "error); 'QS rebound': the quasi-static run's own rebound over the same window."
    )
    crit_rows = []
    for name, units in rules.items():
        for u in units:
            m = u.meta
            crit_rows.append(
                [
                    _NAMES[name],
                    m["n_nodes"],
                    m.get("draw", 0),
                    fmt(m["tau"]),
                    fmt(m["tau_force"]),
                    _bracket(m),
                    m["critical_by"],
                    m.get("non_monotone", 0),
                ]
            )
    doc.add("Critical ratio per size and task draw:")
    doc.table(
        ["rule", "N", "draw", "tau", "tau_force", "rho* bracket", "hi met by", "non-monotone"],
        crit_rows,
    )
    _summary(doc, rules, tasks)
    figures(doc, rules, tasks, ratios, _NAMES)
    _findings(doc, rules, ratios)
    modes_section(doc, tasks)


def _coupling_summary(rules: dict[str, list]) -> str:
    """One computed sentence: how many run units (size x draw x rule x medium) are decoupled,
    by :func:`~.physical_time_findings.coupling_reason`'s measurement, and what follows."""
    units = [u for group in rules.values() for u in group]
    decoupled = decoupled_count(units)
    if decoupled is None:
        return (
            "Coupling (learning.coupling) is not measured for every run: the learning-speed "
            "and critical-ratio findings are not comparable (a task met by prestress alone "
            "would look learned)."
        )
    shares = [u.meta["source_share"] for u in units]
    return (
        f"Coupling of the final learned states (learning.coupling; per size, draw, rule and "
        f"medium the least source share over the ratios run): {decoupled} of {len(units)} "
        f"decoupled, shares {fmt(min(shares))} to {fmt(max(shares))}"
        + (
            ": what the rules learned is prestress on the targets, not a response to the "
            "sources, so the learning-speed and critical-ratio findings are not comparable."
            if decoupled
            else "."
        )
    )
