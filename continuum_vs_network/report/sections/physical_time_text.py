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


def stiffness_intro(doc: Document, scene, rules: dict, not_learned: list, vis: str) -> None:
    """The opening paragraphs of a scene that learns stiffnesses (``dof = "stiffness"``),
    one idea each, with the settings the runs used."""
    from ...learning.coupling import MET_AT
    from ...learning.rates import Adaptive
    from ...scenes.units_time import FLOOR, OSCILLATION, SLOWDOWN
    from ...scenes.units_time_reference import REFERENCE_STEPS

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
                f"N = {u.meta['n_nodes']} draw {u.meta['draw']} {u.meta['medium']} "
                f"({fmt(u.meta.get('error_qs'))})"
                for u in sorted(
                    not_learned,
                    key=lambda u: (u.meta["n_nodes"], u.meta["draw"], u.meta["medium"]),
                )
                if u.meta["rule"] == spec.rules[0]
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
