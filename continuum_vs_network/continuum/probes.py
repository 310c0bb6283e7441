"""Sparse probes: displacement and strain of a finite-element solution at chosen places.

A probe is built once (point location and basis evaluation) and is then a sparse matrix:
reading it off a solution vector is one sparse product (microseconds), which is what a
time-stepping loop or a training loop needs. Probes:

- :func:`displacement_probe`: displacement at points;
- :func:`strain_probe`: the strain tensor ``(eps_xx, eps_yy, eps_xy)`` at points;
- :func:`directional_strain_probe`: normal strain ``n.eps.n`` along given directions;
- :func:`chord_strain_probe`: the relative length change of segments ``a -> b``, what a
  spring between ``a`` and ``b`` measures (exact for uniform strain, linearised);
- :func:`region_strain_probe`: the mean strain tensor over a set of elements;
- :func:`disc_elements` and :func:`material_spring_probe`: a chord between two small
  regions (discs of a fixed radius), the continuum's spring with a size of its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .body import ElasticBody, _element_selection

__all__ = [
    "Probe",
    "chord_strain_probe",
    "directional_strain_probe",
    "disc_elements",
    "displacement_probe",
    "locate",
    "material_spring_probe",
    "region_strain_probe",
    "strain_probe",
]


@dataclass(frozen=True, eq=False)
class Probe:
    """A linear read-out ``y = operator @ u`` of a solution vector.

    Attributes
    ----------
    operator : (n_rows, n_dofs) scipy.sparse.csr_matrix
    shape : tuple of int
        Shape of one read-out (``n_rows`` values, reshaped).
    kind : str
        What is read: ``"displacement"``, ``"strain"``, ``"directional"``, ``"chord"``,
        ``"region"``.
    """

    operator: sp.csr_matrix
    shape: tuple[int, ...]
    kind: str

    def __call__(self, u: ArrayLike) -> NDArray[np.float64]:
        """Read-out of ``u`` ((n_dofs,) -> ``shape``; (n_dofs, k) -> ``shape + (k,)``)."""
        u = np.asarray(u, dtype=float)
        y = self.operator @ u
        return y.reshape(self.shape + u.shape[1:])


def _points(name: str, points: ArrayLike) -> NDArray[np.float64]:
    x = np.asarray(points, dtype=float)
    if x.ndim == 1 and x.shape == (2,):
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != 2:
        raise ValueError(f"{name} must have shape (n, 2), got {np.shape(points)}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite")
    return x


def locate(
    body: ElasticBody, points: ArrayLike, *, tol: float = 1e-9
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Element containing each point and the point's reference coordinates.

    Points on an edge go to one of the adjacent elements. A point outside the body by
    more than ``tol`` times the local element size raises ``ValueError``.

    Returns
    -------
    cells : (n,) int array
    reference : (2, n) float array
        Coordinates on the reference triangle (isoparametric inverse for curved meshes).
    """
    from scipy.spatial import cKDTree

    x = _points("points", points)
    p = body.mesh.p
    t = body.mesh.t
    a = p[:, t[0]].T
    e1 = p[:, t[1]].T - a
    e2 = p[:, t[2]].T - a
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    tree = cKDTree(p[:, t].mean(axis=1).T)
    k = min(12, t.shape[1])
    _, cand = tree.query(x, k)
    cand = np.atleast_2d(cand).reshape(x.shape[0], k)
    d = x[:, None, :] - a[cand]
    xi = (d[..., 0] * e2[cand, 1] - d[..., 1] * e2[cand, 0]) / det[cand]
    eta = (e1[cand, 0] * d[..., 1] - e1[cand, 1] * d[..., 0]) / det[cand]
    inside = np.minimum(np.minimum(xi, eta), 1 - xi - eta)
    rows = np.arange(x.shape[0])
    if body.basis.mapping.__class__.__name__ == "MappingAffine":
        best = np.argmax(inside, axis=1)
        cells = cand[rows, best]
        worst = inside[rows, best]
        ref = np.vstack([xi[rows, best], eta[rows, best]])
        for i in np.flatnonzero(worst < -tol):
            # not among the nearest centroids (slivers): search every element
            d = x[i] - a
            xi_all = (d[:, 0] * e2[:, 1] - d[:, 1] * e2[:, 0]) / det
            eta_all = (e1[:, 0] * d[:, 1] - e1[:, 1] * d[:, 0]) / det
            ins = np.minimum(np.minimum(xi_all, eta_all), 1 - xi_all - eta_all)
            j = int(np.argmax(ins))
            if ins[j] < -tol:
                raise ValueError(f"point {x[i].tolist()} lies outside the body")
            cells[i], ref[:, i] = j, (xi_all[j], eta_all[j])
        return cells.astype(np.int64), np.clip(ref, 0.0, 1.0)
    # curved (isoparametric) mesh: Newton on the exact map for the likeliest candidates
    order = np.argsort(-inside, axis=1)[:, :4]
    best_inside = np.full(x.shape[0], -np.inf)
    cells = cand[rows, order[:, 0]]
    ref = np.zeros((2, x.shape[0]))
    for c in range(order.shape[1]):
        cc = cand[rows, order[:, c]]
        X0 = np.vstack([xi[rows, order[:, c]], eta[rows, order[:, c]]])
        X = _inverse_map(body.basis.mapping, x.T, cc, X0)
        ins = np.minimum(np.minimum(X[0], X[1]), 1 - X[0] - X[1])
        ins[~np.isfinite(ins)] = -np.inf
        better = ins > best_inside
        best_inside[better] = ins[better]
        cells[better] = cc[better]
        ref[:, better] = X[:, better]
    if np.any(best_inside < -tol):
        bad = int(np.argmin(best_inside))
        raise ValueError(f"point {x[bad].tolist()} lies outside the body")
    return cells.astype(np.int64), np.clip(ref, 0.0, 1.0)


