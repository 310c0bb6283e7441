"""A 2D linear-elastic body: a triangle mesh, P1 or P2 vector elements, Lamé parameters.

:func:`elastic_body` builds the finite-element basis once; the operators
(:func:`stiffness_matrix`, :func:`mass_matrix`) and loads (:func:`eigenstrain_load`,
:func:`pressure_load`, :func:`body_force_load`) are functions of the body. Lamé parameters
may differ from element to element (inclusions, modulus contrasts).

Degrees of freedom are scikit-fem's: for vector elements DOF ``d`` is component ``d % 2``
(``x`` or ``y``) at ``body.dof_locations[d]``; the first ``2 * n_vertices`` DOFs are the
mesh vertices, ``(2 i, 2 i + 1)`` for vertex ``i``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .materials import Material

__all__ = [
    "ElasticBody",
    "LockingWarning",
    "body_force_load",
    "dofs_where",
    "eigenstrain_load",
    "elastic_body",
    "mass_matrix",
    "near_segments",
    "pressure_load",
    "stiffness_matrix",
    "strain_energy",
    "vertex_displacement",
]

#: lam / mu above which P1 elements are warned about locking (nu > 0.4545). Measured on
#: Lamé's cylinder (ring meshes h = 0.05-0.2, the ``stability`` scene): P1's L2 error is
#: 1.6-1.9x its nu = 0.3 error at nu = 0.45 (lam / mu = 9), 2.0-2.6x at nu = 0.47 (15.7),
#: 3.5-6x at nu = 0.49 (49); the warning starts just before the error doubles.
LOCKING_RATIO = 10.0


class LockingWarning(UserWarning):
    """P1 elements on a nearly incompressible material: volumetric locking."""


def _element(order: int) -> Any:
    from skfem import ElementTriP1, ElementTriP2, ElementVector

    if order == 1:
        return ElementVector(ElementTriP1())
    if order == 2:
        return ElementVector(ElementTriP2())
    raise ValueError(f"order must be 1 or 2, got {order}")


@dataclass(frozen=True, eq=False)
class ElasticBody:
    """Mesh, finite-element basis and (element-wise) Lamé parameters of a 2D body.

    Build with :func:`elastic_body`.

    Attributes
    ----------
    mesh : skfem.MeshTri1 or skfem.MeshTri2
    basis : skfem.CellBasis
        Vector P1 or P2 basis on ``mesh``.
    order : int
        Polynomial order, 1 or 2.
    lam, mu : (n_elements,) float arrays
        2D Lamé parameters of each element (force per length).
    dof_locations : (n_dofs, 2) float array
    dof_component : (n_dofs,) int array
        0 for an ``x`` displacement DOF, 1 for ``y``.
    """

    mesh: Any
    basis: Any
    order: int
    lam: NDArray[np.float64]
    mu: NDArray[np.float64]
    dof_locations: NDArray[np.float64] = field(repr=False)
    dof_component: NDArray[np.int64] = field(repr=False)

    @property
    def n_dofs(self) -> int:
        return int(self.basis.N)

    @property
    def n_elements(self) -> int:
        return int(self.mesh.t.shape[1])

    @property
    def n_vertices(self) -> int:
        return int(self.mesh.t.max() + 1)

    @property
    def centroids(self) -> NDArray[np.float64]:
        """Element centroids of the straight-sided triangles, (n_elements, 2)."""
        return self.mesh.p[:, self.mesh.t].mean(axis=1).T

    @property
    def element_areas(self) -> NDArray[np.float64]:
        """Element areas (curved elements included), (n_elements,) float array."""
        return np.asarray(self.basis.dx.sum(axis=1))

    def with_material(self, material: Material, elements: ArrayLike | None = None) -> ElasticBody:
        """A copy with ``material`` in ``elements`` (bool mask or indices; default all)."""
        lam, mu = self.lam.copy(), self.mu.copy()
        sel = slice(None) if elements is None else _element_selection(self, elements)
        lam[sel] = material.lam
        mu[sel] = material.mu
        _check_locking(self.order, lam, mu)
        lam.setflags(write=False)
        mu.setflags(write=False)
        return ElasticBody(
            self.mesh, self.basis, self.order, lam, mu, self.dof_locations, self.dof_component
        )

    def elements_where(self, where: Callable[[NDArray, NDArray], NDArray]) -> NDArray[np.bool_]:
        """Mask of elements whose centroid ``(x, y)`` satisfies ``where(x, y)``."""
        c = self.centroids
        return np.asarray(where(c[:, 0], c[:, 1]), dtype=bool)

    def __repr__(self) -> str:
        return f"ElasticBody(P{self.order}, n_elements={self.n_elements}, n_dofs={self.n_dofs})"


def _element_selection(body: ElasticBody, elements: ArrayLike) -> NDArray[np.int64]:
    arr = np.asarray(elements)
    if arr.dtype == bool:
        if arr.shape != (body.n_elements,):
            raise ValueError(f"elements mask must have shape ({body.n_elements},), got {arr.shape}")
        return np.flatnonzero(arr)
    arr = arr.astype(np.int64).ravel()
    if arr.size and (arr.min() < 0 or arr.max() >= body.n_elements):
        raise ValueError(f"elements must lie in 0..{body.n_elements - 1}")
    return arr


def _check_locking(order: int, lam: NDArray, mu: NDArray) -> None:
    ratio = float(np.max(lam / mu))
    if order == 1 and ratio > LOCKING_RATIO:
        warnings.warn(
            f"lam / mu = {ratio:.3g} > {LOCKING_RATIO:g} (nearly incompressible): P1 elements "
            "lock and underestimate displacements; use order=2",
            LockingWarning,
            stacklevel=3,
        )


def elastic_body(
    mesh: Any,
    material: Material,
    *,
    order: int = 2,
    min_angle: float = 1e-3,
) -> ElasticBody:
    """Build an elastic body on ``mesh``.

    Parameters
    ----------
    mesh : skfem.MeshTri1 or skfem.MeshTri2
        For ``MeshTri2`` (curved) meshes the basis is isoparametric.
    material : Material
        Lamé parameters of every element (change regions with
        :meth:`ElasticBody.with_material`).
    order : {1, 2}
        Polynomial order of the displacement (P2 by default: P1 locks for nearly
        incompressible materials and converges one order slower).
    min_angle : float
        Smallest interior angle (degrees) accepted; flatter elements raise ``ValueError``.

    Returns
    -------
    ElasticBody
    """
    from skfem import Basis

    from .mesh import mesh_quality

    if not isinstance(material, Material):
        raise ValueError(f"material must be a Material, got {type(material).__name__}")
    element = _element(order)
    if mesh.t.shape[0] != 3 or mesh.p.shape[0] != 2:
        raise ValueError("mesh must be a 2D triangle mesh (skfem.MeshTri1 or MeshTri2)")
    curved = mesh.doflocs.shape[1] > mesh.t.max() + 1
    if curved and order != 2:
        raise ValueError(
            "a curved (quadratic, MeshTri2) mesh needs order=2 elements; P1 on it does not "
            "reproduce uniform strain. Build the mesh with curved=False for P1"
        )
    quality = mesh_quality(mesh)
    if not quality.min_angle >= min_angle:
        raise ValueError(
            f"mesh has an element with an interior angle of {quality.min_angle:.3g} degrees "
            f"(< min_angle={min_angle}); it is degenerate. Remesh, or lower min_angle"
        )
    if quality.tangled:
        raise ValueError(
            f"mesh is tangled: {quality.tangled} interior edges have both their triangles on "
            "one side (inverted, overlapping elements). Untangle or remesh"
        )
    basis = Basis(mesh, element)
    n_el = int(mesh.t.shape[1])
    lam = np.full(n_el, material.lam)
    mu = np.full(n_el, material.mu)
    _check_locking(order, lam, mu)
    lam.setflags(write=False)
    mu.setflags(write=False)
    component = np.empty(basis.N, dtype=np.int64)
    for dofs in (basis.nodal_dofs, basis.facet_dofs):
        if dofs is not None and dofs.size:
            component[dofs[0]] = 0
            component[dofs[1]] = 1
    locations = np.ascontiguousarray(basis.doflocs.T)
    locations.setflags(write=False)
    component.setflags(write=False)
    return ElasticBody(mesh, basis, int(order), lam, mu, locations, component)


def _field(body: ElasticBody, values: NDArray) -> NDArray:
    """Element-wise constant values as a quadrature field, (n_elements, 1) broadcast over the
    quadrature points (measured 2x faster to assemble than a full (n_elements, n_points)
    array or a Python scalar)."""
    return np.ascontiguousarray(np.asarray(values, dtype=float)[:, None])


def stiffness_matrix(
    body: ElasticBody, *, lam: ArrayLike | None = None, mu: ArrayLike | None = None
) -> sp.csr_matrix:
    """Stiffness matrix ``K`` (n_dofs, n_dofs) of ``sigma = lam tr(eps) I + 2 mu eps``.

    ``lam`` and ``mu`` default to the body's; pass others (scalars or (n_elements,)
    arrays) to assemble, for example, the viscous Kelvin-Voigt matrix.
    """
    from skfem import BilinearForm
    from skfem.helpers import ddot, sym_grad, trace

    @BilinearForm
    def elasticity(u: Any, v: Any, w: Any) -> Any:
        eu, ev = sym_grad(u), sym_grad(v)
        return 2.0 * w.mu * ddot(eu, ev) + w.lam * trace(eu) * trace(ev)

    lam_e = body.lam if lam is None else np.broadcast_to(np.asarray(lam, float), body.lam.shape)
    mu_e = body.mu if mu is None else np.broadcast_to(np.asarray(mu, float), body.mu.shape)
    return elasticity.assemble(body.basis, lam=_field(body, lam_e), mu=_field(body, mu_e)).tocsr()


def mass_matrix(body: ElasticBody, density: ArrayLike = 1.0) -> sp.csr_matrix:
    """Consistent mass matrix ``int rho u.v`` (n_dofs, n_dofs); ``density`` scalar or per element.

    (scikit-fem's shipped ``mass`` form is scalar; this one is written for vector bases.)
    """
    from skfem import BilinearForm
    from skfem.helpers import dot

    rho = np.broadcast_to(np.asarray(density, dtype=float), (body.n_elements,))
    if np.any(~np.isfinite(rho)) or np.any(rho < 0):
        raise ValueError("density must be finite and >= 0")

    @BilinearForm
    def mass(u: Any, v: Any, w: Any) -> Any:
        return w.rho * dot(u, v)

    return mass.assemble(body.basis, rho=_field(body, rho)).tocsr()


def eigenstrain_load(body: ElasticBody, eigenstrain: ArrayLike) -> NDArray[np.float64]:
    """Load vector of an isotropic eigenstrain ``eps* I`` (a dilation), (n_dofs,).

    ``eigenstrain`` is a scalar or an (n_elements,) array; the stress is
    ``sigma = C : (eps - eps* I)`` so the load is ``int 2 (lam + mu) eps* div v``.
    """
    from skfem import LinearForm
    from skfem.helpers import div

    e = np.broadcast_to(np.asarray(eigenstrain, dtype=float), (body.n_elements,))
    if np.any(~np.isfinite(e)):
        raise ValueError("eigenstrain must be finite")

    @LinearForm
    def load(v: Any, w: Any) -> Any:
        return w.s * div(v)

    return load.assemble(body.basis, s=_field(body, 2.0 * (body.lam + body.mu) * e))


def body_force_load(
    body: ElasticBody, force: Callable[[NDArray, NDArray], tuple[NDArray, NDArray]]
) -> NDArray[np.float64]:
    """Load vector of a body force ``f(x, y) -> (f_x, f_y)`` (force per area), (n_dofs,)."""
    from skfem import LinearForm

    @LinearForm
    def load(v: Any, w: Any) -> Any:
        fx, fy = force(w.x[0], w.x[1])
        return fx * v[0] + fy * v[1]

    return load.assemble(body.basis)


def pressure_load(
    body: ElasticBody,
    pressure: float,
    *,
    where: Callable[[NDArray, NDArray], NDArray] | None = None,
) -> NDArray[np.float64]:
    """Load vector of a pressure ``p`` (force per length, pushing inwards) on boundary facets.

    ``where(x, y)`` selects boundary facets by their midpoints (default: all).
    """
    from skfem import FacetBasis, LinearForm

    facets = body.mesh.boundary_facets()
    if where is not None:
        mid = body.mesh.p[:, body.mesh.facets[:, facets]].mean(axis=1)
        facets = facets[np.asarray(where(mid[0], mid[1]), dtype=bool)]
    if facets.size == 0:
        raise ValueError("no boundary facet satisfies `where`")
    fb = FacetBasis(body.mesh, body.basis.elem, facets=facets)
    p = float(pressure)

    @LinearForm
    def load(v: Any, w: Any) -> Any:
        return -p * (w.n[0] * v[0] + w.n[1] * v[1])

    return load.assemble(fb)


def dofs_where(
    body: ElasticBody,
    where: Callable[[NDArray, NDArray], NDArray],
    *,
    component: int | None = None,
    boundary: bool = False,
) -> NDArray[np.int64]:
    """DOF indices whose location ``(x, y)`` satisfies ``where(x, y)``.

    Parameters
    ----------
    component : {0, 1, None}
        Only ``x`` (0) or ``y`` (1) DOFs; both by default.
    boundary : bool
        Only DOFs on the boundary (vertices and, for P2, edge midpoints of boundary facets).
    """
    loc = body.dof_locations
    mask = np.asarray(where(loc[:, 0], loc[:, 1]), dtype=bool)
    if component is not None:
        if component not in (0, 1):
            raise ValueError(f"component must be 0, 1 or None, got {component}")
        mask &= body.dof_component == component
    if boundary:
        on = np.zeros(body.n_dofs, dtype=bool)
        on[body.basis.get_dofs().flatten()] = True
        mask &= on
    return np.flatnonzero(mask)


def near_segments(
    starts: ArrayLike, ends: ArrayLike, *, tol: float = 1e-9
) -> Callable[[NDArray, NDArray], NDArray]:
    """A ``where(x, y)`` selecting points within ``tol`` of any segment ``starts[i] -> ends[i]``.

    Use it to fix the DOFs on a network's outline edges (for example the springs between
    the pinned nodes of a lattice's side), whatever the mesh refinement.
    """
    a = np.atleast_2d(np.asarray(starts, dtype=float))
    b = np.atleast_2d(np.asarray(ends, dtype=float))
    if a.shape != b.shape or a.shape[1] != 2:
        raise ValueError(f"starts and ends must both have shape (m, 2), got {a.shape}, {b.shape}")
    d = b - a
    dd = np.maximum(np.sum(d * d, axis=1), 1e-300)

    def where(x: NDArray, y: NDArray) -> NDArray:
        p = np.stack([np.asarray(x, float).ravel(), np.asarray(y, float).ravel()], axis=1)
        hit = np.zeros(p.shape[0], dtype=bool)
        for k in range(a.shape[0]):
            s = np.clip(((p - a[k]) @ d[k]) / dd[k], 0.0, 1.0)
            hit |= np.hypot(*(p - a[k] - s[:, None] * d[k]).T) <= tol
        return hit.reshape(np.shape(x))

    return where


def vertex_displacement(body: ElasticBody, u: ArrayLike) -> NDArray[np.float64]:
    """Displacement of each mesh vertex, (n_vertices, 2), from a solution vector ``u``."""
    u = np.asarray(u, dtype=float)
    if u.shape != (body.n_dofs,):
        raise ValueError(f"u must have shape ({body.n_dofs},), got {u.shape}")
    return np.column_stack([u[body.basis.nodal_dofs[0]], u[body.basis.nodal_dofs[1]]])


def strain_energy(body: ElasticBody, u: ArrayLike, K: sp.spmatrix | None = None) -> float:
    """Elastic energy ``u.K.u / 2`` (energy per thickness)."""
    u = np.asarray(u, dtype=float)
    K = stiffness_matrix(body) if K is None else K
    return float(0.5 * u @ (K @ u))
