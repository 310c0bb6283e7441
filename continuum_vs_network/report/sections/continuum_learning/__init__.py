"""Report section of a ``continuum_learning`` scene: network against continuum learning.

Everything here is computed from the scene's stored units by the rules stated in the text
(it runs nothing): error against steps and seconds, steps to ``C / C0 <= 1e-3``, the learned
fields side by side on the lattice's triangles, their change under refinement, their
localisation, the relaxation of the learned material (target strains against time after the
sources switch on), and the paper's 1 -> 1 task in the continuum (table and finding at every
refinement).

This module writes the section in order, with its figures (the learned rest strain of the
network and of the continuum at every refinement, and the pyvista renders); the measures and
verdict rules are :mod:`.findings`.
"""

from __future__ import annotations

import math

import numpy as np

from ....learning.coupling import DECOUPLED_BELOW
from ....scenes.results import read_results
from ....scenes.results.continuum_learning import CLASSES, ContinuumRun
from ...document import Document, coupling_text, fmt, mesh_name
from ...figures import COLORS, Panel, Series
from ...findings import NOT_REPRODUCED, REPRODUCED, Finding
from .findings import (
    LOCALISED,
    TOLERANCE,
    _magnitude,
    _rules_agree,
    _verdicts,
    field_summary,
    steps_to,
)

__all__ = ["section"]


def section(doc: Document, result) -> None:
    """The section (see the module docstring); pyvista renders when ``doc.render``."""
    scene = result.scene
    units = read_results(result.units, CLASSES)
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
            e = np.asarray(u.error, dtype=float)
            t = np.asarray(u.seconds_trace, dtype=float)
            ratio = e / e[0]
            k = steps_to(e)
            needed.append(k)
            per_step = (t[-1] - t[0]) / max(1, len(t) - 1)
            rows.append(
                [
                    name,
                    u.n_dofs if isinstance(u, ContinuumRun) else 2 * u.n_nodes,
                    fmt(k),
                    fmt(t[int(k)]) if np.isfinite(k) else "-",
                    fmt(float(ratio[-1])),
                    fmt(1e3 * per_step),
                    coupling_text(u),
                    u.outcome,
                    u.stop_reason or "",
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
    _renders(doc, units, L.rules[0], R)


def _field_figure(doc, units, rule: str, refine: int) -> None:
    """Learned rest-strain magnitude: network on its triangles | continuum at every h."""
    from ...figures import _pyplot, _save

    plt = _pyplot()
    net = units[f"continuum_learning/network/{rule}"]
    panels = [
        (
            "network (rest-length change per triangle)",
            net.points,
            net.triangles,
            _magnitude(np.asarray(net.coarse)),
        )
    ]
    for r in range(refine + 1):
        a = units[f"continuum_learning/refine{r}/{rule}"]
        panels.append(
            (
                f"continuum {mesh_name(r)}",
                a.points,
                a.triangles,
                _magnitude(np.asarray(a.field)),
            )
        )
    vmax = max(float(np.max(p[3])) for p in panels) or 1.0
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.4))
    for ax, (title, pts, tri, val) in zip(np.atleast_1d(axes), panels):
        pts = np.asarray(pts)
        m = ax.tripcolor(
            pts[:, 0], pts[:, 1], np.asarray(tri), facecolors=val, cmap="magma", vmin=0.0, vmax=vmax
        )
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal")
        ax.set_axis_off()
    fig.colorbar(m, ax=list(np.atleast_1d(axes)), shrink=0.8, label="|learned rest strain|")
    dest = _save(fig, doc.folder / f"fig_continuum_fields_{rule}.png", doc.dpi)
    plt.close(fig)
    doc.image(
        dest,
        f"Learned rest strain |eps0| ({rule}): the network's rest-length changes as the rest "
        "strain of each lattice triangle (left) and the continuum's eigenstrain at every "
        "refinement, one colour scale.",
    )


def _renders(doc, units, rule: str, R: int) -> None:
    """pyvista renders of the network's and the finest continuum's learned fields."""
    if not doc.renders_heading(3):
        return
    from ....io.render_continuum import render_continuum

    shown = [
        ("network", units[f"continuum_learning/network/{rule}"].coarse),
        (f"continuum {mesh_name(R)}", units[f"continuum_learning/refine{R}/{rule}"].field),
    ]
    meshes = [units[f"continuum_learning/network/{rule}"]]
    meshes.append(units[f"continuum_learning/refine{R}/{rule}"])
    vmax = max(float(np.max(_magnitude(np.asarray(v)))) for _, v in shown) or 1.0
    for (name, values), a in zip(shown, meshes, strict=True):
        pts = np.asarray(a.points, dtype=float)
        path = render_continuum(
            pts,
            a.triangles,
            np.zeros_like(pts),
            _magnitude(np.asarray(values)),
            doc.folder / f"render_learned_{name.replace(' ', '_').replace('/', '_')}.png",
            clim=(0.0, vmax),
            scale=0.0,
            location="cell",
            window_size=(700, 600),
            title=f"{name}: learned rest strain ({rule})",
            scalar_bar_title="|rest strain|",
        )
        doc.image(path, f"pyvista: {name}, |learned rest strain| ({rule}), shared colour scale.")


