"""Node tasks of the ``beyond_paper`` section (:mod:`.`): absolute and relative
node displacements as the learned output, each task trained with its rest example.
"""

from __future__ import annotations

import numpy as np

from ....learning.coupling import MET_AT
from ....scenes.results.beyond_paper import NodeResult
from ...document import coupling_text, fmt
from ...figures import COLORS, Panel, Series
from ...findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding, reasoned, runs_basis

OUTPUT_NAMES = {
    "absolute": ("absolute node displacements", "x_T"),
    "relative": ("relative node displacements", "x_a - x_b"),
}


#: the rules whose "learns a node task" claim is judged
JUDGED = ("gcl", "gcl_k", "gcl_both", "exact", "aging")


def node_verdict(rule: str, metas: dict[str, NodeResult]) -> tuple[str, str]:
    """Verdict of "``rule`` learns the node task" and the reason when not comparable: the
    optimum does not take node tasks, so a miss counts (not reproduced) only when another
    rule learning the same dof met the task (feasible for it)."""
    m = metas[rule]
    if m.outcome.startswith("learned"):
        return REPRODUCED, ""
    if m.outcome.startswith("met trivially"):
        return NOT_COMPARABLE, "met by prestress (decoupled), not learned"
    shown = [
        r for r, o in metas.items() if o.learns == m.learns and o.outcome.startswith("learned")
    ]
    if shown:
        return NOT_REPRODUCED, ""
    return NOT_COMPARABLE, (
        f"no rule learning {m.learns} met it and the optimum does not take node tasks, "
        "so whether it is feasible for that dof is not known"
    )


def _nodes(doc, scene, units) -> None:
    from ....scenes.units_beyond import node_rules

    t = scene.task
    doc.heading("Node tasks", 3)
    doc.add(
        f"The output is {t.n_targets} node coordinate(s) (nodes away from the {t.n_sources} "
        f"source(s)) that should move by displacements ~ N(0, {t.target_std:g}) mean rest "
        "lengths: *absolute* (a node's coordinate) or *relative* (node a's coordinate minus "
        "node b's, both away from the sources); C = sum (y_T - y_T*)^2 / 2. Every task is "
        "trained with its rest example (sources off, outputs asked to stay where the "
        "untrained network puts them), so prestress alone cannot meet it. Every rule holds "
        "the outputs one way (NodeTask.hold): an absolute output's coordinate is pinned, a "
        "relative output is a two-node constraint held by its reaction. Default rules "
        f"(nothing tuned), {scene.learning.steps} steps; `gcl_k` learns only stiffnesses. "
        "Coupling: the source share of the output displacements (sources on and off). The "
        "optimum does not take node tasks: a rule's miss counts against it only when a rule "
        "learning the same dof met the task.",
        "",
    )
    rules = node_rules(scene)
    panels = []
    for outputs in t.node_outputs:
        name, symbol = OUTPUT_NAMES[outputs]
        rows, series = [], []
        for i, rule in enumerate(rules):
            m: NodeResult = units[f"beyond/node/{outputs}/{rule}"]
            e = np.asarray(m.error, dtype=float)
            rows.append(
                [rule, m.learns, fmt(m.ratio),
                 coupling_text(m), m.outcome,
                 fmt(m.seconds), (m.stop_reason or "")[:80]]
            )  # fmt: skip
            series.append(Series(np.arange(e.size), e / e[0], rule, color=COLORS[i % len(COLORS)]))
        doc.add(f"**{name}** (output {symbol}):")
        doc.table(
            ["rule", "learns", "C/C0 at the end", "source share (coupling)", "outcome",
             "seconds", "stopped"],
            rows,
        )  # fmt: skip
        panels.append(Panel(series, name, "step", "C / C0", yscale="log", hlines=(MET_AT,)))
        metas = {r: units[f"beyond/node/{outputs}/{r}"] for r in rules}
        learned = [r for r in rules if metas[r].outcome.startswith("learned")]
        doc.add(
            f"{name.capitalize()}: learned (C/C0 <= {MET_AT:g}, not decoupled) by "
            + (", ".join(learned) if learned else "no rule")
            + ".",
            "",
        )
        for rule in JUDGED:
            if rule not in rules:
                continue
            m = metas[rule]
            verdict, reason = node_verdict(rule, metas)
            doc.finding(
                Finding(
                    claim=f"{rule} learns a task of {name} (with its rest example)",
                    metric="final C/C0 and source share of the output displacements",
                    measured={"C/C0": m.ratio, "source share": m.source_share},
                    verdict=verdict,
                    rule=reasoned(
                        f"reproduced when C/C0 <= {MET_AT:g} and the network is not "
                        "decoupled; not reproduced when it misses a task that a rule learning "
                        "the same dof learned",
                        verdict,
                        reason,
                    ),
                    source="field",
                    basis=runs_basis([m]),
                )
            )
    doc.figure(
        "beyond_node",
        panels,
        "Node tasks: error against steps of every rule (one run each, bulk learning, with the "
        "rest example), " + " and ".join(OUTPUT_NAMES[o][0] for o in t.node_outputs) + ".",
    )
