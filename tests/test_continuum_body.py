"""Continuum body: meshes, static solves against closed forms, convergence rates, locking."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("skfem")

from continuum_vs_network.continuum.body import (
    LockingWarning,
    elastic_body,
    pressure_load,
    stiffness_matrix,
)
from continuum_vs_network.continuum.materials import Material, plane_stress_lambda
from continuum_vs_network.continuum.mesh import (
    annulus_mesh,
    disk_mesh,
    mesh_quality,
    network_mesh,
    rectangle_mesh,
)
from continuum_vs_network.continuum.static import Dirichlet, fix, solve_static
from continuum_vs_network.network.builders import triangular_lattice


def test_importing_the_package_does_not_import_scikit_fem():
    code = (
        "import sys\n"
        "import continuum_vs_network, continuum_vs_network.continuum as c\n"
        "from continuum_vs_network.continuum import (body, materials, mesh, probes, static,\n"
        "    transmission, viscoelastic)\n"
        "before = 'skfem' in sys.modules\n"
        "c.rectangle_mesh(1.0, 1.0, h=0.5)\n"
        "print(before, 'skfem' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True"]


# -- meshes -----------------------------------------------------------------------------------
def _area(mesh) -> float:
    p, t = mesh.p.T, mesh.t.T
    d1, d2 = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    return float(np.sum(0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])))


@pytest.mark.parametrize("h", [0.2, 0.1])
def test_ring_meshes_are_well_shaped_and_resolve_their_circles(h):
    disk = disk_mesh(1.0, h=h, interfaces=[0.4])
    ring = annulus_mesh(0.5, 1.0, h=h)
    for m in (disk, ring):
        q = mesh_quality(m)
        assert q.min_angle > 25.0
        assert 0.7 * h < q.h < 1.3 * h
    # the straight-sided polygon loses area O(h^2); every boundary vertex is on the circle
    assert 0 < np.pi - _area(disk) < 2.0 * h**2
    r = np.hypot(*disk.p[:, disk.boundary_nodes()])
    assert np.allclose(r, 1.0)
    # the interface circle is made of vertices
    r_all = np.hypot(*disk.p)
    assert np.sum(np.isclose(r_all, 0.4)) >= 2 * np.pi * 0.4 / h - 1


def test_curved_disk_area_is_exact_to_high_order():
    from skfem import Basis, ElementTriP2

    errors = []
    for h in (0.4, 0.2):
        m = disk_mesh(1.0, h=h, curved=True)
        errors.append(abs(Basis(m, ElementTriP2()).dx.sum() - np.pi))
    # quadratic arcs: area error O(h^4) against O(h^2) for straight sides
    assert errors[1] < 1e-3
    assert np.log2(errors[0] / errors[1]) > 3.5


def test_network_mesh_is_the_union_of_the_lattice_triangles():
    net = triangular_lattice(5, 4, spacing=0.5)
    m0 = network_mesh(net)
    n_faces = 2 * (5 - 1) * (4 - 1)
    assert m0.t.shape[1] == n_faces
    assert _area(m0) == pytest.approx(n_faces * np.sqrt(3) / 4 * 0.25, rel=1e-12)
    np.testing.assert_array_equal(m0.p.T[: net.n_nodes], net.positions)
    m2 = network_mesh(net, refine=2)
    assert m2.t.shape[1] == 16 * n_faces
    assert mesh_quality(m2).min_angle == pytest.approx(60.0)


# -- materials ---------------------------------------------------------------------------------
def test_plane_stress_and_plane_strain_lame_parameters():
    E, nu = 3.0, 0.3
    strain = Material.from_young(E, nu, plane="strain")
    stress = Material.from_young(E, nu, plane="stress")
    assert strain.mu == stress.mu == pytest.approx(E / 2.6)
    assert stress.lam == pytest.approx(plane_stress_lambda(strain.lam, strain.mu), rel=1e-14)
    assert strain.poisson_plane_strain == pytest.approx(nu)
    with pytest.raises(ValueError, match="poisson"):
        Material.from_young(E, 0.5)
    with pytest.raises(ValueError, match="mu"):
        Material(1.0, 0.0)


# -- static solves --------------------------------------------------------------------------------
def _shaken_square(*, amplitude: float, seed: int):
    """Unit square mesh (h = 0.1) with its interior vertices moved at random."""
    from dataclasses import replace

    rng = np.random.default_rng(seed)
    m = rectangle_mesh(1.0, 1.0, h=0.1)
    p = m.p.copy()
    inner = np.setdiff1d(np.arange(p.shape[1]), m.boundary_nodes())
    p[:, inner] += rng.uniform(-amplitude, amplitude, size=(2, inner.size))
    return replace(m, doflocs=p)


@pytest.mark.parametrize("order", [1, 2])
def test_uniform_strain_is_exact_on_badly_shaped_elements(order):
    """Patch test: a linear displacement on the boundary is reproduced inside, even on slivers."""
    m = _shaken_square(amplitude=0.04, seed=3)
    q = mesh_quality(m)
    assert q.min_angle < 1.0 and q.tangled == 0
    body = elastic_body(m, Material(2.0, 1.0), order=order)
    G = np.array([[1e-3, 4e-3], [-2e-3, 5e-4]])
    fixed = fix(
        body,
        lambda x, y: np.ones_like(x, bool),
        boundary=True,
        displacement=lambda x, y: (G[0, 0] * x + G[0, 1] * y, G[1, 0] * x + G[1, 1] * y),
    )
    sol = solve_static(body, fixed)
    loc = body.dof_locations
    exact = np.where(body.dof_component == 0, loc @ G[0], loc @ G[1])
    assert np.max(np.abs(sol.u - exact)) < 1e-12
    # and the probes find every point, slivers included
    from continuum_vs_network.continuum.probes import strain_probe

    pts = np.random.default_rng(0).uniform(0, 1, size=(500, 2))
    E = 0.5 * (G + G.T)
    np.testing.assert_allclose(
        strain_probe(body, pts)(sol.u), np.tile([E[0, 0], E[1, 1], E[0, 1]], (500, 1)), atol=1e-12
    )


def test_degenerate_elements_and_free_bodies_raise_clear_errors():
    from skfem import MeshTri1

    flat = MeshTri1(
        np.array([[0.0, 1.0, 2.0, 0.0], [0.0, 0.0, 0.0, 1.0]]), np.array([[0, 1, 3], [0, 1, 2]]).T
    )
    with pytest.raises(ValueError, match="degenerate"):
        elastic_body(flat, Material(1.0, 1.0))
    tangled = _shaken_square(amplitude=0.045, seed=2)
    assert mesh_quality(tangled).tangled > 0
    with pytest.raises(ValueError, match="tangled"):
        elastic_body(tangled, Material(1.0, 1.0))
    body = elastic_body(rectangle_mesh(1.0, 1.0, h=0.5), Material(1.0, 1.0), order=1)
    one_point = fix(body, lambda x, y: (x == 0) & (y == 0))
    with pytest.raises(ValueError, match="rigid"):
        solve_static(body, one_point)
    with pytest.raises(ValueError, match="rigid"):
        solve_static(body, Dirichlet(np.empty(0, int), np.empty(0)))
    with pytest.raises(ValueError, match="order=2"):
        elastic_body(disk_mesh(1.0, h=0.5, curved=True), Material(1.0, 1.0), order=1)


def _thick_cylinder(material: Material, a: float, b: float, p: float):
    """Lamé's thick cylinder: pressure p inside (r = a), clamped outside (r = b)."""
    lam, mu = material.lam, material.mu
    A = -p / (2 * (lam + mu) + 2 * mu * b**2 / a**2)
    B = -A * b**2

    def u(x, y):
        r = np.hypot(x, y)
        ur = A * r + B / r
        return ur * x / r, ur * y / r

    return u


