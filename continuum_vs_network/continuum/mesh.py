"""Triangle meshes of the bodies the continuum is solved on.

Rectangle, disk (optionally with interface circles, for inclusions), annulus, and the
outline of a spring network (the union of its triangular faces). Disks and annuli are built
ring by ring so that every circle (boundary or interface) is a set of mesh edges; with
``curved=True`` they are returned as quadratic (isoparametric) meshes whose edges on those
circles are arcs, which keeps P2 elements at their full convergence rate on curved bodies.

Every function returns a scikit-fem mesh (``MeshTri1`` or ``MeshTri2``); scikit-fem is
imported inside the functions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # pragma: no cover
    from ..network.model import SpringNetwork

__all__ = [
    "MeshQuality",
    "annulus_mesh",
    "disk_mesh",
    "mesh_quality",
    "network_faces",
    "network_mesh",
    "rectangle_mesh",
]


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value}")
    return value


def rectangle_mesh(
    width: float,
    height: float,
    *,
    h: float,
    origin: tuple[float, float] = (0.0, 0.0),
) -> Any:
    """Structured triangle mesh of the rectangle ``[x0, x0 + width] x [y0, y0 + height]``.

    Parameters
    ----------
    width, height : float
        Side lengths (length units).
    h : float
        Target edge length; each side gets ``ceil(side / h)`` intervals.
    origin : (2,) float
        Lower-left corner.

    Returns
    -------
    skfem.MeshTri1
    """
    from skfem import MeshTri1

    width, height, h = _positive("width", width), _positive("height", height), _positive("h", h)
    nx = max(1, math.ceil(width / h - 1e-9))
    ny = max(1, math.ceil(height / h - 1e-9))
    x = origin[0] + np.linspace(0.0, width, nx + 1)
    y = origin[1] + np.linspace(0.0, height, ny + 1)
    return MeshTri1.init_tensor(x, y)


def _ring_counts(radii: NDArray, h: float) -> NDArray[np.int64]:
    return np.array([0 if r == 0 else max(6, round(2 * math.pi * r / h)) for r in radii])


def _zip_rings(inner: NDArray, inner_angle: NDArray, outer: NDArray, outer_angle: NDArray) -> list:
    """Triangles between two closed rings of nodes (ascending angles, outer starting first)."""
    n, m = inner.size, outer.size
    a = b = 0
    tris = []
    two_pi = 2 * math.pi
    while a < n or b < m:
        next_a = inner_angle[(a + 1) % n] + two_pi * ((a + 1) // n)
        next_b = outer_angle[(b + 1) % m] + two_pi * ((b + 1) // m)
        if b == m or (a < n and next_a <= next_b):
            tris.append((inner[a % n], inner[(a + 1) % n], outer[b % m]))
            a += 1
        else:
            tris.append((inner[a % n], outer[(b + 1) % m], outer[b % m]))
            b += 1
    return tris


def _ring_mesh(radii: NDArray, h: float, centre: tuple[float, float], curved: bool) -> Any:
    from skfem import MeshTri1, MeshTri2

    counts = _ring_counts(radii, h)
    points: list[NDArray] = []
    ring_nodes: list[NDArray] = []
    ring_angles: list[NDArray] = []
    node_radius: list[NDArray] = []
    start = 0
    for i, (r, n) in enumerate(zip(radii, counts)):
        if r == 0:
            points.append(np.zeros((1, 2)))
            ring_nodes.append(np.array([start]))
            ring_angles.append(np.zeros(1))
            node_radius.append(np.zeros(1))
            start += 1
            continue
        # stagger every other ring by half a step; the first angle stays in [0, 2 pi / n)
        angle = 2 * math.pi * (np.arange(n) + 0.5 * (i % 2)) / n
        points.append(r * np.column_stack([np.cos(angle), np.sin(angle)]))
        ring_nodes.append(np.arange(start, start + n))
        ring_angles.append(angle)
        node_radius.append(np.full(n, r))
        start += n
    tris: list = []
    for k in range(len(radii) - 1):
        if radii[k] == 0:
            outer = ring_nodes[k + 1]
            tris += [
                (ring_nodes[k][0], outer[j], outer[(j + 1) % outer.size]) for j in range(outer.size)
            ]
        else:
            # the zipper needs the outer ring's first angle <= the inner ring's first angle
            inner, ia = ring_nodes[k], ring_angles[k]
            outer, oa = ring_nodes[k + 1], ring_angles[k + 1]
            start_node = int(np.argmin(np.mod(ia[0] - oa, 2 * math.pi)))
            start_angle = ia[0] - np.mod(ia[0] - oa[start_node], 2 * math.pi)
            outer = np.roll(outer, -start_node)
            oa = start_angle + np.mod(np.roll(oa, -start_node) - start_angle, 2 * math.pi)
            tris += _zip_rings(inner, ia, outer, oa)
    p = np.vstack(points) + np.asarray(centre, dtype=float)
    t = np.array(tris, dtype=np.int64)
    mesh = MeshTri1(p.T.copy(), t.T.copy())
    if not curved:
        return mesh
    radius = np.concatenate(node_radius)
    mesh2 = MeshTri2.from_mesh(mesh)
    facets = mesh2.facets
    on_ring = (radius[facets[0]] == radius[facets[1]]) & (radius[facets[0]] > 0)
    dofs = mesh2.dofs.facet_dofs[0, np.flatnonzero(on_ring)]
    doflocs = mesh2.doflocs.copy()
    rel = doflocs[:, dofs] - np.asarray(centre, dtype=float)[:, None]
    r_target = radius[facets[0, on_ring]]
    doflocs[:, dofs] = (
        np.asarray(centre, dtype=float)[:, None] + rel / np.linalg.norm(rel, axis=0) * r_target
    )
    from dataclasses import replace

    return replace(mesh2, doflocs=doflocs)


def _radii(stops: Sequence[float], h: float) -> NDArray:
    """Ring radii through every value in ``stops`` (ascending), spaced about ``h``."""
    radii = [stops[0]]
    for lo, hi in itertools.pairwise(stops):
        n = max(1, round((hi - lo) / h))
        radii += list(np.linspace(lo, hi, n + 1)[1:])
    return np.array(radii)


def disk_mesh(
    radius: float,
    *,
    h: float,
    interfaces: Sequence[float] = (),
    centre: tuple[float, float] = (0.0, 0.0),
    curved: bool = False,
) -> Any:
    """Triangle mesh of a disk, with every circle in ``interfaces`` made of mesh edges.

    Parameters
    ----------
    radius : float
        Disk radius (length units).
    h : float
        Target edge length (radial and tangential).
    interfaces : sequence of float
        Radii in ``(0, radius)`` of circles that must be resolved (inclusion boundaries).
    centre : (2,) float
    curved : bool
        Return a quadratic ``MeshTri2`` whose edges on the boundary and interface circles
        are arcs (use with P2 elements).

    Returns
    -------
    skfem.MeshTri1 or skfem.MeshTri2
    """
    radius, h = _positive("radius", radius), _positive("h", h)
    inner = sorted(float(r) for r in interfaces)
    if any(not (0 < r < radius) for r in inner):
        raise ValueError(f"interfaces must lie in (0, radius={radius}), got {list(interfaces)}")
    return _ring_mesh(_radii([0.0, *inner, radius], h), h, centre, curved)


def annulus_mesh(
    inner_radius: float,
    outer_radius: float,
    *,
    h: float,
    interfaces: Sequence[float] = (),
    centre: tuple[float, float] = (0.0, 0.0),
    curved: bool = False,
) -> Any:
    """Triangle mesh of the annulus ``inner_radius <= r <= outer_radius``.

    Parameters as in :func:`disk_mesh`; ``interfaces`` must lie strictly between the radii.
    """
    a = _positive("inner_radius", inner_radius)
    b = _positive("outer_radius", outer_radius)
    h = _positive("h", h)
    if not a < b:
        raise ValueError(f"inner_radius ({a}) must be smaller than outer_radius ({b})")
    inner = sorted(float(r) for r in interfaces)
    if any(not (a < r < b) for r in inner):
        raise ValueError(f"interfaces must lie in ({a}, {b}), got {list(interfaces)}")
    return _ring_mesh(_radii([a, *inner, b], h), h, centre, curved)


def network_faces(net: SpringNetwork, positions: ArrayLike | None = None) -> NDArray[np.int64]:
    """The triangular faces of a network: every 3-cycle of springs, counter-clockwise.

    Parameters
    ----------
    net : SpringNetwork
    positions : (n_nodes, 2) float array, optional
        Node positions (default ``net.positions``).

    Returns
    -------
    (n_faces, 3) int array
        Node triples. Raises ``ValueError`` when the network has no triangle, a triangle
        has (near) zero area, or a spring borders more than two triangles (crossing springs),
        since then the faces do not tile a planar body.
    """
    x = net.positions if positions is None else np.asarray(positions, dtype=float)
    n = net.n_nodes
    neighbours: list[set[int]] = [set() for _ in range(n)]
    for i, j in net.springs:
        neighbours[i].add(int(j))
        neighbours[j].add(int(i))
    faces = set()
    for i, j in net.springs:
        for k in neighbours[i] & neighbours[j]:
            faces.add(tuple(sorted((int(i), int(j), int(k)))))
    if not faces:
        raise ValueError("the network has no triangular faces; cannot build its outline")
    t = np.array(sorted(faces), dtype=np.int64)
    d1 = x[t[:, 1]] - x[t[:, 0]]
    d2 = x[t[:, 2]] - x[t[:, 0]]
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    scale = float(np.mean(net.lengths(x))) ** 2
    tiny = np.flatnonzero(np.abs(cross) < 1e-10 * scale)
    if tiny.size:
        raise ValueError(f"face {t[tiny[0]].tolist()} of the network has (near) zero area")
    t[cross < 0] = t[cross < 0][:, [0, 2, 1]]
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if np.any(counts > 2):
        raise ValueError(
            "a spring borders more than two triangles (crossing springs): the network's "
            "faces do not tile a planar body"
        )
    return t


def network_mesh(
    net: SpringNetwork,
    *,
    refine: int = 0,
    positions: ArrayLike | None = None,
) -> Any:
    """Mesh of the body a network fills: the union of its triangular faces.

    Parameters
    ----------
    net : SpringNetwork
    refine : int
        Uniform refinements; the edge length is the spring length over ``2**refine``.
        The first ``n_nodes`` mesh vertices are the network's nodes, in order.
    positions : (n_nodes, 2) float array, optional
        Node positions (default ``net.positions``).

    Returns
    -------
    skfem.MeshTri1
    """
    from skfem import MeshTri1

    if int(refine) != refine or refine < 0:
        raise ValueError(f"refine must be an integer >= 0, got {refine}")
    x = net.positions if positions is None else np.asarray(positions, dtype=float)
    t = network_faces(net, x)
    used = np.unique(t)
    if used.size != net.n_nodes:
        missing = np.setdiff1d(np.arange(net.n_nodes), used)
        raise ValueError(
            f"node {missing[0]} belongs to no triangular face; the outline mesh needs every "
            "node on a face"
        )
    mesh = MeshTri1(x.T.copy(), t.T.copy(), sort_t=False)
    return mesh.refined(int(refine)) if refine else mesh


@dataclass(frozen=True)
class MeshQuality:
    """Shape of the worst elements of a mesh.

    Attributes
    ----------
    min_angle : float
        Smallest interior angle over all triangles (degrees).
    max_aspect : float
        Largest ratio longest edge / shortest altitude.
    min_area, max_area : float
        Element areas (length**2).
    h : float
        Mean edge length.
    tangled : int
        Interior edges whose two triangles lie on the same side (inverted, overlapping
        elements); a valid mesh has none.
    """

    min_angle: float
    max_aspect: float
    min_area: float
    max_area: float
    h: float
    tangled: int


def mesh_quality(mesh: Any) -> MeshQuality:
    """Angles, aspect ratio and areas of the (straight-sided) triangles of ``mesh``."""
    p = mesh.p.T
    t = mesh.t.T
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    e = np.stack([b - a, c - b, a - c], axis=1)  # (n, 3, 2)
    lengths = np.linalg.norm(e, axis=2)
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    area = 0.5 * cross
    angles = []
    for k in range(3):
        u, v = -e[:, k - 1], e[:, k]
        cosang = np.sum(u * v, axis=1) / np.maximum(lengths[:, k - 1] * lengths[:, k], 1e-300)
        angles.append(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))))
    # each interior edge: its two triangles' third vertices must lie on opposite sides
    f2t = mesh.f2t
    inner = np.flatnonzero(f2t[1] >= 0)
    fa, fb = p[mesh.facets[0, inner]], p[mesh.facets[1, inner]]
    side = []
    for k in (0, 1):
        tri = t[f2t[k, inner]]
        third = tri.sum(axis=1) - mesh.facets[0, inner] - mesh.facets[1, inner]
        d, e_ = fb - fa, p[third] - fa
        side.append(np.sign(d[:, 0] * e_[:, 1] - d[:, 1] * e_[:, 0]))
    tangled = int(np.sum(side[0] * side[1] >= 0))
    longest = lengths.max(axis=1)
    altitude = 2 * area / np.maximum(longest, 1e-300)
    return MeshQuality(
        min_angle=float(np.min(angles)),
        max_aspect=float(np.max(longest / np.maximum(altitude, 1e-300))),
        min_area=float(area.min()),
        max_area=float(area.max()),
        h=float(lengths.mean()),
        tangled=tangled,
    )
