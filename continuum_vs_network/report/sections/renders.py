"""pyvista renders of learning runs and of networks beside continua."""

from __future__ import annotations

import numpy as np

from ..document import (
    Document,
)


def learning_renders(doc: Document, result) -> None:
    """The initial and trained networks of the first exported trial (pyvista)."""
    render, reason = doc.render, doc.render_reason
    units = result.select("fields/")
    if not units:
        return
    doc.heading("Renders")
    if not render:
        doc.add(f"Renders skipped: {reason}.")
        return
    from ...io.render import render_network
    from ...network.model import SpringNetwork

    # one trial (the first exported) per rule; every rule starts from the same network, so
    # the initial state is drawn once; one colour scale for every image
    todo = []
    for j, (key, u) in enumerate(units.items()):
        a = u.arrays
        if not u.meta["trials"]:
            continue
        k = u.meta["trials"][0]
        for stage in ("initial", "final") if j == 0 else ("final",):
            p = f"t{k}/{stage}/"
            if p + "x" in a:
                net = SpringNetwork(
                    a[p + "positions"], a[p + "springs"], a[p + "stiffness"], a[p + "rest_length"]
                )
                todo.append(
                    (
                        key.split("/")[-1],
                        k,
                        stage,
                        net,
                        a[p + "x"],
                        np.asarray(a[f"t{k}/sources"], dtype=int),
                        a[f"t{k}/targets"],
                    )
                )
    if not todo:
        return
    # colour limits from the first image (the initial network when drawn), every spring but
    # the sources (clamped, they would dominate); a trained network may strain far more
    _, _, _, net0, x0, src0, _ = todo[0]
    clim = float(np.max(np.abs(np.delete(net0.strains(x0), src0)))) or 1.0
    for rule, k, stage, net, x, src, tgt in todo:
        label = rule if stage == "final" else "every rule"
        name = f"render_{rule}_t{k}_final.png" if stage == "final" else f"render_t{k}_initial.png"
        path = doc.folder / name
        render_network(
            net,
            x,
            path,
            sources=src,
            targets=tgt,
            clim=clim,
            window_size=(560, 560),
            line_width=3.0 if net.n_springs < 200 else 1.5,
            title=f"{label}, trial {k}, {stage} free state",
        )
        doc.image(
            path,
            f"{label}, trial {k}: {stage} network in its free state, springs "
            f"coloured by strain (limits +-{clim:.3g} in every image: the largest strain of "
            f"the {todo[0][2]} network but its sources; larger strains saturate); green: "
            "source, orange: target.",
        )


def side_by_side(doc: Document, result, prefix: str, what: str) -> None:
    """Network (and continuum, when solved) of the last unit under ``prefix`` (pyvista)."""
    render, reason = doc.render, doc.render_reason
    units = [u for u in result.select(prefix).values() if "net/x" in u.arrays]
    if not units:
        return
    doc.heading("Renders")
    if not render:
        doc.add(f"Renders skipped: {reason}.")
        return
    from ...io.render import render_network, render_side_by_side
    from ...network.model import SpringNetwork

    u = units[-1]
    a = u.arrays
    net = SpringNetwork(
        a["net/positions"], a["net/springs"], a["net/stiffness"], a["net/rest_length"]
    )
    x = a["net/x"]
    sources = a["net/sources"] if "net/sources" in a else ()
    strain = net.strains(x)
    others = np.delete(strain, np.asarray(sources, int)) if len(sources) else strain
    # a point source: saturate the near field so the far field shows; a uniform step: no
    fraction = 0.3 if len(sources) else 1.0
    clim = fraction * float(np.max(np.abs(others))) or 1.0
    n = u.meta["n"]
    if "cont/points" in a:
        path = doc.folder / f"render_{what}_n{n}.png"
        render_side_by_side(
            net,
            x,
            a["cont/points"],
            a["cont/triangles"],
            a["cont/displacement"],
            a["cont/principal"],
            path,
            sources=sources,
            network_clim=clim,
            continuum_clim=clim,
            window_size=(1100, 560),
            titles=(f"network n = {n}", "continuum"),
            network_bar_title="spring strain",
            continuum_bar_title="principal strain",
        )
        doc.image(
            path,
            f"n = {n}: spring strain of the network (left) and the largest "
            f"principal strain of the continuum (right), same colour limits +-{clim:.3g} "
            + (
                "(0.3 of the largest spring strain, source excluded; the near field saturates)."
                if len(sources)
                else "(the largest spring strain)."
            ),
        )
    else:
        path = doc.folder / f"render_{what}_n{n}_network.png"
        render_network(
            net,
            x,
            path,
            sources=sources,
            clim=clim,
            window_size=(560, 560),
            title=f"network n = {n}",
        )
        doc.image(path, f"n = {n}: spring strain of the network.")