def _inverse_map(mapping: Any, x: NDArray, cells: NDArray, X: NDArray) -> NDArray:
    """Reference coordinates of points ``x`` (2, n) in ``cells`` by Newton from ``X``."""
    X = X.copy()
    for _ in range(30):
        F = mapping.F(X[:, :, None], tind=cells)[:, :, 0]
        J = mapping.invDF(X[:, :, None], tind=cells)[:, :, :, 0]
        dX = np.einsum("ijk,jk->ik", J, x - F)
        X += dX
        if np.all(np.abs(dX) < 1e-13):
            break
    return X


def _basis_at(body: ElasticBody, points: ArrayLike) -> tuple[NDArray, list[Any]]:
    cells, ref = locate(body, points)
    basis = body.basis
    fields = [
        basis.elem.gbasis(basis.mapping, ref[:, :, None], j, tind=cells)[0]
        for j in range(basis.Nbfun)
    ]
    return cells, fields


def displacement_probe(body: ElasticBody, points: ArrayLike) -> Probe:
    """Displacement ``(u_x, u_y)`` at ``points`` (n, 2): a probe of shape (n, 2)."""
    x = _points("points", points)
    n = x.shape[0]
    cells, fields = _basis_at(body, x)
    dofs = body.basis.element_dofs[:, cells]  # (Nbfun, n)
    rows, cols, vals = [], [], []
    for j, phi in enumerate(fields):
        for c in range(2):
            rows.append(2 * np.arange(n) + c)
            cols.append(dofs[j])
            vals.append(np.asarray(phi)[c, :, 0])
    op = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(2 * n, body.n_dofs),
    )
    op.eliminate_zeros()
    return Probe(op, (n, 2), "displacement")


def strain_probe(body: ElasticBody, points: ArrayLike) -> Probe:
    """Strain ``(eps_xx, eps_yy, eps_xy)`` at ``points`` (n, 2): a probe of shape (n, 3).

    The strain of a P1/P2 field jumps across element edges; a point on an edge reads the
    strain of one adjacent element.
    """
    x = _points("points", points)
    n = x.shape[0]
    cells, fields = _basis_at(body, x)
    dofs = body.basis.element_dofs[:, cells]
    rows, cols, vals = [], [], []
    for j, phi in enumerate(fields):
        G = phi.grad[:, :, :, 0]  # (2, 2, n): d v_i / d x_j
        comps = (G[0, 0], G[1, 1], 0.5 * (G[0, 1] + G[1, 0]))
        for c, v in enumerate(comps):
            rows.append(3 * np.arange(n) + c)
            cols.append(dofs[j])
            vals.append(v)
    op = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(3 * n, body.n_dofs),
    )
    op.eliminate_zeros()
    return Probe(op, (n, 3), "strain")


def _unit(name: str, directions: ArrayLike, n: int) -> NDArray:
    d = _points(name, directions)
    if d.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n}, 2), got {d.shape}")
    norm = np.linalg.norm(d, axis=1)
    if np.any(norm == 0):
        raise ValueError(f"{name} must be non-zero vectors")
    return d / norm[:, None]


def directional_strain_probe(body: ElasticBody, points: ArrayLike, directions: ArrayLike) -> Probe:
    """Normal strain ``n.eps.n`` at ``points`` along ``directions`` (n, 2): shape (n,)."""
    x = _points("points", points)
    nrm = _unit("directions", directions, x.shape[0])
    S = strain_probe(body, x).operator
    w = np.column_stack([nrm[:, 0] ** 2, nrm[:, 1] ** 2, 2 * nrm[:, 0] * nrm[:, 1]]).ravel()
    rows = np.repeat(np.arange(x.shape[0]), 3)
    combine = sp.csr_matrix((w, (rows, np.arange(3 * x.shape[0]))), shape=(x.shape[0], S.shape[0]))
    return Probe((combine @ S).tocsr(), (x.shape[0],), "directional")


