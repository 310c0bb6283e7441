"""Report section of a ``continuum_learning`` scene: network against continuum learning.

Everything here is computed from the scene's stored units by the rules stated in the text
(it runs nothing): error against steps and seconds, steps to ``C / C0 <= 1e-3``, the learned
fields side by side on the lattice's triangles, their change under refinement, their
localisation, and the paper's 1 -> 1 task in the continuum.

This module writes the section in order; its parts: :mod:`.continuum_learning_measures`
(steps, field summary, thresholds), :mod:`.continuum_learning_format`,
:mod:`.continuum_learning_figures` (fields, renders), :mod:`.continuum_learning_findings`
(the verdict rules), :mod:`.continuum_learning_relaxation`, :mod:`.continuum_learning_paper`.
"""

from __future__ import annotations

import numpy as np

from ...learning.coupling import DECOUPLED_BELOW
from ..document import Document, fmt, mesh_name
from ..figures import COLORS, Panel, Series
from .continuum_learning_figures import _field_figure, _renders
from .continuum_learning_findings import (
    _rules_agree,
    _verdicts,
    agreed_coupling,
    fields_agree_verdict,
)
from .continuum_learning_findings import _same_coupling as _same_coupling
from .continuum_learning_measures import (
    LOCALISED,
    SETTLED,
    SHRINK,
    TOLERANCE,
    field_summary,
    steps_to,
)
from .continuum_learning_measures import _magnitude as _magnitude
from .continuum_learning_paper import _paper
from .continuum_learning_relaxation import _relaxation

__all__ = [
    "LOCALISED",
    "SETTLED",
    "SHRINK",
    "TOLERANCE",
    "agreed_coupling",
    "field_summary",
    "fields_agree_verdict",
    "section",
    "steps_to",
]


def section(doc: Document, result) -> None:
    """The section (see the module docstring); pyvista renders when ``doc.render``."""
    scene = result.scene
    units = result.units
    R = scene.continuum.refine
    L = scene.learning
    doc.add(
        f"A {scene.network.size} x {scene.network.size} triangular lattice and the elastic "
        f"continuum on its own triangles (P{scene.continuum.order}, lattice Lamé parameters "
        f"lam = mu = sqrt(3) k / 4), refined to h/{2**R}, learn one task: "
        f"{scene.task.n_sources} source and {scene.task.n_targets} target springs (material "
        f"springs in the continuum, clamped and read exactly), strains ~ N(0, "
        f"{scene.task.source_std:g}) and N(0, {scene.task.target_std:g}). The same rule "
        "object trains both media; the network learns rest lengths, the continuum its "
        "eigenstrain field (per unit area, so the rate means the same on every mesh). "
        f"{L.steps} steps. A run *meets* the task when C / C0 <= {TOLERANCE:g}; it *learns* "
        f"it when it meets it and is not decoupled (source share >= {DECOUPLED_BELOW:g}): a "
        "decoupled medium met it trivially, by prestressing its targets."
    )
    for rule in L.rules:
        doc.heading(f"Rule `{rule}`", 3)
        media = [("network", f"continuum_learning/network/{rule}")] + [
            (f"continuum {mesh_name(r)}", f"continuum_learning/refine{r}/{rule}")
            for r in range(R + 1)
        ]
        rows, s_err, s_time = [], [], []
        needed = []
        for i, (name, key) in enumerate(media):
            u = units[key]
            e = np.asarray(u.arrays["error"], dtype=float)
            t = np.asarray(u.arrays["seconds"], dtype=float)
            ratio = e / e[0]
            k = steps_to(e)
            needed.append(k)
            per_step = (t[-1] - t[0]) / max(1, len(t) - 1)
            rows.append(
                [
                    name,
                    u.meta.get("n_dofs", 2 * u.meta.get("n_nodes", 0)),
                    fmt(k),
                    fmt(t[int(k)]) if np.isfinite(k) else "-",
                    fmt(float(ratio[-1])),
                    fmt(1e3 * per_step),
                    f"{fmt(u.meta['source_share'], 2)} ({u.meta['coupling']})",
                    u.meta["outcome"],
                    u.meta["stop_reason"] or "",
                ]
            )
            color = COLORS[i % len(COLORS)]
            s_err.append(Series(np.arange(e.size), ratio, name, color=color))
            s_time.append(Series(t, ratio, name, color=color))
        doc.table(
            [
                "medium",
                "DOFs",
                "steps to 1e-3",
                "seconds to 1e-3",
                f"C/C0 at {L.steps}",
                "ms per step",
                "source share (coupling)",
                "outcome",
                "stopped",
            ],
            rows,
        )
        doc.figure(
            f"continuum_error_{rule}",
            [
                Panel(
                    s_err,
                    "error against steps",
                    "step",
                    "C / C0",
                    yscale="log",
                    hlines=(TOLERANCE,),
                ),
                Panel(
                    s_time,
                    "error against wall time",
                    "seconds",
                    "C / C0",
                    yscale="log",
                    xscale="log",
                    hlines=(TOLERANCE,),
                    legend=False,
                ),
            ],
            f"Task error ({rule}) of the network and of the continuum at every refinement, "
            "against steps and against wall-clock seconds (one run each).",
        )
        summary = field_summary(units, rule, R)
        doc.table(
            [
                "continuum",
                "change from h/2^(r-1) (L2, lattice triangles)",
                "correlation with the network's field",
                f"area with change > {LOCALISED:g} max",
            ],
            [
                [
                    mesh_name(r),
                    fmt(summary["change"][r]),
                    fmt(summary["correlation"][r]),
                    fmt(summary["localised"][r]),
                ]
                for r in range(R + 1)
            ],
        )
        _field_figure(doc, units, rule, R)
        doc.add(*_verdicts(doc, rule, units, summary, needed, R))
    _rules_agree(doc, units, L.rules, R)
    _relaxation(doc, units)
    _paper(doc, units, R, L.rules[0])
    _renders(doc, units, L.rules[0], R, doc.render, doc.render_reason)
