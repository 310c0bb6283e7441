"""Node tasks of the ``beyond_paper`` section (:mod:`.beyond_paper`): absolute and relative
node displacements as the learned output.
"""

from __future__ import annotations

import numpy as np

from ...learning.coupling import MET_AT
from ..figures import COLORS, Panel, Series
from ..findings import NOT_REPRODUCED, REPRODUCED, Finding
from .beyond_paper_format import _g

OUTPUT_NAMES = {
    "absolute": ("absolute node displacements", "x_T"),
    "relative": ("relative node displacements", "x_a - x_b"),
}


def _nodes(doc, scene, units) -> None:
    from ...scenes.units_beyond import GCL_K, node_rules

    t = scene.task
    doc.heading("Node tasks", 3)
    doc.add(
        f"The output is {t.n_targets} node coordinates (nodes away from the {t.n_sources} "
        f"sources) that should move by displacements ~ N(0, {t.target_std:g}) mean rest "
        "lengths: *absolute* (a node's coordinate) or *relative* (node a's coordinate minus "
        "node b's, both away from the sources); C = sum (y_T - y_T*)^2 / 2. Every rule holds "
        "the outputs one way (NodeTask.hold): an absolute output's coordinate is pinned, a "
        "relative output is a two-node constraint held by its reaction, equal and opposite "
        "forces on a and b found by Newton's method on the multipliers. GCL holds the outputs "
        "at its nudge, GPC and directed aging at y*, the exact gradient solves one adjoint. "
        f"`gcl_k` is GCL of the stiffnesses (rate {GCL_K['alpha']:g} / mean k, nudge "
        f"{scene.learning.eta:g}, floor {GCL_K['floor']:g} mean k): a network at rest that "
        "learns only stiffnesses has no prestress, so it can meet the task only by changing "
        "how the sources drive the outputs. Coupling: the source share of the output "
        "displacements (sources on and off); a task met by prestress alone (decoupled) is not "
        "learned.",
        "",
    )
    rules = node_rules(scene)
    panels = []
    for outputs in t.node_outputs:
        name, symbol = OUTPUT_NAMES[outputs]
        rows, series = [], []
        for i, rule in enumerate(rules):
            u = units[f"beyond/node/{outputs}/{rule}"]
            m = u.meta
            e = np.asarray(u.arrays["error"], dtype=float)
            rows.append(
                [rule, m.get("learns", "-"), _g(m["ratio"]),
                 f"{_g(m['source_share'], 2)} ({m['coupling']})", m["outcome"],
                 _g(m["seconds"]), m["stop_reason"] or ""]
            )  # fmt: skip
            series.append(Series(np.arange(e.size), e / e[0], rule, color=COLORS[i % len(COLORS)]))
        doc.add(f"**{name}** (output {symbol}):")
        doc.table(
            ["rule", "learns", "C/C0 at the end", "source share (coupling)", "outcome",
             "seconds", "stopped"],
            rows,
        )  # fmt: skip
        panels.append(Panel(series, name, "step", "C / C0", yscale="log", hlines=(MET_AT,)))
        metas = {r: units[f"beyond/node/{outputs}/{r}"].meta for r in rules}
        learned = [r for r in rules if metas[r]["outcome"].startswith("learned")]
        coupled = [r for r in learned if metas[r]["coupling"] == "coupled"]
        doc.add(
            f"{name.capitalize()}: learned (C/C0 <= {MET_AT:g}, not decoupled) by "
            + (", ".join(learned) if learned else "no rule")
            + "; coupled (source share >= 0.5) among them: "
            + (", ".join(coupled) if coupled else "none")
            + ".",
            "",
        )
        for rule in ("gcl", "gcl_k", "aging"):
            if rule in rules:
                m = units[f"beyond/node/{outputs}/{rule}"].meta
                doc.finding(
                    Finding(
                        claim=f"{rule} learns a task of {name}",
                        metric="final C/C0 and source share of the output displacements",
                        measured={"C/C0": m["ratio"], "source share": m["source_share"]},
                        verdict=REPRODUCED
                        if m["outcome"].startswith("learned")
                        else NOT_REPRODUCED,
                        rule=f"reproduced when C/C0 <= {MET_AT:g} and the network is not "
                        "decoupled (outcome 'learned ...'); a decoupled network met it by "
                        "prestress around the target nodes",
                    )
                )
    doc.figure(
        "beyond_node",
        panels,
        "Node tasks: error against steps of every rule (one run each, bulk learning), "
        + " and ".join(OUTPUT_NAMES[o][0] for o in t.node_outputs)
        + ".",
    )