def _annulus_error(material: Material, h: float, order: int, curved: bool) -> tuple[float, int]:
    a, b, p = 1.0, 2.0, 1.0
    body = elastic_body(annulus_mesh(a, b, h=h, curved=curved), material, order=order)
    load = pressure_load(body, p, where=lambda x, y: np.hypot(x, y) < 1.5)
    fixed = fix(body, lambda x, y: np.hypot(x, y) > 1.5, boundary=True)
    sol = solve_static(body, fixed, load=load)
    uh = np.asarray(body.basis.interpolate(sol.u))
    X = np.asarray(body.basis.global_coordinates())
    ux, uy = _thick_cylinder(material, a, b, p)(X[0], X[1])
    dx = body.basis.dx
    err = np.sqrt(np.sum(((uh[0] - ux) ** 2 + (uh[1] - uy) ** 2) * dx))
    return float(err / np.sqrt(np.sum((ux**2 + uy**2) * dx))), body.n_dofs


@pytest.mark.parametrize(
    ("order", "curved", "rate"),
    [(1, False, 2.0), (2, True, 3.0), (2, False, 2.0)],
    ids=["P1", "P2-curved", "P2-straight-boundary"],
)
def test_thick_cylinder_converges_at_the_expected_rate(order, curved, rate):
    """L2 error against Lamé's solution: P1 h^2, isoparametric P2 h^3, and P2 on a polygonal
    boundary only h^2 (the geometry error dominates)."""
    mat = Material.from_young(1.0, 0.3)
    e = [_annulus_error(mat, h, order, curved)[0] for h in (0.2, 0.1, 0.05)]
    rates = np.log2(np.array(e[:-1]) / np.array(e[1:]))
    assert np.all(np.abs(rates - rate) < 0.15), rates


def test_nearly_incompressible_material_locks_p1_not_p2():
    mat = Material.from_young(1.0, 0.49999)
    with pytest.warns(LockingWarning):
        e1, _ = _annulus_error(mat, 0.1, 1, False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", LockingWarning)
        e2, _ = _annulus_error(mat, 0.1, 2, True)
    assert e1 > 0.3  # P1: tens of percent wrong
    assert e2 < 0.01  # P2: within a percent


def test_orderings_agree_and_modulus_contrast_1e6_is_solved():
    body = elastic_body(rectangle_mesh(2.0, 1.0, h=0.1), Material(1.0, 1.0), order=2)
    stiff = body.elements_where(lambda x, y: (x > 0.8) & (x < 1.2))
    body = body.with_material(Material(1e6, 1e6), stiff)
    fixed = fix(body, lambda x, y: x < 1e-9) + fix(
        body, lambda x, y: x > 2 - 1e-9, displacement=(1e-3, 0.0)
    )
    K = stiffness_matrix(body)
    a = solve_static(body, fixed, K=K)
    b = solve_static(body, fixed, K=K, ordering="COLAMD")
    assert np.max(np.abs(a.u - b.u)) < 1e-8 * np.max(np.abs(a.u))
    # the rigid middle hardly strains: the soft parts take the whole stretch; the reaction
    # balances (no net force)
    assert abs(a.reaction.sum()) < 1e-5 * np.abs(a.reaction).max()
    from continuum_vs_network.continuum.probes import strain_probe

    eps = strain_probe(body, [[1.0, 0.5], [0.4, 0.5]])(a.u)
    assert abs(eps[0, 0]) < 1e-5 * abs(eps[1, 0])
