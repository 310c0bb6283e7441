"""Off-screen images with pyvista: networks coloured by strain, continuum strain fields.

Images are deterministic: fixed window size, fixed colour limits, a fixed camera (looking down
-z with parallel projection, ``view_xy``), no lighting (flat 2D colours) and a colormap built
here from the ColorBrewer RdBu anchors (the same values as matplotlib's ``RdBu_r``, so
matplotlib is not needed). Strain is drawn with symmetric limits: white is zero strain, red is
extension, blue is compression. Sources and targets are drawn with a coloured halo (green and
orange) behind the strain-coloured line, so the spring keeps its strain colour.

Headless machines: when no ``DISPLAY`` is set, ``VTK_DEFAULT_OPENGL_WINDOW`` defaults to
``vtkEGLRenderWindow`` (Mesa's EGL; on Debian/Ubuntu the packages ``libegl1 libegl-mesa0
libgl1-mesa-dri libgbm1``). :func:`rendering_available` says whether rendering works.

pyvista is imported inside the functions that draw. PNG files are written atomically.
"""

from __future__ import annotations

import functools
import os
import re
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_vs_network.io.atomic import atomic_path

if TYPE_CHECKING:
    import pyvista

    from continuum_vs_network.network.model import SpringNetwork

__all__ = [
    "BACKGROUND",
    "SOURCE_COLOR",
    "TARGET_COLOR",
    "diverging_colors",
    "nice_length",
    "render_network",
    "render_networks",
    "rendering_available",
]

#: Window background: mid grey, so that white (zero strain) springs stay visible.
BACKGROUND = (0.62, 0.62, 0.62)
#: Halo colours marking source and target springs.
SOURCE_COLOR = (0.0, 0.75, 0.0)
TARGET_COLOR = (1.0, 0.6, 0.0)
_TEXT_COLOR = (0.0, 0.0, 0.0)

# ColorBrewer RdBu (11 classes), blue (low) to red (high): matplotlib's "RdBu_r" anchors.
_RDBU_R = (
    "053061", "2166ac", "4393c3", "92c5de", "d1e5f0", "f7f7f7",
    "fddbc7", "f4a582", "d6604d", "b2182b", "67001f",
)  # fmt: skip

_EGL = "vtkEGLRenderWindow"
_PROBE = (
    "import pyvista as pv\n"
    "p = pv.Plotter(off_screen=True, window_size=(48, 48))\n"
    "p.add_mesh(pv.Sphere(), color='red')\n"
    "img = p.screenshot(return_img=True)\n"
    "name = p.render_window.GetClassName()\n"
    "p.close()\n"
    "assert img.std() > 0, 'blank image'\n"
    "print(name)\n"
)


# -- backend -------------------------------------------------------------------------------
def _configure_backend() -> None:
    """Default VTK to the EGL window when there is no X display (never set it empty)."""
    if not os.environ.get("DISPLAY") and not os.environ.get("VTK_DEFAULT_OPENGL_WINDOW"):
        os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = _EGL


def _pyvista() -> Any:
    _configure_backend()
    import pyvista

    return pyvista


@functools.cache
def rendering_available() -> tuple[bool, str]:
    """Whether off-screen rendering works here, and why not if it does not.

    Tries once (in a subprocess, since a broken OpenGL stack can abort the process rather
    than raise) to draw a sphere off-screen; the answer is cached for this process.

    Returns
    -------
    (bool, str)
        ``(True, render window class)`` or ``(False, reason)``.
    """
    import importlib.util

    if importlib.util.find_spec("pyvista") is None:
        return False, "pyvista is not installed (pip install 'continuum_vs_network[io]')"
    _configure_backend()
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE],
            capture_output=True,
            text=True,
            timeout=120,
            env=dict(os.environ),
            check=False,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, f"off-screen rendering probe failed: {exc}"
    if proc.returncode != 0:
        text = re.sub(r"\x1b\[[0-9;]*m", "", proc.stderr or proc.stdout).strip()
        text = re.sub(r"(?m)^.*?\b(?:WARN|ERR|INFO)\|\s*", "", text)  # VTK log prefixes
        lines = list(dict.fromkeys(line.strip() for line in text.splitlines() if line.strip()))
        tail = " | ".join(lines[-2:])
        window = os.environ.get("VTK_DEFAULT_OPENGL_WINDOW", "(default)")
        return False, (
            f"off-screen rendering with VTK_DEFAULT_OPENGL_WINDOW={window} failed "
            f"(exit {proc.returncode}): {tail.rstrip('.')}. Headless Debian/Ubuntu needs "
            "'apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1'"
        )
    return True, proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else "ok"