def _relaxation(doc, units) -> None:
    """Target strains against time after the sources switch on, both trained media."""
    m = units.get("continuum_learning/relaxation")
    if m is None:
        return
    doc.heading("Relaxation of the learned material", 3)
    strain_clamp = m.network_nodes_settle is not None
    if strain_clamp:
        drive = (
            "Both media are driven by a strain clamp: the continuum holds the source springs' "
            "strains as exact constraints, the network holds each source spring as a stiff "
            f"rod (stiffness {m.rod_factor:.0e} x the mean k, rest length the clamp "
            "length; backward Euler, L-stable), its end nodes free otherwise (the rods' "
            f"largest strain error {m.rod_strain_error:.1e}). For comparison, the network "
            "is also run with its clamps as prescribed end-node displacements (both end nodes "
            "held, so a source spring cannot rotate or translate)"
        )
    else:
        drive = (
            "The continuum holds exact clamps; the network holds its clamps as prescribed "
            "end-node displacements"
        )
    doc.add(
        f"The trained network and the trained continuum (rule `{m.rule}`, on the lattice "
        "triangles) start at rest with the sources off; at t = 0 the sources switch on and "
        "both creep against node drag c = 1 (the continuum: its equivalent substrate drag; "
        f"the network: overdamped dynamics). {drive}. dt = {m.dt:g}, time in units of "
        "c / k."
    )
    runs = [("network, strain clamp" if strain_clamp else "network", "network", "network")]
    if strain_clamp:
        runs.append(("network, end nodes held", "network_nodes", "network_nodes"))
    runs.append(("continuum h, strain clamp", "continuum", None))
    panels, rows = [], []
    for name, key, arr in runs:
        t = getattr(m, f"{arr}_times") if arr else m.times
        s = np.asarray(getattr(m, f"{arr}_strain") if arr else m.continuum_strain)
        d = np.linalg.norm(s - s[-1], axis=1)
        panels.append(Series(t, d / d[0], name))
        rows.append(
            [
                name,
                fmt(getattr(m, f"{key}_settle")),
                fmt(getattr(m, f"{key}_gap")),
                fmt(getattr(m, f"{key}_seconds")),
            ]
        )
    doc.table(
        [
            "medium",
            "time to settle within 10 % of the end values",
            "gap at the end to the exact-clamp free state",
            "seconds",
        ],
        rows,
    )
    caption = (
        "Distance of the target strains from their values at the end of the run after the "
        "sources switch on, trained network and trained continuum (one run each). "
    )
    if strain_clamp:
        caption += (
            "Driven alike (strain clamps), the network and the continuum approach their end "
            "values along similar paths (not identical: the continuum's drag goes by node area "
            "and its boundary edges are softer); holding the network's source springs by their "
            "end nodes changes the path and the end state (its gap in the table)."
        )
    else:
        caption += (
            "The network's clamps move the source springs' end nodes, the continuum's fix "
            "only their strain: the two relax along different paths."
        )
    doc.figure(
        "continuum_relaxation",
        [
            Panel(
                panels,
                "approach of the target strains",
                "time (c / k)",
                "|S(t) - S(end)| / |S(0) - S(end)|",
                yscale="log",
                hlines=(0.1,),
            )
        ],
        caption,
    )


def _paper(doc, units, R: int, rule: str) -> None:
    doc.heading("The paper's 1 -> 1 task in the continuum", 3)
    rows, finals = [], []
    for r in range(R + 1):
        u = units[f"continuum_learning/paper/refine{r}"]
        e = np.asarray(u.error, dtype=float)
        finals.append(float(e[-1] / e[0]) if np.isfinite(e[-1]) else math.inf)
        rows.append(
            [
                mesh_name(r),
                u.n_dofs,
                fmt(u.source_strain[0]),
                fmt(u.target_strain[0]),
                fmt(steps_to(e)),
                fmt(e[-1] / e[0]),
                coupling_text(u),
            ]
        )
    doc.add(
        f"One source and one target material spring with the paper's strains (about 5; "
        f"linear elasticity is scale-free), rule `{rule}`:"
    )
    doc.table(
        [
            "continuum",
            "DOFs",
            "source strain",
            "target strain",
            "steps to 1e-3",
            "C/C0 at the end",
            "source share (coupling)",
        ],
        rows,
    )
    worst = max(finals)
    share = min(
        float(units[f"continuum_learning/paper/refine{r}"].source_share) for r in range(R + 1)
    )
    learned = worst <= TOLERANCE and share >= DECOUPLED_BELOW
    doc.finding(
        Finding(
            source="paper",
            claim="paper, discussion (Sec. 1, 8): a visco-elastic material learns the paper's "
            "1 -> 1 task by a local rule (here: an elastic continuum)",
            metric=f"final C/C0 and source share at every refinement (rule {rule})",
            measured={"largest C/C0": worst, "smallest source share": share},
            verdict=REPRODUCED if learned else NOT_REPRODUCED,
            rule=f"reproduced when C/C0 <= {TOLERANCE:g} and the medium is not decoupled "
            f"(source share >= {DECOUPLED_BELOW:g}) at every refinement; a decoupled medium "
            "met the task by prestressing the target",
        )
    )
