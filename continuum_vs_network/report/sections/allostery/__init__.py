"""Report section of an ``allostery`` scene: do jammed networks learn genuine allostery with
the package's default rule objects?

Computed from the scene's stored units by the rules stated in the text (it runs nothing):
the feasibility map first (share of draws the bounded optimum solves against the
source-target distance, as Rocks et al. 2017), then for every (size, task, dof) a summary
table per rule beside the optimum's row, the verdict of every draw, C/C0 against steps and
seconds, the source sweeps and a render of one trained network. Numbers:
:mod:`.data`; figures: :mod:`.figures`.
"""

from __future__ import annotations

from ....learning.coupling import COUPLED_AT, DECOUPLED_BELOW, MET_AT
from ....learning.ranges import REST_LENGTH_RANGE, STIFFNESS_RANGE
from ....scenes.units_allostery import CLAMPED, FEASIBLE, RULES, _rule, steps_of
from ...document import Document, fmt
from ...findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding
from .data import LEARNED, RULE_NAMES, feasibility_map, groups, optimum_summary, tally
from .figures import curve_panels, map_panel, render, sweep_panels
from .noise import noise_section

__all__ = ["CLAIM_SHARE", "section"]

#: The share of feasible draws a rule must learn (coupled) for the finding to hold.
CLAIM_SHARE = 0.75
TASK_NAMES = {"1to1": "1 -> 1 (Rocks 2017)", "10to3": "10 -> 3 (Stern 2021)"}
DOF_NAMES = {"stiffness": "k", "rest_length": "L", "both": "k and L"}


def _rates(rules, step=None, alpha=None) -> str:
    parts = []
    for rule in rules:
        r = _rule(rule, "stiffness", step=None if alpha is not None else step, alpha=alpha)
        rate = r.adaptive
        parts.append(
            f"{RULE_NAMES[rule]} ({RULES[rule]}): "
            + (
                f"the paper's raw rate alpha = {r.alpha:g}"
                if rate is None
                else f"{type(rate).__name__.lower()} rate, step {rate.step:g}"
            )
        )
    return "; ".join(parts)


def _intro(doc: Document, scene, grps) -> None:
    a = scene.allostery
    first = {g.n: g.opt[0] for g in reversed(grps)}  # draw 0 of each size
    sizes = ", ".join(
        f"N = {n} discs: {first[n].n_nodes} nodes, {first[n].n_springs} springs in draw 0"
        for n in a.n_nodes
    )
    dz = "" if a.dz is None else f", pruned to Z = Z_iso + {a.dz:g}"
    doc.add(
        "",
        f"**Network.** Jammed packings of bidisperse discs at phi = {a.phi:g}{dz} "
        f"({sizes}); contacts become springs with k = 1/L. Near isostaticity (few springs "
        "above rigidity) a jammed network has the soft, spatially extended modes that carry "
        "a local strain far; it is the field's allostery setting (Rocks et al. 2017, PNAS; "
        "Stern et al. 2021, PRX).",
        "",
        f"**Task.** {', '.join(TASK_NAMES[t] for t in a.tasks)}: sources drawn at random, "
        f"strained by {a.source_strain:g}; targets about {a.distance:g} box sizes from the "
        f"nearest source, asked for S_T = ratio x S_S with ratio = +{abs(a.ratio):g} on even "
        f"draws and -{abs(a.ratio):g} on odd ones. Every task is trained with its rest example "
        "(sources off, targets at their untrained strains: `anchored`), so prestress alone "
        "cannot meet it; sources and targets do not learn (bulk learning). Every rule of a "
        f"draw trains the same network on the same task; {a.draws} draws.",
        "",
        "**Rules and rates.** "
        + (
            "The package's default rule objects, nothing tuned: "
            if a.alpha is None and a.step is None
            else "The package's rule objects at the scene's rate: "
        )
        + f"{_rates(a.rules, a.step, a.alpha)} (`learning/rates.py`: the adaptive rate is per "
        "spring and scale-free; the scaled rate is fixed after the first step). Learned "
        f"stiffnesses stay within [{STIFFNESS_RANGE[0]:g}, {STIFFNESS_RANGE[1]:g}] x k0 "
        "(`learning/ranges.py`, every rule and the optimum); the optimum keeps rest lengths "
        f"within [{REST_LENGTH_RANGE[0]:g}, {REST_LENGTH_RANGE[1]:g}] x L0. Steps: "
        + ", ".join(f"{RULE_NAMES[r]} {steps_of(scene, r)}" for r in a.rules)
        + (
            " (the clamped-only rules run fewer steps to keep the scene cheap)."
            if any(steps_of(scene, r) != a.steps for r in a.rules if r in CLAMPED)
            else "."
        ),
        "",
        "**Verdict.** The bounded optimum of every draw (L-BFGS-B on the exact gradient "
        "within the same range) says what the task allows: a draw whose optimum does not "
        f"reach C/C0 <= {FEASIBLE:g} is *infeasible*, flagged with its optimum C/C0 and "
        "counted apart, never in a success rate. On a feasible draw a rule's verdict is its "
        f"outcome: *{LEARNED}* when its final C/C0 <= {MET_AT:g} and the sources cause at "
        f"least {COUPLED_AT:g} of the target's response (source share; *decoupled* below "
        f"{DECOUPLED_BELOW:g}: met trivially); *not met* otherwise. Medians are over the "
        "feasible draws.",
        "",
    )


