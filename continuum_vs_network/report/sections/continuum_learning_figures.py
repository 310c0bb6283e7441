"""Figures of the ``continuum_learning`` section (:mod:`.continuum_learning`): the learned
rest strain of the network and of the continuum at every refinement, and the pyvista
renders.
"""

from __future__ import annotations

import numpy as np

from ..document import mesh_name
from .continuum_learning_measures import _magnitude


def _field_figure(doc, units, rule: str, refine: int) -> None:
    """Learned rest-strain magnitude: network on its triangles | continuum at every h."""
    from ...io.atomic import atomic_path
    from ..figures import _pyplot

    plt = _pyplot()
    net = units[f"continuum_learning/network/{rule}"].arrays
    panels = [
        (
            "network (rest-length change per triangle)",
            net["points"],
            net["triangles"],
            _magnitude(np.asarray(net["coarse"])),
        )
    ]
    for r in range(refine + 1):
        a = units[f"continuum_learning/refine{r}/{rule}"].arrays
        panels.append(
            (
                f"continuum {mesh_name(r)}",
                a["points"],
                a["triangles"],
                _magnitude(np.asarray(a["field"])),
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
    dest = doc.folder / f"fig_continuum_fields_{rule}.png"
    with atomic_path(dest) as tmp:
        fig.savefig(tmp, format="png", dpi=doc.dpi, metadata={"Software": None})
    plt.close(fig)
    doc.image(
        dest,
        f"Learned rest strain |eps0| ({rule}): the network's rest-length changes as the rest "
        "strain of each lattice triangle (left) and the continuum's eigenstrain at every "
        "refinement, one colour scale.",
    )


def _renders(doc, units, rule: str, R: int, render: bool, reason: str) -> None:
    """pyvista renders of the network's and the finest continuum's learned fields."""
    doc.heading("Renders", 3)
    if not render:
        doc.add(f"Renders skipped: {reason}.")
        return
    from ...io.render_continuum import render_continuum

    shown = [
        ("network", units[f"continuum_learning/network/{rule}"].arrays, "coarse"),
        (
            f"continuum {mesh_name(R)}",
            units[f"continuum_learning/refine{R}/{rule}"].arrays,
            "field",
        ),
    ]
    vmax = max(float(np.max(_magnitude(np.asarray(a[f])))) for _, a, f in shown) or 1.0
    for name, a, f in shown:
        pts = np.asarray(a["points"], dtype=float)
        path = render_continuum(
            pts,
            a["triangles"],
            np.zeros_like(pts),
            _magnitude(np.asarray(a[f])),
            doc.folder / f"render_learned_{name.replace(' ', '_').replace('/', '_')}.png",
            clim=(0.0, vmax),
            scale=0.0,
            location="cell",
            window_size=(700, 600),
            title=f"{name}: learned rest strain ({rule})",
            scalar_bar_title="|rest strain|",
        )
        doc.image(path, f"pyvista: {name}, |learned rest strain| ({rule}), shared colour scale.")