def _segments(ends_a: ArrayLike, ends_b: ArrayLike):
    """The segments ``a_i -> b_i``: ends (n, 2) each, lengths (n,) and unit directions
    (n, 2); an error names the argument when the ends differ in shape or coincide."""
    a = _points("ends_a", ends_a)
    b = _points("ends_b", ends_b)
    if a.shape != b.shape:
        raise ValueError(f"ends_a and ends_b must have the same shape, got {a.shape}, {b.shape}")
    d = b - a
    length = np.linalg.norm(d, axis=1)
    if np.any(length == 0):
        raise ValueError("segments must have non-zero length")
    return a, b, length, d / length[:, None]


def chord_strain_probe(body: ElasticBody, ends_a: ArrayLike, ends_b: ArrayLike) -> Probe:
    """Linearised strain of the segments ``a_i -> b_i``: ``n.(u(b) - u(a)) / |b - a|``.

    This is what a spring from ``a`` to ``b`` reads (its strain ``r / L - 1`` to first
    order in the displacement, with ``L = |b - a|``); shape (n,).
    """
    a, b, length, nrm = _segments(ends_a, ends_b)
    n = a.shape[0]
    U = displacement_probe(body, np.vstack([a, b])).operator  # (4n, N)
    w = (nrm / length[:, None]).ravel()
    rows = np.repeat(np.arange(n), 2)
    cols_a = np.arange(2 * n)
    combine = sp.csr_matrix(
        (
            np.concatenate([-w, w]),
            (np.concatenate([rows, rows]), np.concatenate([cols_a, cols_a + 2 * n])),
        ),
        shape=(n, 4 * n),
    )
    return Probe((combine @ U).tocsr(), (n,), "chord")


def region_strain_probe(body: ElasticBody, elements: ArrayLike) -> Probe:
    """Mean strain ``(eps_xx, eps_yy, eps_xy)`` over ``elements`` (mask or indices): shape (3,)."""
    from skfem import Basis, LinearForm
    from skfem.helpers import sym_grad

    sel = _element_selection(body, elements)
    if sel.size == 0:
        raise ValueError("the region holds no element")
    sub = Basis(body.mesh, body.basis.elem, elements=sel)
    area = float(sub.dx.sum())
    rows = []
    for i, j in ((0, 0), (1, 1), (0, 1)):

        @LinearForm
        def comp(v: Any, w: Any, i: int = i, j: int = j) -> Any:
            return sym_grad(v)[i, j]

        rows.append(comp.assemble(sub) / area)
    op = sp.csr_matrix(np.vstack(rows))
    op.eliminate_zeros()
    return Probe(op, (3,), "region")


def disc_elements(body: ElasticBody, centre: ArrayLike, radius: float) -> NDArray[np.int64]:
    """Elements whose centroid lies within ``radius`` of ``centre`` (2,), plus the element
    holding ``centre``: never empty, and the disc itself as the mesh is refined."""
    c = _points("centre", centre)[0]
    if not (np.isfinite(radius) and radius >= 0):
        raise ValueError(f"radius must be finite and >= 0, got {radius}")
    near = np.flatnonzero(np.hypot(*(body.centroids - c).T) <= radius)
    cells, _ = locate(body, c[None, :], tol=1e-6)
    return np.union1d(near, cells).astype(np.int64)


def _mean_displacement_rows(body: ElasticBody, elements: NDArray) -> sp.csr_matrix:
    """(2, n_dofs): the area mean of ``(u_x, u_y)`` over ``elements``."""
    from skfem import Basis, LinearForm

    sub = Basis(body.mesh, body.basis.elem, elements=elements)
    area = float(sub.dx.sum())
    rows = []
    for c in range(2):

        @LinearForm
        def comp(v: Any, w: Any, c: int = c) -> Any:
            return v[c]

        rows.append(comp.assemble(sub) / area)
    return sp.csr_matrix(np.vstack(rows))


def material_spring_probe(
    body: ElasticBody, ends_a: ArrayLike, ends_b: ArrayLike, radius: float = 0.0
) -> Probe:
    """Linearised strain of material springs whose ends are discs of ``radius`` about
    ``a_i`` and ``b_i``: ``n.(<u>_B - <u>_A) / |b - a|`` with ``<u>`` the area mean of the
    displacement over the disc's elements (:func:`disc_elements`); shape (n,).

    ``radius = 0`` is :func:`chord_strain_probe` (point ends). A point end is a point
    constraint when clamped, whose force is singular in 2D and whose neighbourhood a
    learned field collapses onto as the mesh is refined; a disc of fixed radius has a limit.
    """
    if radius == 0:
        return chord_strain_probe(body, ends_a, ends_b)
    a, b, length, nrm = _segments(ends_a, ends_b)
    rows = []
    for ai, bi, ni, li in zip(a, b, nrm, length):
        mean_a = _mean_displacement_rows(body, disc_elements(body, ai, radius))
        mean_b = _mean_displacement_rows(body, disc_elements(body, bi, radius))
        rows.append(sp.csr_matrix(ni[None, :] / li) @ (mean_b - mean_a))
    op = sp.vstack(rows).tocsr()
    op.eliminate_zeros()
    return Probe(op, (a.shape[0],), "chord")