def _map(doc: Document, scene, units) -> None:
    a = scene.allostery
    doc.heading("Feasibility map", 3)
    panels, lines = [], []
    for n in a.n_nodes:
        for task in a.tasks:
            fmap = feasibility_map(scene, units, n, task)
            if fmap is None:
                continue
            panels.append(map_panel(fmap, scene, f"N = {n}, {TASK_NAMES[task]}"))
            for j, q in enumerate(a.map_ratios):
                shares = ", ".join(
                    f"{fmt(d, 2)}: {fmt(s, 2)}"
                    for d, s in zip(fmap["distance"][:, j], fmap["share"][:, j], strict=True)
                )
                lines.append(
                    f"- N = {n}, {TASK_NAMES[task]}, |ratio| = {q:g}: "
                    f"share feasible at distance {shares}"
                )
    if not panels:
        doc.add("No feasibility map in this scene (map_draws = 0).", "")
        return
    doc.add(
        f"Share of {a.map_draws} draws per point whose bounded optimum (learning "
        f"{DOF_NAMES[a.dofs[0]]}) reaches C/C0 <= {FEASIBLE:g}, against the source-target "
        "distance (median distance measured over the draws) and the response ratio"
        + (f", at dz = {a.dz:g}" if a.dz is not None else "")
        + f". Optimum only (no rule trains here); {a.map_draws} draws per point is a small "
        "sample (a share is known to about +-1/sqrt(draws)).",
        "",
        *lines,
        "",
    )
    doc.figure(
        "allostery_map",
        panels,
        "Feasibility map: share of draws the bounded "
        "optimum solves against source-target distance, one line per response ratio.",
        ncols=min(2, len(panels)),
    )


def _finding(doc: Document, g, t) -> None:
    name = RULE_NAMES[t.rule]
    if t.feasible == 0:
        v = NOT_COMPARABLE
    else:
        v = REPRODUCED if t.share >= CLAIM_SHARE else NOT_REPRODUCED
    doc.finding(
        Finding(
            claim=f"{name} on {DOF_NAMES[g.dof]} learns the {g.task.replace('to', '-to-')} task "
            f"(coupled) in >= {CLAIM_SHARE:.0%} of feasible draws within the step budget "
            f"(jammed N = {g.n})",
            metric=f"draws learned (coupled) over feasible draws (optimum C/C0 <= {FEASIBLE:g})",
            measured={"learned": t.learned, "feasible": t.feasible, "share": t.share},
            verdict=v,
            rule=f"reproduced when learned / feasible >= {CLAIM_SHARE:g}, not reproduced "
            "otherwise; not comparable without a feasible draw",
            source="field",
            basis="coupled" if t.learned else "",
        )
    )


