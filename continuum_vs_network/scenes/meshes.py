"""The meshes of a scene result, written for ParaView with :mod:`continuum_vs_network.io.export`.

Only a scene with an ``[export]`` table writes meshes (``cvn export`` adds a default table).
What is written (``meshes/<scene>/`` by default):

* learning: ``<solver>_<rule>_t<k>_initial.vtu`` / ``_final.vtu`` (free states of the
  exported trials, springs with a ``role`` array: 0 hidden, 1 source, 2 target) and, with
  ``series = true``, ``<solver>_<rule>_t<k>_trajectory.pvd`` (one frame per ``every``
  learning steps; time = learning step);
* transmission (largest lattice): ``network_n<n>.vtu`` and ``continuum_n<n>.vtu``
  (displacement, strain and stress tensors, largest principal strain);
* continuum_learning: ``learned_<medium>_<rule>.vtu``, the learned rest strain as cell
  data (tensor, magnitude, principal direction, dilation; ``frozen`` elements) on the
  network's triangles (the network's rest-length changes) or the continuum's mesh;
* relaxation (largest lattice): ``network_n<n>_final.vtu``, ``continuum_n<n>_final.vtu`` and,
  with ``series = true``, ``network_n<n>_relaxation.pvd`` (time = physical time);
* physical_time (largest lattice, ``series = true``): ``<rule>_n<n>_physical_time.pvd``, the
  moving network learning in physical time at the ratio nearest 1 (one frame per output
  time; time = physical time; :func:`~continuum_vs_network.io.export.time_history_series`),
  and ``<rule>_n<n>_continuum_physical_time.pvd``, the moving body (displacement, learned
  ``eigenstrain`` tensor and ``modulus`` per element;
  :func:`~continuum_vs_network.io.export.body_history_series`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .results import from_stored
from .results.physical_time import TimeRunResult
from .runner import SceneResult

__all__ = ["export_meshes"]


def _net(a: dict, prefix: str):
    from ..network.model import SpringNetwork

    return SpringNetwork(
        a[prefix + "positions"],
        a[prefix + "springs"],
        a[prefix + "stiffness"],
        a[prefix + "rest_length"],
    )


def _tensor9(eps: np.ndarray) -> np.ndarray:
    """(n, 3) rows ``(xx, yy, xy)`` -> (n, 9) ParaView tensors (out-of-plane entries 0)."""
    out = np.zeros((eps.shape[0], 9))
    out[:, 0], out[:, 4] = eps[:, 0], eps[:, 1]
    out[:, 1] = out[:, 3] = eps[:, 2]
    return out


def _learned_field_mesh(key: str, a: dict, folder: Path) -> Path:
    """A learned rest-strain field as cell data on its triangles (undeformed body)."""
    from ..continuum.learned_fields import field_direction, field_magnitude
    from ..io.export import continuum_mesh, write_mesh

    eps = np.asarray(a["field"] if "field" in a else a["coarse"], dtype=float)
    points = np.asarray(a["points"], dtype=float)
    fields = {
        "rest_strain": _tensor9(eps),
        "rest_strain_magnitude": field_magnitude(eps),
        "rest_strain_direction": field_direction(eps),
        "dilation": 0.5 * (eps[:, 0] + eps[:, 1]),
    }
    if "frozen" in a:
        fields["frozen"] = np.asarray(a["frozen"], dtype=bool)
    mesh = continuum_mesh(points, a["triangles"], np.zeros_like(points), cell_fields=fields)
    name = key.removeprefix("continuum_learning/").replace("/", "_")
    return write_mesh(mesh, folder / f"learned_{name}.vtu")


def _time_series(run: TimeRunResult, folder: Path) -> Path:
    """The frames of a physical_time run (its ``series/*`` fields): the moving body, or the
    moving network with its sources and targets."""
    from ..io.export import body_history_series, time_history_series

    a = run.fields
    frames = (a["series/times"], a["series/x"], a["series/rest_length"], a["series/stiffness"])
    if "body/points" in a:
        return body_history_series(
            a["body/points"], a["body/triangles"], *frames, folder,
            f"{run.rule}_n{run.n}_continuum_physical_time",
        )  # fmt: skip
    return time_history_series(
        _net(a, "net/"), *frames, folder, f"{run.rule}_n{run.n}_physical_time",
        sources=a["net/sources"], targets=a["net/targets"],
    )  # fmt: skip


def export_meshes(result: SceneResult, folder: str | os.PathLike[str]) -> list[Path]:
    """Write the meshes of ``result`` to ``folder``; returns the files written (indices of
    series, not their frames). Nothing is written when the scene has no ``[export]``."""
    export = result.scene.export
    if export is None:
        return []
    from ..io.export import continuum_mesh, network_mesh, spring_roles, write_mesh, write_series

    folder = Path(folder)
    written: list[Path] = []
    for key, unit in result.units.items():
        a = unit.arrays
        if key.startswith("physical_time/"):
            if export.series and "series/x" in a:
                written.append(_time_series(from_stored(unit, TimeRunResult), folder))
            continue
        if key.startswith("continuum_mechanism/"):
            from .meshes_mechanism import mechanism_field_mesh

            if (path := mechanism_field_mesh(unit, folder)) is not None:
                written.append(path)
            continue
        if key.startswith("continuum_learning/"):
            if export.continuum and "triangles" in a:
                written.append(_learned_field_mesh(key, a, folder))
            continue
        if key.startswith("fields/"):
            _, solver, rule = key.split("/")
            for k in unit.meta["trials"]:
                roles = None
                for stage in ("initial", "final"):
                    p = f"t{k}/{stage}/"
                    if p + "x" not in a:
                        continue
                    net = _net(a, p)
                    roles = spring_roles(
                        net.n_springs, sources=a[f"t{k}/sources"], targets=a[f"t{k}/targets"]
                    )
                    if export.networks:
                        written.append(
                            write_mesh(
                                network_mesh(net, a[p + "x"], fields={"role": roles}),
                                folder / f"{solver}_{rule}_t{k}_{stage}.vtu",
                            )
                        )
                s = f"t{k}/series/"
                if export.series and s + "x" in a and roles is not None:
                    base = _net(a, f"t{k}/initial/")
                    frames = (
                        network_mesh(
                            base.with_rest_length(L).with_stiffness(kk), x, fields={"role": roles}
                        )
                        for L, kk, x in zip(a[s + "rest_length"], a[s + "stiffness"], a[s + "x"])
                    )
                    written.append(
                        write_series(
                            frames,
                            a[s + "steps"].astype(float),
                            folder,
                            f"{solver}_{rule}_t{k}_trajectory",
                        )
                    )
        elif "net/x" in a:
            n = unit.meta["n"]
            net = _net(a, "net/")
            sources = a["net/sources"] if "net/sources" in a else ()
            roles = spring_roles(net.n_springs, sources=sources)
            stage = "" if result.scene.kind == "transmission" else "_final"
            if export.networks:
                written.append(
                    write_mesh(
                        network_mesh(net, a["net/x"], fields={"role": roles}),
                        folder / f"network_n{n}{stage}.vtu",
                    )
                )
            if export.continuum and "cont/points" in a:
                mesh = continuum_mesh(
                    a["cont/points"],
                    a["cont/triangles"],
                    a["cont/displacement"],
                    a["cont/strain"],
                    a["cont/stress"],
                    cell_fields={"principal_strain": a["cont/principal"]},
                )
                written.append(write_mesh(mesh, folder / f"continuum_n{n}{stage}.vtu"))
            if export.series and "net/series_x" in a:
                times = np.asarray(a["net/series_times"], dtype=float)
                frames = (network_mesh(net, x, fields={"role": roles}) for x in a["net/series_x"])
                written.append(write_series(frames, times, folder, f"network_n{n}_relaxation"))
    return written