# -- colours and limits --------------------------------------------------------------------
def diverging_colors(n: int = 256) -> NDArray[np.float64]:
    """The blue-white-red colormap as an ``(n, 3)`` RGB array in [0, 1] (low to high)."""
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n}")
    anchors = np.array([[int(h[i : i + 2], 16) for i in (0, 2, 4)] for h in _RDBU_R]) / 255.0
    s = np.linspace(0.0, 1.0, anchors.shape[0])
    t = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(t, s, anchors[:, c]) for c in range(3)], axis=1)


def sequential_colors(n: int = 256) -> NDArray[np.float64]:
    """White to dark red as an ``(n, 3)`` RGB array in [0, 1]: the upper half of
    :func:`diverging_colors`, for a field that is never negative."""
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n}")
    return diverging_colors(2 * n)[n:]


def _lookup_table(pv: Any, clim: tuple[float, float]) -> Any:
    """A diverging map for a signed range, a sequential one when ``clim`` starts at >= 0."""
    rgba = np.ones((256, 4))
    rgba[:, :3] = sequential_colors(256) if clim[0] >= 0 else diverging_colors(256)
    table = pv.LookupTable(values=(rgba * 255).round().astype(np.uint8))
    table.scalar_range = clim
    return table


def _clim(name: str, clim: float | Sequence[float] | None, values: NDArray) -> tuple[float, float]:
    """Colour limits: ``None`` -> symmetric ``(-a, a)`` with ``a = max |values|``; a number
    ``a`` -> ``(-a, a)``; a pair is used as given."""
    if clim is None:
        a = float(np.max(np.abs(values))) if values.size else 0.0
        a = a if a > 0 else 1.0
        return -a, a
    if np.ndim(clim) == 0:
        a = float(clim)  # type: ignore[arg-type]
        if not (np.isfinite(a) and a > 0):
            raise ValueError(f"{name} as a number must be finite and > 0, got {clim}")
        return -a, a
    lo, hi = (float(v) for v in clim)  # type: ignore[union-attr]
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"{name} must be a pair (low, high) with low < high, got {clim}")
    return lo, hi


def _window(window_size: Sequence[int]) -> tuple[int, int]:
    w = tuple(int(v) for v in window_size)
    if len(w) != 2 or min(w) < 16:
        raise ValueError(f"window_size must be (width, height) >= 16 pixels, got {window_size}")
    return w  # type: ignore[return-value]


def _scalar_bar(title: str, font_scale: float) -> dict[str, Any]:
    return {
        "title": title,
        "n_labels": 5,
        "fmt": "%.3g",
        "color": _TEXT_COLOR,
        "vertical": False,
        "position_x": 0.2,
        "position_y": 0.02,
        "width": 0.6,
        "height": 0.13,
        "title_font_size": round(16 * font_scale),
        "label_font_size": round(13 * font_scale),
        "font_family": "arial",
        "shadow": False,
    }


def _labels_below(plotter: Any, bar_title: str) -> None:
    """Put the colour bar's tick labels below the bar, away from its title."""
    plotter.scalar_bars[bar_title].SetTextPositionToPrecedeScalarBar()


def _finish_view(plotter: Any, bounds: NDArray[np.float64], zoom: float = 0.85) -> None:
    """Look down -z at ``bounds`` (xmin, xmax, ymin, ymax) with parallel projection."""
    plotter.view_xy()
    plotter.enable_parallel_projection()
    xmin, xmax, ymin, ymax = bounds
    plotter.reset_camera(bounds=(xmin, xmax, ymin, ymax, -1e-3, 1e-3))
    plotter.camera.zoom(zoom)
    # leave room for the scalar bar below and the title above: shift the view down a bit
    cam = plotter.camera
    dy = 0.06 * cam.parallel_scale
    fx, fy, fz = cam.focal_point
    px, py, pz = cam.position
    cam.focal_point = (fx, fy - dy, fz)
    cam.position = (px, py - dy, pz)


def _save(plotter: Any, path: str | os.PathLike[str]) -> Path:
    """Render, screenshot and write a PNG atomically."""
    from PIL import Image

    dest = Path(path)
    if dest.suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    img = plotter.screenshot(return_img=True)
    with atomic_path(dest) as tmp:
        Image.fromarray(np.asarray(img, dtype=np.uint8)).save(tmp, format="PNG", optimize=True)
    return dest


def _new_plotter(pv: Any, window_size: tuple[int, int], shape: tuple[int, int] = (1, 1)) -> Any:
    plotter = pv.Plotter(off_screen=True, window_size=list(window_size), shape=shape, border=False)
    plotter.set_background(BACKGROUND)
    return plotter


