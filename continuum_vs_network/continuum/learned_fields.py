"""Learned material fields: a network's rest-length changes on its triangles, fields moved
between nested meshes, magnitude, direction and localisation.

Pure array functions (no training, no I/O), used to compare a trained network with a
trained continuum on the same triangles.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "coarse_average",
    "field_direction",
    "field_magnitude",
    "localisation",
    "network_rest_strain",
]


def network_rest_strain(net0, net1, faces: ArrayLike | None = None) -> NDArray[np.float64]:
    """The rest strain each triangle of a network learned, (n_faces, 3) tensors (xx, yy, xy).

    For a triangle with edges ``j`` (unit vectors ``n_j`` at ``net0.positions``) it is the
    one symmetric tensor ``eps`` with ``n_j . eps . n_j = L1_j / L0_j - 1``: the uniform
    eigenstrain whose edge extensions are the springs' relative rest-length changes from
    ``net0`` to ``net1``. A spring shared by two triangles enters both.

    Parameters
    ----------
    net0, net1 : SpringNetwork
        The network before and after learning (same topology).
    faces : (n_faces, 3) int array, optional
        Default :func:`~.mesh.network_faces` of ``net0`` (the elements of
        :func:`~.mesh.network_mesh`, in order).
    """
    from .mesh import network_faces

    if net0.n_springs != net1.n_springs or not np.array_equal(net0.springs, net1.springs):
        raise ValueError("net0 and net1 must have the same springs")
    t = network_faces(net0) if faces is None else np.asarray(faces, dtype=np.int64)
    x = net0.positions
    n = net0.n_nodes
    key = np.sort(net0.springs, axis=1) @ np.array([n, 1])
    order = np.argsort(key)
    rel = net1.rest_length / net0.rest_length - 1.0
    A = np.empty((t.shape[0], 3, 3))
    b = np.empty((t.shape[0], 3))
    for c, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        pair = np.sort(t[:, [i, j]], axis=1) @ np.array([n, 1])
        pos = np.searchsorted(key, pair, sorter=order)
        spring = order[np.minimum(pos, key.size - 1)]
        if np.any(key[spring] != pair):
            raise ValueError("a face edge is not a spring of the network")
        d = x[t[:, j]] - x[t[:, i]]
        d /= np.hypot(d[:, 0], d[:, 1])[:, None]
        A[:, c] = np.column_stack([d[:, 0] ** 2, d[:, 1] ** 2, 2 * d[:, 0] * d[:, 1]])
        b[:, c] = rel[spring]
    return np.linalg.solve(A, b[:, :, None])[:, :, 0]


def coarse_average(values: ArrayLike, fine, coarse) -> NDArray[np.float64]:
    """Area-weighted mean of element values of ``fine`` over the elements of ``coarse``.

    ``fine`` and ``coarse`` are LearnableBody or ElasticBody on nested meshes (``fine``
    refines ``coarse``): each fine element belongs to the coarse element holding its
    centroid. ``values`` is (n_fine,) or (n_fine, k); returns (n_coarse,) or (n_coarse, k).
    """
    from .probes import locate

    fb, cb = getattr(fine, "body", fine), getattr(coarse, "body", coarse)
    v = np.asarray(values, dtype=float)
    if v.shape[0] != fb.n_elements:
        raise ValueError(f"values must have {fb.n_elements} rows, got {v.shape[0]}")
    cells, _ = locate(cb, fb.centroids)
    area = fb.element_areas
    total = np.bincount(cells, weights=area, minlength=cb.n_elements)
    flat = v.reshape(v.shape[0], -1)
    out = (
        np.column_stack(
            [np.bincount(cells, weights=area * col, minlength=cb.n_elements) for col in flat.T]
        )
        / total[:, None]
    )
    return out.reshape((cb.n_elements, *v.shape[1:]))


def field_magnitude(eps: ArrayLike) -> NDArray[np.float64]:
    """Frobenius norm ``sqrt(xx^2 + yy^2 + 2 xy^2)`` of (n, 3) tensors, (n,)."""
    e = np.asarray(eps, dtype=float)
    return np.sqrt(e[:, 0] ** 2 + e[:, 1] ** 2 + 2 * e[:, 2] ** 2)


def field_direction(eps: ArrayLike) -> NDArray[np.float64]:
    """Angle (radians, in (-pi/2, pi/2]) of the principal axis of largest |eigenvalue|."""
    e = np.asarray(eps, dtype=float)
    m = 0.5 * (e[:, 0] + e[:, 1])
    theta = 0.5 * np.arctan2(2 * e[:, 2], e[:, 0] - e[:, 1])  # axis of the larger eigenvalue
    r = np.hypot(0.5 * (e[:, 0] - e[:, 1]), e[:, 2])
    flip = np.abs(m - r) > np.abs(m + r)
    theta = np.where(flip, theta + np.pi / 2, theta)
    return np.where(theta > np.pi / 2, theta - np.pi, theta)


def localisation(change: ArrayLike, area: ArrayLike, threshold: float) -> float:
    """Fraction of the area (0..1) where ``|change| > threshold`` (same units as change)."""
    c = np.abs(np.asarray(change, dtype=float))
    a = np.asarray(area, dtype=float)
    if c.shape != a.shape:
        raise ValueError(f"change and area must have the same shape, got {c.shape}, {a.shape}")
    if not threshold >= 0:
        raise ValueError(f"threshold must be >= 0, got {threshold}")
    return float(np.sum(a[c > threshold]) / np.sum(a))
