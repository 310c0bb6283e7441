"""Off-screen images of continuum strain fields, alone or beside the network they map.

Same conventions as :mod:`.render` (fixed camera, symmetric strain limits, the RdBu map,
atomic PNG files); pyvista is imported inside the functions that draw.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_vs_network.io.render import (
    _TEXT_COLOR,
    _clim,
    _draw_network,
    _finish_view,
    _font_scale,
    _labels_below,
    _lookup_table,
    _new_plotter,
    _pyvista,
    _save,
    _scalar_bar,
    _window,
)

if TYPE_CHECKING:
    from continuum_vs_network.network.model import SpringNetwork

__all__ = ["render_continuum", "render_side_by_side"]


def _continuum_arrays(
    points: ArrayLike,
    triangles: ArrayLike,
    displacement: ArrayLike,
    scalar: ArrayLike,
    location: str | None,
) -> tuple[NDArray, NDArray, NDArray, NDArray, str]:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {pts.shape}")
    tri = np.asarray(triangles)
    if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
        raise ValueError(f"triangles must be an (n, 3) int array, got {tri.shape} {tri.dtype}")
    if tri.size and (tri.min() < 0 or tri.max() >= pts.shape[0]):
        raise ValueError(f"triangles hold a vertex index outside 0..{pts.shape[0] - 1}")
    disp = np.asarray(displacement, dtype=np.float64)
    if disp.shape != pts.shape:
        raise ValueError(f"displacement must have shape {pts.shape}, got {disp.shape}")
    val = np.asarray(scalar, dtype=np.float64)
    n_pts, n_tri = pts.shape[0], tri.shape[0]
    if location is None:
        if n_pts == n_tri and val.shape == (n_pts,):
            raise ValueError(
                "scalar has one value per point and per triangle alike; pass location='cell' "
                "or location='point'"
            )
        location = "cell" if val.shape == (n_tri,) else "point"
    if location not in ("cell", "point"):
        raise ValueError(f"location must be 'cell' or 'point', got {location!r}")
    want = n_tri if location == "cell" else n_pts
    if val.shape != (want,):
        raise ValueError(
            f"scalar must have shape ({n_tri},) per triangle or ({n_pts},) per point, "
            f"got {val.shape}"
        )
    for name, arr in (("points", pts), ("displacement", disp), ("scalar", val)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite")
    return pts, tri.astype(np.int64), disp, val, location


def _draw_continuum(
    pv: Any,
    plotter: Any,
    points: ArrayLike,
    triangles: ArrayLike,
    displacement: ArrayLike,
    scalar: ArrayLike,
    *,
    clim: float | Sequence[float] | None,
    scale: float,
    location: str | None,
    title: str | None,
    bar_title: str,
    show_edges: bool,
    font_scale: float,
) -> None:
    if not (np.isfinite(scale) and scale >= 0):
        raise ValueError(f"scale must be finite and >= 0, got {scale}")
    pts, tri, disp, val, location = _continuum_arrays(
        points, triangles, displacement, scalar, location
    )
    lo, hi = _clim("clim", clim, val)
    deformed = pts + scale * disp
    xyz = np.zeros((pts.shape[0], 3))
    xyz[:, :2] = deformed
    faces = np.hstack([np.full((tri.shape[0], 1), 3), tri]).ravel()
    mesh = pv.PolyData(xyz, faces=faces)
    data = mesh.cell_data if location == "cell" else mesh.point_data
    data[bar_title] = val
    plotter.add_mesh(
        mesh,
        scalars=bar_title,
        cmap=_lookup_table(pv, (lo, hi)),
        clim=(lo, hi),
        lighting=False,
        show_edges=show_edges,
        edge_color=(0.3, 0.3, 0.3),
        line_width=0.5,
        scalar_bar_args=_scalar_bar(bar_title, font_scale),
    )
    _labels_below(plotter, bar_title)
    if title:
        plotter.add_text(
            title, position="upper_left", font_size=round(11 * font_scale), color=_TEXT_COLOR
        )
    bounds = np.array(
        [deformed[:, 0].min(), deformed[:, 0].max(), deformed[:, 1].min(), deformed[:, 1].max()]
    )
    _finish_view(plotter, bounds)


def render_continuum(
    points: ArrayLike,
    triangles: ArrayLike,
    displacement: ArrayLike,
    scalar: ArrayLike,
    path: str | os.PathLike[str],
    *,
    clim: float | Sequence[float] | None = None,
    scale: float = 1.0,
    location: str | None = None,
    window_size: Sequence[int] = (800, 800),
    title: str | None = None,
    scalar_bar_title: str = "strain",
    show_edges: bool = False,
) -> Path:
    """Draw a scalar field (e.g. a strain component) on the deformed triangle mesh; write a PNG.

    Parameters
    ----------
    points : (n_points, 2) float array
        Reference vertex positions.
    triangles : (n_triangles, 3) int array
        Vertex indices.
    displacement : (n_points, 2) float array
        Vertex displacements; the mesh is drawn at ``points + scale * displacement``.
    scalar : (n_triangles,) or (n_points,) float array
        The field to colour by, per triangle (flat) or per vertex (interpolated).
    path : str or os.PathLike
        Destination ``.png`` (written atomically).
    clim : float or (float, float), optional
        Colour limits, as in :func:`render_network`.
    scale : float
        Displacement magnification (0 draws the reference mesh).
    location : {"cell", "point"}, optional
        Where ``scalar`` lives; inferred from its length unless that is ambiguous.
    window_size, title, scalar_bar_title
        As in :func:`render_network`.
    show_edges : bool
        Draw the triangle edges.
    """
    pv = _pyvista()
    size = _window(window_size)
    plotter = _new_plotter(pv, size)
    try:
        _draw_continuum(
            pv,
            plotter,
            points,
            triangles,
            displacement,
            scalar,
            clim=clim,
            scale=scale,
            location=location,
            title=title,
            bar_title=scalar_bar_title,
            show_edges=show_edges,
            font_scale=_font_scale(size),
        )
        return _save(plotter, path)
    finally:
        plotter.close()


def render_side_by_side(
    net: SpringNetwork,
    x: ArrayLike,
    points: ArrayLike,
    triangles: ArrayLike,
    displacement: ArrayLike,
    scalar: ArrayLike,
    path: str | os.PathLike[str],
    *,
    sources: ArrayLike = (),
    targets: ArrayLike = (),
    network_clim: float | Sequence[float] | None = None,
    continuum_clim: float | Sequence[float] | None = None,
    scale: float = 1.0,
    location: str | None = None,
    window_size: Sequence[int] = (1600, 800),
    titles: tuple[str, str] = ("network", "continuum"),
    network_bar_title: str = "spring strain",
    continuum_bar_title: str = "continuum strain",
    line_width: float = 3.0,
    show_edges: bool = False,
) -> Path:
    """Network (left) and continuum (right) in one 1x2 image; write a PNG.

    The arguments are those of :func:`render_network` (``net, x, sources, targets``) and
    :func:`render_continuum` (``points, triangles, displacement, scalar, scale, location``).
    Each panel has its own colour bar; pass the same limits to both to compare colours.
    """
    if network_bar_title == continuum_bar_title:
        raise ValueError("network_bar_title and continuum_bar_title must differ")
    pv = _pyvista()
    size = _window(window_size)
    plotter = _new_plotter(pv, size, shape=(1, 2))
    fs = _font_scale(size, columns=2)
    try:
        plotter.subplot(0, 0)
        _draw_network(
            pv,
            plotter,
            net,
            x,
            sources=sources,
            targets=targets,
            clim=network_clim,
            title=titles[0],
            bar_title=network_bar_title,
            line_width=line_width,
            font_scale=fs,
        )
        plotter.subplot(0, 1)
        _draw_continuum(
            pv,
            plotter,
            points,
            triangles,
            displacement,
            scalar,
            clim=continuum_clim,
            scale=scale,
            location=location,
            title=titles[1],
            bar_title=continuum_bar_title,
            show_edges=show_edges,
            font_scale=fs,
        )
        return _save(plotter, path)
    finally:
        plotter.close()