# -- drawing -------------------------------------------------------------------------------
def _spring_indices(name: str, idx: ArrayLike, n_springs: int) -> NDArray[np.int64]:
    arr = np.asarray(idx, dtype=np.int64).reshape(-1)
    if np.any((arr < 0) | (arr >= n_springs)):
        raise ValueError(f"{name} holds a spring index outside 0..{n_springs - 1}: {arr}")
    return arr


def _lines(pv: Any, points: NDArray, springs: NDArray, z: float) -> pyvista.PolyData:
    pts = np.zeros((points.shape[0], 3))
    pts[:, :2] = points
    pts[:, 2] = z
    lines = np.hstack([np.full((springs.shape[0], 1), 2), springs]).astype(np.int64).ravel()
    return pv.PolyData(pts, lines=lines)


def _draw_network(
    pv: Any,
    plotter: Any,
    net: SpringNetwork,
    x: ArrayLike,
    *,
    sources: ArrayLike,
    targets: ArrayLike,
    clim: float | Sequence[float] | None,
    title: str | None,
    bar_title: str,
    line_width: float,
    font_scale: float,
    bounds: NDArray[np.float64] | None = None,
    scale_length: float | None = None,
    show_bar: bool = True,
) -> None:
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (net.n_nodes, 2):
        raise ValueError(f"x must have shape ({net.n_nodes}, 2), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x must be finite")
    src = _spring_indices("sources", sources, net.n_springs)
    tgt = _spring_indices("targets", targets, net.n_springs)
    strain = net.strains(x)
    lo, hi = _clim("clim", clim, strain)
    extent = float(np.ptp(x[:, 0]) + np.ptp(x[:, 1])) or 1.0
    mesh = _lines(pv, x, np.asarray(net.springs), 0.0)
    mesh.cell_data[bar_title] = strain
    for idx, color, name in ((src, SOURCE_COLOR, "source"), (tgt, TARGET_COLOR, "target")):
        if idx.size:
            halo = _lines(pv, x, np.asarray(net.springs)[idx], -1e-3 * extent)
            plotter.add_mesh(
                halo, color=color, line_width=4.0 * line_width, lighting=False, label=name
            )
    plotter.add_mesh(
        mesh,
        scalars=bar_title,
        cmap=_lookup_table(pv, (lo, hi)),
        clim=(lo, hi),
        line_width=line_width,
        lighting=False,
        show_scalar_bar=show_bar,
        scalar_bar_args=_scalar_bar(bar_title, font_scale),
    )
    if show_bar:
        _labels_below(plotter, bar_title)
    # the key of the halos as coloured words in this panel's corner (a pyvista legend is
    # sized and placed against the whole window and floats between side-by-side panels)
    row = 0
    for idx, color, name in ((src, SOURCE_COLOR, "source"), (tgt, TARGET_COLOR, "target")):
        if idx.size:
            plotter.add_text(
                name,
                position=(0.02, 0.86 - 0.06 * row),
                viewport=True,
                font_size=round(10 * font_scale),
                color=color,
            )
            row += 1
    if title:
        plotter.add_text(
            title, position="upper_left", font_size=round(11 * font_scale), color=_TEXT_COLOR
        )
    if bounds is None:
        bounds = np.array([x[:, 0].min(), x[:, 0].max(), x[:, 1].min(), x[:, 1].max()])
    if scale_length is not None:
        _scale_bar(pv, plotter, bounds, scale_length, font_scale)
    _finish_view(plotter, bounds)


def nice_length(span: float) -> float:
    """A 1-2-5 length near a fifth of ``span`` (> 0), for a scale bar."""
    target = max(float(span), 1e-300) / 5
    exp = np.floor(np.log10(target))
    for m in (5.0, 2.0, 1.0):
        if m * 10**exp <= target:
            return float(m * 10**exp)
    return float(10**exp)


def _scale_bar(pv: Any, plotter: Any, bounds: NDArray, length: float, font_scale: float) -> None:
    """A black bar of ``length`` (length units) above the upper right of ``bounds``, labelled
    above it: clear of the colour bar below the drawing and of the title at the upper left."""
    xmin, xmax, ymin, ymax = bounds
    extent = max(xmax - xmin, ymax - ymin, length)
    y = ymax + 0.04 * extent
    bar = pv.Line((xmax - length, y, 0.0), (xmax, y, 0.0))
    plotter.add_mesh(bar, color=_TEXT_COLOR, line_width=4.0, lighting=False)
    plotter.add_point_labels(
        [(xmax - length, y + 0.03 * extent, 0.0)],
        [f"{length:g} (length units)"],
        font_size=round(11 * font_scale),
        text_color=_TEXT_COLOR,
        shape_opacity=0.0,
        show_points=False,
        always_visible=True,
    )


