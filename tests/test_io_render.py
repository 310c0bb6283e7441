"""Off-screen images: reference-image regression, non-blank output, colour of a strained spring.

The reference images in ``tests/data/images`` were made by this code. To regenerate them
after a deliberate change of the drawing, run ``CVN_UPDATE_IMAGES=1 pytest
tests/test_io_render.py`` and look at them before committing.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from continuum_vs_network import SpringNetwork, triangular_lattice
from continuum_vs_network.io import render
from continuum_vs_network.io.render import (
    SOURCE_COLOR,
    diverging_colors,
    render_network,
    rendering_available,
)
from continuum_vs_network.io.render_continuum import render_continuum, render_side_by_side

pytestmark = pytest.mark.render

IMAGES = Path(__file__).parent / "data" / "images"
UPDATE = os.environ.get("CVN_UPDATE_IMAGES") == "1"
#: Largest accepted ``pyvista.compare_images`` error against a reference (vtkImageDifference
#: thresholded error). Identical renders give 0; the "sensitivity" test below checks that a
#: visible change (colour limits halved) lies far above it.
MAX_ERROR = 100.0


@pytest.fixture(scope="module")
def pv():
    pyvista = pytest.importorskip("pyvista")
    ok, why = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering backend: {why}")
    return pyvista


def _lattice(nx: int = 5, ny: int = 5) -> SpringNetwork:
    """Triangular lattice, rows shifted by half a spacing, springs at rest."""
    return triangular_lattice(nx, ny)


def _deformed(net: SpringNetwork) -> np.ndarray:
    """A smooth, deterministic deformation: a bend plus a horizontal stretch."""
    X = net.positions
    x = np.array(X)
    x[:, 0] += 0.06 * X[:, 0] * (X[:, 1] - 1.7)
    x[:, 1] += 0.04 * (X[:, 0] - 2.2) ** 2
    return x


def _square(n: int = 8):
    xs, ys = np.meshgrid(np.linspace(0, 4, n + 1), np.linspace(0, 3, n + 1))
    pts = np.c_[xs.ravel(), ys.ravel()]
    tri = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tri += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    tri = np.array(tri)
    disp = np.c_[0.05 * pts[:, 0] * pts[:, 1], -0.03 * pts[:, 0] ** 2]
    exx = 0.05 * pts[tri].mean(axis=1)[:, 1]  # d u_x / dx at the centroids
    return pts, tri, disp, exx - exx.mean()


def _image(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(float)


def _compare(pv, path: Path, name: str) -> float:
    ref = IMAGES / name
    if UPDATE:
        IMAGES.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, ref)
        pytest.skip(f"reference image {ref} rewritten (CVN_UPDATE_IMAGES=1)")
    assert ref.is_file(), f"missing reference {ref}; make it with CVN_UPDATE_IMAGES=1"
    return pv.compare_images(str(path), str(ref))


def _near(img: np.ndarray, rgb, tol: float = 30.0) -> np.ndarray:
    return np.linalg.norm(img - np.asarray(rgb, dtype=float), axis=-1) < tol


# -- regression against stored images ----------------------------------------------------
def _network_image(tmp_path: Path, clim: float = 0.1) -> Path:
    net = _lattice()
    return render_network(
        net, _deformed(net), tmp_path / "net.png", sources=[0], targets=[net.n_springs - 1],
        clim=clim, window_size=(400, 400), title="network",
    )  # fmt: skip


def test_network_matches_reference(pv, tmp_path):
    err = _compare(pv, _network_image(tmp_path), "network.png")
    assert err <= MAX_ERROR, f"network image differs from the reference: error {err:.1f}"


def test_reference_comparison_detects_a_change(pv, tmp_path):
    """Halving the colour limits recolours every spring: the comparison must notice."""
    if UPDATE:
        pytest.skip("updating references")
    err = pv.compare_images(str(_network_image(tmp_path, clim=0.05)), str(IMAGES / "network.png"))
    assert err > 5 * MAX_ERROR


def test_continuum_matches_reference(pv, tmp_path):
    pts, tri, disp, exx = _square()
    path = render_continuum(
        pts, tri, disp, exx, tmp_path / "cont.png", clim=0.08, scale=1.0,
        window_size=(400, 400), title="continuum", scalar_bar_title="strain xx",
    )  # fmt: skip
    err = _compare(pv, path, "continuum.png")
    assert err <= MAX_ERROR, f"continuum image differs from the reference: error {err:.1f}"


def test_side_by_side_matches_reference(pv, tmp_path):
    net = _lattice()
    pts, tri, disp, exx = _square()
    path = render_side_by_side(
        net, _deformed(net), pts, tri, disp, exx, tmp_path / "sbs.png",
        sources=[0], targets=[net.n_springs - 1], network_clim=0.1, continuum_clim=0.08,
        window_size=(800, 400),
    )  # fmt: skip
    err = _compare(pv, path, "side_by_side.png")
    assert err <= MAX_ERROR, f"side-by-side image differs from the reference: error {err:.1f}"


# -- properties of a rendered image -------------------------------------------------------
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_strained_source_takes_the_matching_end_of_the_colormap(pv, tmp_path, sign):
    """Only the source spring is strained (its rest length changed): at strain +a with
    clim (-a, a) it is drawn in the colormap's top colour (dark red), at -a in the bottom
    colour (dark blue), inside its green halo; no pixel takes the other end."""
    net = _lattice(4, 4)
    src = 5
    a = 0.2
    rest = np.array(net.rest_length)
    rest[src] /= 1 + sign * a
    net = net.with_rest_length(rest)
    strain = net.strains()
    assert strain[src] == pytest.approx(sign * a) and np.allclose(np.delete(strain, src), 0)

    img = _image(
        render_network(net, net.positions, tmp_path / "src.png", sources=[src], clim=a,
                       window_size=(300, 300))
    )  # fmt: skip
    img = img[: int(0.8 * img.shape[0])]  # leave out the colour bar at the bottom
    ends = (diverging_colors(256)[[0, -1]] * 255).round()
    low, high = ends if sign > 0 else ends[::-1]  # `high` is the expected colour
    hit = _near(img, high)
    assert hit.sum() >= 20, "the strained source spring is not drawn in the end colour"
    assert not _near(img, low).any(), "some pixel has the opposite end colour"
    # the end-colour pixels lie on the source spring: inside the halo of the source colour
    from scipy.ndimage import binary_dilation

    halo = binary_dilation(_near(img, np.asarray(SOURCE_COLOR) * 255), iterations=3)
    assert halo[hit].mean() > 0.95


def test_rendered_image_is_not_blank(pv, tmp_path):
    net = _lattice()
    img = _image(
        render_network(net, _deformed(net), tmp_path / "n.png", clim=0.1, window_size=(200, 200))
    )
    assert img.shape == (200, 200, 3)
    background = np.asarray(render.BACKGROUND) * 255
    drawn = ~_near(img, background, tol=3.0)
    assert img.std() > 10.0
    assert 0.02 < drawn.mean() < 0.6, f"fraction of drawn pixels {drawn.mean():.3f}"


def test_failed_render_leaves_no_png(pv, tmp_path):
    net = _lattice(3, 3)
    with pytest.raises(ValueError, match="x must have shape"):
        render_network(net, net.positions[:-1], tmp_path / "bad.png")
    with pytest.raises(ValueError, match=r"must end in \.png"):
        render_network(net, net.positions, tmp_path / "bad.jpg", window_size=(64, 64))
    pts, tri, disp, exx = _square(2)
    with pytest.raises(ValueError, match="scalar must have shape"):
        render_continuum(pts, tri, disp, exx[:-1], tmp_path / "c.png")
    assert list(tmp_path.iterdir()) == []


def test_colormap_is_rdbu_r():
    """The hand-built table equals matplotlib's RdBu_r where matplotlib is installed."""
    colors = diverging_colors(256)
    assert colors[0] == pytest.approx(np.array([5, 48, 97]) / 255)
    assert colors[-1] == pytest.approx(np.array([103, 0, 31]) / 255)
    mpl = pytest.importorskip("matplotlib")
    ref = mpl.colormaps["RdBu_r"](np.linspace(0, 1, 256))[:, :3]
    np.testing.assert_allclose(colors, ref, atol=1.5 / 255)


def test_egl_default_only_without_display(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "")
    render._configure_backend()
    assert os.environ["VTK_DEFAULT_OPENGL_WINDOW"] == "vtkEGLRenderWindow"
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")
    render._configure_backend()
    assert os.environ["VTK_DEFAULT_OPENGL_WINDOW"] == "vtkOSOpenGLRenderWindow"
    monkeypatch.delenv("VTK_DEFAULT_OPENGL_WINDOW")
    monkeypatch.setenv("DISPLAY", ":0")
    render._configure_backend()
    assert "VTK_DEFAULT_OPENGL_WINDOW" not in os.environ
