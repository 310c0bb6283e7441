"""A dilating circular inclusion (eigenstrain): the closed-form (Eshelby) field and its
finite-element solution, the continuum's reference source for strain transmission."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .materials import Material

__all__ = ["InclusionField", "InclusionSolution", "eshelby_inclusion", "solve_inclusion"]

Outer = Literal["infinite", "fixed", "free"]


@dataclass(frozen=True, eq=False)
class InclusionField:
    """Closed-form field of a dilating circular inclusion (arrays shaped like ``r``).

    Attributes
    ----------
    u_r : radial displacement (length units)
    eps_rr, eps_tt : radial and hoop strains
    coefficients : (A, C, B)
        ``u = A r`` inside, ``u = C r + B / r`` outside.
    """

    u_r: NDArray[np.float64]
    eps_rr: NDArray[np.float64]
    eps_tt: NDArray[np.float64]
    coefficients: tuple[float, float, float]


def eshelby_inclusion(
    r: ArrayLike,
    *,
    radius: float,
    eigenstrain: float,
    material: Material,
    inclusion: Material | None = None,
    outer_radius: float | None = None,
    outer: Outer = "infinite",
) -> InclusionField:
    """Exact plane field of a circular inclusion with the dilation eigenstrain ``eps* I``.

    Inside (``r < radius``, Lamé parameters ``inclusion``, default ``material``) the strain
    is uniform, ``u = A r``; outside ``u = C r + B / r``. Continuity of ``u`` and of the
    radial traction at ``r = radius`` and the outer condition fix ``A, B, C``:
    ``outer="infinite"`` (``C = 0``; for equal moduli ``A = eps* (lam + mu) / (lam + 2 mu)``,
    Eshelby's result), ``"fixed"`` (``u(R) = 0``) or ``"free"`` (``sigma_rr(R) = 0``) for a
    disk of radius ``outer_radius``.

    Returns
    -------
    InclusionField
    """
    a = float(radius)
    if not a > 0:
        raise ValueError(f"radius must be > 0, got {radius}")
    inc = material if inclusion is None else inclusion
    lam, mu = material.lam, material.mu
    k1 = inc.lam + inc.mu
    M = np.zeros((3, 3))
    rhs = np.zeros(3)
    M[0] = [a, -a, -1 / a]  # continuity of u at r = a
    M[1] = [k1, -(lam + mu), mu / a**2]  # continuity of sigma_rr at r = a
    rhs[1] = k1 * float(eigenstrain)
    if outer == "infinite":
        M[2] = [0, 1, 0]
    else:
        if outer_radius is None or not outer_radius > a:
            raise ValueError(f"outer_radius must be > radius for outer={outer!r}")
        R = float(outer_radius)
        if outer == "fixed":
            M[2] = [0, R, 1 / R]
        elif outer == "free":
            M[2] = [0, lam + mu, -mu / R**2]
        else:
            raise ValueError(f"outer must be 'infinite', 'fixed' or 'free', got {outer!r}")
    A, C, B = np.linalg.solve(M, rhs)
    r = np.asarray(r, dtype=float)
    if np.any(r <= 0):
        raise ValueError("r must be > 0")
    inside = r < a
    u_r = np.where(inside, A * r, C * r + B / r)
    eps_rr = np.where(inside, A, C - B / r**2)
    eps_tt = np.where(inside, A, C + B / r**2)
    return InclusionField(u_r, eps_rr, eps_tt, (float(A), float(C), float(B)))


@dataclass(frozen=True, eq=False)
class InclusionSolution:
    """Finite-element solution of a disk with a dilating inclusion (:func:`solve_inclusion`).

    Attributes
    ----------
    body : ElasticBody
    u : (n_dofs,) float array
    exact : callable ``r -> InclusionField``
        The closed form for the same problem.
    l2_error : float
        ``|u_h - u| / |u|`` in L2 over the disk.
    seconds : float
    """

    body: object = field(repr=False)
    u: NDArray[np.float64] = field(repr=False)
    l2_error: float
    seconds: float
    radius: float
    outer_radius: float
    eigenstrain: float
    material: Material
    inclusion: Material
    outer: str

    def exact(self, r: ArrayLike) -> InclusionField:
        return eshelby_inclusion(
            r,
            radius=self.radius,
            eigenstrain=self.eigenstrain,
            material=self.material,
            inclusion=self.inclusion,
            outer_radius=self.outer_radius,
            outer=self.outer,
        )


def solve_inclusion(
    *,
    radius: float,
    outer_radius: float,
    eigenstrain: float,
    material: Material,
    inclusion: Material | None = None,
    h: float,
    order: int = 2,
    outer: Literal["fixed", "free"] = "fixed",
) -> InclusionSolution:
    """Solve a disk with a dilating circular inclusion by finite elements.

    The mesh resolves the inclusion boundary; with ``order=2`` it is curved (isoparametric).
    ``outer="free"`` removes rigid motion by fixing the centre and ``u_y`` on the positive
    ``x`` axis, which the exact (radial) solution satisfies.
    """
    from .body import eigenstrain_load, elastic_body
    from .mesh import disk_mesh
    from .static import Dirichlet, fix, solve_static

    t0 = time.perf_counter()
    inc = material if inclusion is None else inclusion
    mesh = disk_mesh(outer_radius, h=h, interfaces=[radius], curved=order == 2)
    body = elastic_body(mesh, material, order=order)
    r_el = np.hypot(*body.centroids.T)
    inside = r_el < radius
    body = body.with_material(inc, inside)
    load = eigenstrain_load(body, np.where(inside, float(eigenstrain), 0.0))
    tol = 1e-9 * outer_radius
    if outer == "fixed":
        fixed = fix(body, lambda x, y: np.hypot(x, y) > outer_radius - tol, boundary=True)
    elif outer == "free":
        centre = fix(body, lambda x, y: np.hypot(x, y) < tol)
        axis = fix(body, lambda x, y: (np.abs(y) < tol) & (x > tol), component=1)
        fixed = Dirichlet(
            np.concatenate([centre.dofs, axis.dofs]), np.concatenate([centre.values, axis.values])
        )
    else:
        raise ValueError(f"outer must be 'fixed' or 'free', got {outer!r}")
    sol = solve_static(body, fixed, load=load)
    seconds = time.perf_counter() - t0
    basis = body.basis
    uh = np.asarray(basis.interpolate(sol.u))
    X = np.asarray(basis.global_coordinates())
    r = np.hypot(X[0], X[1])
    ex = eshelby_inclusion(
        r,
        radius=radius,
        eigenstrain=eigenstrain,
        material=material,
        inclusion=inc,
        outer_radius=outer_radius,
        outer=outer,
    ).u_r
    ux, uy = ex * X[0] / r, ex * X[1] / r
    dx = basis.dx
    err = np.sqrt(np.sum(((uh[0] - ux) ** 2 + (uh[1] - uy) ** 2) * dx))
    ref = np.sqrt(np.sum((ux**2 + uy**2) * dx))
    return InclusionSolution(
        body=body,
        u=sol.u,
        l2_error=float(err / ref),
        seconds=seconds,
        radius=float(radius),
        outer_radius=float(outer_radius),
        eigenstrain=float(eigenstrain),
        material=material,
        inclusion=inc,
        outer=outer,
    )