def _font_scale(window_size: tuple[int, int], columns: int = 1) -> float:
    return max(0.6, min(window_size[0] / columns, window_size[1]) / 800.0 * 1.6)


# -- public --------------------------------------------------------------------------------
def render_network(
    net: SpringNetwork,
    x: ArrayLike,
    path: str | os.PathLike[str],
    *,
    sources: ArrayLike = (),
    targets: ArrayLike = (),
    clim: float | Sequence[float] | None = None,
    window_size: Sequence[int] = (800, 800),
    title: str | None = None,
    scalar_bar_title: str = "spring strain",
    line_width: float = 3.0,
) -> Path:
    """Draw the network at positions ``x`` with springs coloured by strain; write a PNG.

    Parameters
    ----------
    net : SpringNetwork
        The network (rest lengths define the strain ``r/L - 1``).
    x : (n_nodes, 2) float array
        Positions to draw (e.g. an equilibrium).
    path : str or os.PathLike
        Destination ``.png`` (written atomically; parent folders created).
    sources, targets : sequence of int
        Spring indices marked with a green (sources) or orange (targets) halo.
    clim : float or (float, float), optional
        Colour limits. Default: symmetric ``(-a, a)``, ``a = max |strain|``; a number ``a``
        means ``(-a, a)``. Fix it to compare images.
    window_size : (int, int)
        Image size in pixels.
    title : str, optional
        Text in the upper left corner.
    scalar_bar_title : str
        Title of the colour bar (must differ from other bars in the same image).
    line_width : float
        Spring line width in pixels (halos are four times wider).

    Returns
    -------
    pathlib.Path
        The PNG written.
    """
    pv = _pyvista()
    size = _window(window_size)
    plotter = _new_plotter(pv, size)
    try:
        _draw_network(
            pv,
            plotter,
            net,
            x,
            sources=sources,
            targets=targets,
            clim=clim,
            title=title,
            bar_title=scalar_bar_title,
            line_width=line_width,
            font_scale=_font_scale(size),
        )
        return _save(plotter, path)
    finally:
        plotter.close()


def render_networks(
    panels: Sequence[tuple[SpringNetwork, ArrayLike, str]],
    path: str | os.PathLike[str],
    *,
    sources: ArrayLike = (),
    targets: ArrayLike = (),
    clim: float | Sequence[float] | None = None,
    window_size: Sequence[int] = (1400, 700),
    scalar_bar_title: str = "spring strain",
    line_width: float = 3.0,
) -> Path:
    """Several networks in one row, same view and a length scale; write a PNG.

    Parameters
    ----------
    panels : sequence of (SpringNetwork, (n_nodes, 2) positions, title)
        Drawn left to right in one frame (the union of their extents), so that a network
        that shrank or collapsed looks so beside the others.
    sources, targets : sequence of int
        Spring indices marked in every panel (the same task).
    clim : float or (float, float), optional
        Colour limits of every panel (default: from the first panel's strains).
    window_size, scalar_bar_title, line_width
        As in :func:`render_network`; one colour bar, under the first panel.
    """
    if not panels:
        raise ValueError("panels must name at least one network")
    pv = _pyvista()
    size = _window(window_size)
    cols = len(panels)
    xs = [np.asarray(x, dtype=np.float64) for _, x, _ in panels]
    for (net, _, _), x in zip(panels, xs, strict=True):
        if x.shape != (net.n_nodes, 2) or not np.all(np.isfinite(x)):
            raise ValueError(f"positions must be finite with shape ({net.n_nodes}, 2)")
    allx = np.concatenate(xs)
    bounds = np.array([allx[:, 0].min(), allx[:, 0].max(), allx[:, 1].min(), allx[:, 1].max()])
    if clim is None:
        clim = float(np.max(np.abs(panels[0][0].strains(xs[0])))) or 1.0
    length = nice_length(max(bounds[1] - bounds[0], bounds[3] - bounds[2]))
    plotter = _new_plotter(pv, size, shape=(1, cols))
    fs = _font_scale(size, columns=cols)
    try:
        for j, ((net, _, title), x) in enumerate(zip(panels, xs, strict=True)):
            plotter.subplot(0, j)
            _draw_network(
                pv,
                plotter,
                net,
                x,
                sources=sources,
                targets=targets,
                clim=clim,
                title=title,
                bar_title=scalar_bar_title,
                line_width=line_width,
                font_scale=fs,
                bounds=bounds,
                scale_length=length,
                show_bar=j == 0,
            )
        return _save(plotter, path)
    finally:
        plotter.close()