def _group(doc: Document, scene, g) -> None:
    a = scene.allostery
    doc.heading(f"N = {g.n}, task {TASK_NAMES[g.task]}, learning {DOF_NAMES[g.dof]}", 3)
    tallies = [tally(g, r) for r in a.rules]
    o = optimum_summary(g)
    infeasible = o["draws"] - o["feasible"]
    doc.add(
        f"{o['feasible']} of {o['draws']} draws are feasible ({infeasible} infeasible, "
        "counted apart). "
        + " ".join(
            f"{RULE_NAMES[t.rule]} learned (coupled) {t.learned} of {t.feasible} feasible draws."
            for t in tallies
        ),
        "",
    )
    rows = [
        [
            RULE_NAMES[t.rule],
            steps_of(scene, t.rule),
            f"{t.learned} / {t.feasible}",
            fmt(t.ratio, 2),
            f"{fmt(t.steps_to['0.01'])} ({t.reached['0.01']})",
            f"{fmt(t.steps_to['0.001'])} ({t.reached['0.001']})",
            fmt(t.seconds, 2),
            fmt(t.contrast, 2),
        ]
        for t in tallies
    ]
    rows.append(
        [
            "optimum (what the task allows)",
            f"{fmt(o['evaluations'])} evaluations",
            f"{o['feasible']} / {o['draws']} feasible",
            fmt(o["ratio"], 2),
            "-",
            "-",
            fmt(o["seconds"], 2),
            fmt(o["contrast"], 2),
        ]
    )
    doc.table(
        [
            "rule",
            "steps",
            "learned (coupled) / feasible",
            "median final C/C0",
            "median steps to C/C0 <= 1e-2 (draws)",
            "median steps to C/C0 <= 1e-3 (draws)",
            "median seconds",
            "median contrast max(k/k0)/min(k/k0)",
        ],
        rows,
    )
    doc.add("Verdict of every draw (ratio sign, optimum C/C0, each rule's verdict):", "")
    doc.table(
        ["draw", "ratio", "optimum C/C0", *(RULE_NAMES[r] for r in a.rules)],
        [
            [
                i,
                f"{g.train[a.rules[0]][i].task_ratio:+.2g}",
                fmt(g.opt[i].ratio, 2),
                *(t.verdicts[i] for t in tallies),
            ]
            for i in range(o["draws"])
        ],
    )
    _clamped_note(doc, g, tallies)
    if g.dof == "stiffness":
        for t in tallies:
            if t.rule in ("gcl", "exact"):
                _finding(doc, g, t)
    stem = f"allostery_n{g.n}_{g.task}_{g.dof}"
    doc.figure(
        f"{stem}_curves",
        curve_panels(g, a.rules, o["ratio"]),
        "C/C0 against learning steps (left) and against the rule's own wall-clock "
        "seconds (right; free states measured only for the record left out), one thin "
        "line per feasible draw and rule, the median bold, the optimum's median C/C0 "
        f"dashed, C/C0 = {MET_AT:g} dotted.",
    )
    doc.figure(
        f"{stem}_sweeps",
        sweep_panels(g, a.rules),
        "Source sweeps of the feasible draws: first target's strain change from its "
        "rest strain over the desired change, against the source scale lambda; trained "
        "(colour) and untrained (grey). A learned target follows the diagonal: 0 at "
        "lambda = 0, 1 at lambda = 1.",
        ncols=min(4, len(a.rules)),
    )
    _render(doc, g, a.rules, tallies)


