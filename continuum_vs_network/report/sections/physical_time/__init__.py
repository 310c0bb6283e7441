"""physical_time scenes: learning concurrent with the dynamics against the ratio of learning
rate to relaxation rate, the critical ratio against size, and the verdicts.

This module writes the section in order, with the sentences that state the settings the runs
used (GCL phase length, learning steps, quasi-static rebound, continuum tau over network tau,
task draws per size); its parts: :mod:`.runs` (the stored units read per rule, the summary
table with its fits, the figures), :mod:`.findings` (the verdict rules), :mod:`.modes` (the
linear modes behind the relaxation times, against the `relaxation` scene).
"""

from __future__ import annotations

import math

import numpy as np

from ...document import Document, fmt
from .findings import _findings, decoupled_count
from .modes import modes_section
from .runs import _NAMES, _bracket, _by_rule, _not_learned, _summary, _tasks, figures, first_draws


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
    from ....scenes.units_time import FLOOR, OSCILLATION, SLOWDOWN

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
            m = u
            for r in m.runs:
                rows.append(
                    [
                        _NAMES[name],
                        m.n_nodes,
                        fmt(m.tau),
                        fmt(r["ratio"]),
                        fmt(r["T"] / m.tau),
                        fmt(r["T_qs"] / m.tau),
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
            m = u
            crit_rows.append(
                [
                    _NAMES[name],
                    m.n_nodes,
                    m.draw,
                    fmt(m.tau),
                    fmt(m.tau_force),
                    _bracket(m),
                    m.critical_by,
                    m.non_monotone,
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
    by :func:`~.findings.coupling_reason`'s measurement, and what follows."""
    units = [u for group in rules.values() for u in group]
    decoupled = decoupled_count(units)
    if decoupled is None:
        return (
            "Coupling (learning.coupling) is not measured for every run: the learning-speed "
            "and critical-ratio findings are not comparable (a task met by prestress alone "
            "would look learned)."
        )
    shares = [u.source_share for u in units]
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


def _all_runs(units) -> list[dict]:
    """Every ratio run of the units (grid and bisection)."""
    return [r for u in units for r in (*u.runs, *u.bisection)]


def _phase_text(rules: dict) -> str:
    """The GCL phase length as the runs used it (half the learning step), per ratio."""
    c = [
        0.5 * r["dt_learn"] * r["ratio"] / u.tau
        for name, units in rules.items()
        if name.startswith("gcl_phases")
        for u in units
        for r in (*u.runs, *u.bisection)
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
        u.continuum["tau"] / u.network["tau"]
        for u in _tasks(result)
        if u.medium_times("continuum") is not None and u.medium_times("network") is not None
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
        counts[u.n_nodes] = counts.get(u.n_nodes, 0) + 1
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


def stiffness_intro(doc: Document, scene, rules: dict, not_learned: list, vis: str) -> None:
    """The opening paragraphs of a scene that learns stiffnesses (``dof = "stiffness"``),
    one idea each, with the settings the runs used."""
    from ....learning.coupling import MET_AT
    from ....learning.rates import Adaptive
    from ....scenes.units_time import FLOOR, OSCILLATION, SLOWDOWN
    from ....scenes.units_time_reference import REFERENCE_STEPS

    spec = scene.physical_time
    step = Adaptive().step
    doc.add(
        "Learning runs concurrently with the overdamped dynamics of the lattice "
        f"({vis}; k = 1) and of its continuum, as one system of ODEs "
        "(`learning/physical_time.py`). What learns is the stiffness (the continuum: its "
        "modulus field) of a medium that is unstressed at rest: with the sources off every "
        "spring stays at its rest length whatever k is, so learning cannot prestress the "
        "targets and any change of their response comes from the sources. The coupling "
        "measurement below checks this on every run."
    )
    doc.add(
        f"Task: Rocks' response task ({scene.task.n_sources} source, {scene.task.n_targets} "
        f"target; source strain {spec.source_strain:g}, target asked for "
        f"+-{spec.response_ratio:g} of it, sign alternating with the draw, about "
        f"{spec.distance:g} box sizes from the source), sources and targets frozen, both "
        "media driven the same way: a clamp holds only the clamped spring's length (the "
        "network: the spring as a stiff rod at the clamp length, no node held; the "
        "continuum: its material spring's strain, exactly)."
    )
    doc.add(
        "Rule: GCL as twin copies (a free and a nudged copy evolving together, the update "
        f"from their difference; nudge eta = {spec.eta:g}) with the package's adaptive rate "
        f"(per-spring Adam, step {step:g}), run in physical time: one adaptive step per "
        "step time t_s, a learning step dt taking dt / t_s of a step (`learning/time_media.py`"
        ", AdaptiveClock). A raw rate on stiffnesses is ill-conditioned (its line scales with "
        "the squared strain) and did not reach C/C0 = 1e-2 in the steps this scene affords."
        + (
            f" GCL with free and nudged phases: each phase min({spec.phase:g} tau, t_s / 2)."
            if "gcl_phases" in spec.rules
            else ""
        )
    )
    doc.add(
        f"Ratio: rho = {step:g} tau / t_s, the relaxation time tau over the time in which "
        "the adaptive rate may change a stiffness by its own size (the analogue of alpha k "
        "tau for rest lengths, the ratio of learning rate to relaxation rate of Stern et al. "
        "2022). tau: the time after which the target strains stay within 1 % of their total "
        "change after the source step. The tables also give T_qs / tau, the quasi-static "
        "learning time over tau (T_qs / tau = steps_qs x "
        f"{step:g} / rho)."
    )
    doc.add(
        f"Reference: per size, draw and medium a quasi-static run of {REFERENCE_STEPS} "
        "adaptive steps (an equilibrium at every step). The draw counts as learned when it "
        f"reaches C/C0 <= {MET_AT:g} with a coupled verdict; only learned draws run the "
        "ratios"
        + (
            f" ({len(not_learned)} run units of draws not learned are counted apart: "
            + ", ".join(
                f"N = {u.n_nodes} draw {u.draw} {u.medium} ({fmt(u.error_qs)})"
                for u in sorted(
                    not_learned,
                    key=lambda u: (u.n_nodes, u.draw, u.medium),
                )
                if u.rule == spec.rules[0]
            )
            + ", final quasi-static C/C0 in brackets)."
            if not_learned
            else "; every draw learned."
        )
    )
    doc.add(
        "Learning time T: when the error has made all but "
        f"{spec.fraction:g} of its quasi-static drop, in the physical run and in its "
        f"quasi-static twin (same steps). Each run lasts {spec.learning_times:g} quasi-static "
        f"learning times (at least {spec.relaxation_times:g} tau). A run is past the "
        f"quasi-static regime when T / T_qs >= {SLOWDOWN:g} (or it never gets there) or when "
        f"its error climbs back to {OSCILLATION:g} times its running minimum (floored at "
        f"{FLOOR:g}) while above the quasi-static run's error. The critical ratio rho* is a "
        "bracket (lo, hi]: lo the largest ratio run not past, hi the next ratio run; the "
        f"grid's bracket is narrowed by {spec.bisections} bisections in log scale."
    )
