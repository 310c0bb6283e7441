"""pyvista renders of learning runs and of networks beside continua."""

from __future__ import annotations

import numpy as np

from ..document import (
    Document,
)


def learning_renders(doc: Document, result) -> None:
    """The initial and trained networks of the first exported trial (pyvista)."""
    units = result.select("fields/")
    if not units:
        return
    if not doc.renders_heading():
        return
    from ...io.render import render_networks
    from ...network.model import SpringNetwork

    def state(a, k: int, stage: str):
        p = f"t{k}/{stage}/"
        if p + "x" not in a:
            return None
        net = SpringNetwork(
            a[p + "positions"], a[p + "springs"], a[p + "stiffness"], a[p + "rest_length"]
        )
        return net, a[p + "x"]

    # one trial (the first exported) per rule, initial and trained side by side in one
    # frame with a length scale; every rule starts from the same network; one colour scale
    todo = []
    initial = None
    for key, u in units.items():
        a = u.arrays
        if not u.meta["trials"]:
            continue
        k = u.meta["trials"][0]
        initial = initial or state(a, k, "initial")
        final = state(a, k, "final")
        if final is not None:
            src = np.asarray(a[f"t{k}/sources"], dtype=int)
            todo.append((key.split("/")[-1], k, final, src, a[f"t{k}/targets"]))
    if not todo or initial is None:
        return
    # colour limits from the initial network, every spring but the sources (clamped, they
    # would dominate); a trained network may strain far more (it saturates)
    net0, x0 = initial
    clim = float(np.max(np.abs(np.delete(net0.strains(x0), todo[0][3])))) or 1.0
    for rule, k, (net, x), src, tgt in todo:
        path = doc.folder / f"render_{rule}_t{k}.png"
        render_networks(
            [(net0, x0, f"initial, trial {k}"), (net, x, f"{rule} trained, trial {k}")],
            path,
            sources=src,
            targets=tgt,
            clim=clim,
            window_size=(1120, 560),
            line_width=3.0 if net.n_springs < 200 else 1.5,
        )
        doc.image(
            path,
            f"{rule}, trial {k}: the initial (left) and trained (right) networks in their free "
            "states, in one frame with a length scale; springs coloured by strain (limits "
            f"+-{clim:.3g} in both: the largest strain of the initial network but its sources; "
            "larger strains saturate); green halo: source, orange halo: target.",
        )


def side_by_side(doc: Document, result, prefix: str, what: str) -> None:
    """Network (and continuum, when solved) of the last unit under ``prefix`` (pyvista)."""
    units = [u for u in result.select(prefix).values() if "net/x" in u.arrays]
    if not units:
        return
    if not doc.renders_heading():
        return
    from ...io.render import render_network
    from ...io.render_continuum import render_side_by_side
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
            continuum_bar_title="principal strain (largest magnitude)",
        )
        doc.image(
            path,
            f"n = {n}: spring strain of the network (left) and the signed principal strain "
            "of largest magnitude of the continuum (right), same colour limits "
            f"+-{clim:.3g} "
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