def _clamped_note(doc: Document, g, tallies) -> None:
    """Why the clamped-only rules do not learn a stiffness task, where they did not."""
    stuck = [t for t in tallies if t.rule in CLAMPED and t.learned == 0 and t.feasible]
    if g.dof != "stiffness" or not stuck:
        return
    doc.add(
        "Why "
        + " and ".join(RULE_NAMES[t.rule] for t in stuck)
        + " do not learn here: their stiffness lines, -(alpha/2) (r^C - L)^2 (GPC) and "
        "-(alpha/2) k S^C^2 (aging), are <= 0 for every spring. They descend the energy of "
        "the clamped state (sources and targets held at the task's strains), which asks "
        "nothing of the free state's response, so every stressed spring only softens, "
        "towards the range's floor "
        f"({STIFFNESS_RANGE[0]:g} k0; median contrast reached: "
        + ", ".join(f"{RULE_NAMES[t.rule]} {fmt(t.contrast, 2)}" for t in stuck)
        + f", the floor's 1/{STIFFNESS_RANGE[0]:g} = {1 / STIFFNESS_RANGE[0]:g} when reached).",
        "",
    )


def _render(doc: Document, g, rules, tallies) -> None:
    """Render the first draw a rule learned (GCL first), else the first feasible one."""
    pick = None
    for t in sorted(tallies, key=lambda t: t.rule != "gcl"):
        hits = [i for i, v in enumerate(t.verdicts) if v == LEARNED]
        if hits:
            pick = (t.rule, hits[0])
            break
    if pick is None:
        pick = (rules[0], 0)
    rule, i = pick
    u = g.train[rule][i]
    path = doc.folder / f"fig_allostery_n{g.n}_{g.task}_{g.dof}_render.png"
    title = f"{RULE_NAMES[rule]}, draw {i}: {u.outcome}"
    doc.image(
        render(u, path, title, doc.dpi),
        f"Trained network ({RULE_NAMES[rule]}, draw {i}, ratio "
        f"{u.task_ratio:+.2g}, final C/C0 {fmt(u.ratio, 2)}): springs "
        "coloured by their learned change log10(k/k0) (red stiffer, blue softer), "
        "source green, target black.",
    )


def section(doc: Document, result) -> None:
    scene = result.scene
    units = result.units
    grps = groups(scene, units)
    _intro(doc, scene, grps)
    if scene.allostery.noise != (0.0,) or scene.allostery.etas:
        for g in grps:
            noise_section(doc, scene, g)
        return
    _map(doc, scene, units)
    for g in grps:
        _group(doc, scene, g)
    if grps:
        _headline(doc, scene, grps[0])


def _headline(doc: Document, scene, g) -> None:
    """The README's first result: the first group's tallies beside its optimum."""
    o = optimum_summary(g)
    rows = [
        [
            f"{RULE_NAMES[t.rule]} (default `{RULES[t.rule]}`)",
            f"{t.learned} / {t.feasible}",
            fmt(t.ratio, 2),
            f"{fmt(t.steps_to['0.001'])} ({t.reached['0.001']} draws)",
            fmt(t.seconds, 2),
        ]
        for t in (tally(g, r) for r in scene.allostery.rules)
    ]
    rows.append(
        [
            "bounded optimum (what the task allows)",
            f"{o['feasible']} / {o['draws']} draws feasible",
            fmt(o["ratio"], 2),
            f"{fmt(o['evaluations'])} evaluations",
            fmt(o["seconds"], 2),
        ]
    )
    doc.summary(
        "headline",
        f"Jammed networks learn allostery: N = {g.n} discs, task {TASK_NAMES[g.task]} with its "
        f"rest example, learning {DOF_NAMES[g.dof]}, {len(g.opt)} draws, default rule objects",
        [
            "rule",
            "learned (coupled) / feasible draws",
            "median final C/C0",
            "median steps to C/C0 <= 1e-3",
            "median seconds",
        ],
        rows,
    )
