"""Strain transmission: Eshelby inclusion, probes, decay with distance, network vs continuum."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

pytest.importorskip("skfem")

import continuum_vs_network as cvn
from continuum_vs_network.continuum.body import elastic_body
from continuum_vs_network.continuum.inclusion import eshelby_inclusion, solve_inclusion
from continuum_vs_network.continuum.materials import Material, lattice_lame
from continuum_vs_network.continuum.mesh import disk_mesh, network_faces, network_mesh
from continuum_vs_network.continuum.probes import (
    chord_strain_probe,
    directional_strain_probe,
    displacement_probe,
    region_strain_probe,
    strain_probe,
)
from continuum_vs_network.continuum.static import solve_static
from continuum_vs_network.continuum.transmission import (
    continuum_transmission,
    decay_exponent,
    network_dirichlet,
    network_patch_source,
    network_transmission,
    patch_source,
    strain_profile,
)
from continuum_vs_network.network.builders import triangular_lattice

UNIT = Material(1.0, 1.0)


# -- the inclusion -------------------------------------------------------------------------------
def test_eshelby_closed_form():
    lam, mu, es, a = 0.7, 1.3, 0.02, 0.5
    mat = Material(lam, mu)
    f = eshelby_inclusion(np.array([0.1, 0.3, 1.0, 2.0]), radius=a, eigenstrain=es, material=mat)
    A = es * (lam + mu) / (lam + 2 * mu)  # Eshelby: uniform strain inside
    np.testing.assert_allclose(f.eps_rr[:2], A)
    np.testing.assert_allclose(f.eps_tt[:2], A)
    r = np.array([1.0, 2.0])  # outside: pure shear, u = A a^2 / r
    np.testing.assert_allclose(f.u_r[2:], A * a**2 / r)
    np.testing.assert_allclose(f.eps_rr[2:] + f.eps_tt[2:], 0.0, atol=1e-18)
    # a finite disk tends to the infinite body as its radius grows
    far = [
        eshelby_inclusion(
            np.array([1.0]), radius=a, eigenstrain=es, material=mat, outer_radius=R, outer="free"
        ).u_r[0]
        for R in (5.0, 50.0)
    ]
    assert abs(far[1] - A * a**2) < 0.01 * abs(far[0] - A * a**2)


@pytest.mark.parametrize("outer", ["fixed", "free"])
def test_inclusion_finite_elements_converge_to_eshelby(outer):
    errors = {}
    for order in (1, 2):
        errors[order] = [
            solve_inclusion(
                radius=0.5,
                outer_radius=2.0,
                eigenstrain=0.01,
                material=UNIT,
                h=h,
                order=order,
                outer=outer,
            ).l2_error
            for h in (0.2, 0.1)
        ]
    assert np.log2(errors[1][0] / errors[1][1]) == pytest.approx(2.0, abs=0.25)
    assert np.log2(errors[2][0] / errors[2][1]) == pytest.approx(3.0, abs=0.35)
    assert errors[2][1] < 3e-4


@pytest.mark.parametrize("contrast", [1e6, 1e-6])
def test_inclusion_with_modulus_contrast_1e6(contrast):
    stiff = Material(contrast, contrast)
    sol = solve_inclusion(
        radius=0.5, outer_radius=2.0, eigenstrain=0.01, material=UNIT, inclusion=stiff, h=0.1
    )
    assert sol.l2_error < 1e-3
    A = sol.exact(np.array([0.1])).coefficients[0]
    # a stiff inclusion keeps its eigenstrain, a soft one is squeezed flat
    assert (A == pytest.approx(0.01, rel=1e-5)) if contrast > 1 else (abs(A) < 1e-7)


# -- probes --------------------------------------------------------------------------------
@pytest.mark.parametrize(("order", "curved"), [(1, False), (2, False), (2, True)])
def test_probes_read_a_uniform_strain_exactly(order, curved):
    body = elastic_body(disk_mesh(1.0, h=0.25, curved=curved), UNIT, order=order)
    G = np.array([[0.01, 0.02], [-0.005, 0.03]])
    E = 0.5 * (G + G.T)
    full = body.dof_locations @ G.T
    u = np.where(body.dof_component == 0, full[:, 0], full[:, 1])
    rng = np.random.default_rng(1)
    r, t = 0.95 * np.sqrt(rng.uniform(size=40)), rng.uniform(0, 2 * np.pi, 40)
    pts = np.column_stack([r * np.cos(t), r * np.sin(t)])
    np.testing.assert_allclose(displacement_probe(body, pts)(u), pts @ G.T, atol=1e-15)
    np.testing.assert_allclose(
        strain_probe(body, pts)(u), np.tile([E[0, 0], E[1, 1], E[0, 1]], (40, 1)), atol=1e-14
    )
    n = rng.normal(size=(40, 2))
    n /= np.linalg.norm(n, axis=1)[:, None]
    expect = np.einsum("ni,ij,nj->n", n, E, n)
    np.testing.assert_allclose(directional_strain_probe(body, pts, n)(u), expect, atol=1e-14)
    chord = chord_strain_probe(body, pts[:20], pts[20:])(u)
    d = pts[20:] - pts[:20]
    d /= np.linalg.norm(d, axis=1)[:, None]
    np.testing.assert_allclose(chord, np.einsum("ni,ij,nj->n", d, E, d), atol=1e-14)
    region = region_strain_probe(body, body.elements_where(lambda x, y: x > 0))(u)
    np.testing.assert_allclose(region, [E[0, 0], E[1, 1], E[0, 1]], atol=1e-14)
    with pytest.raises(ValueError, match="outside"):
        displacement_probe(body, [[1.5, 0.0]])


# -- strain against distance ---------------------------------------------------------------------
def _central_horizontal_spring(net) -> int:
    x = net.positions
    mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
    flat = np.abs(x[net.springs[:, 1], 1] - x[net.springs[:, 0], 1]) < 1e-9
    return int(np.argmin(np.hypot(*(mid - x.mean(axis=0)).T) + 1e3 * ~flat))


def test_clamped_spring_and_patch_source_transmit_alike():
    """Lattice with a clamped spring vs the continuum with two rigid patches: the same
    far-field pattern (a force dipole), both decaying as r^-2."""
    net = triangular_lattice(25, 29)
    src = _central_horizontal_spring(net)
    tn = network_transmission(net, src, 0.01)
    tc = continuum_transmission(net, src, 0.01, material=lattice_lame(1.0))
    np.testing.assert_array_equal(tn.springs, tc.springs)
    fits = [decay_exponent(t.distance, t.strain, r_min=2.0, r_max=9.0) for t in (tn, tc)]
    for fit in fits:
        assert fit.exponent == pytest.approx(2.0, abs=0.15)
    far = (tn.distance > 3) & (tn.distance < 9)
    assert np.corrcoef(tn.strain[far], tc.strain[far])[0, 1] > 0.98
    ratio = np.linalg.lstsq(tc.strain[far][:, None], tn.strain[far], rcond=None)[0][0]
    assert 0.7 < ratio < 1.4
    prof = strain_profile(tn.distance, tn.strain, bins=[1.0, 2.0, 4.0, 8.0])
    assert np.all(np.diff(prof.strain) < 0)


def test_dilated_springs_act_as_an_eshelby_inclusion():
    """Springs within a radius lengthened by 1 %: uniform strain inside as Eshelby predicts
    (free finite body), strain decaying as r^-2 outside."""
    net = triangular_lattice(35, 41)
    x = net.positions
    c = x[np.argmin(np.hypot(*(x - x.mean(axis=0)).T))]
    mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
    r = np.hypot(*(mid - c).T)
    a, es = 4.0, 0.01
    eq = cvn.relax(net.with_rest_length(net.rest_length * np.where(r < a, 1 + es, 1.0)), tol=1e-12)
    S = net.strains(eq.positions)
    R = 0.5 * min(np.ptp(x[:, 0]), np.ptp(x[:, 1]))
    A = eshelby_inclusion(
        np.array([1.0]),
        radius=a,
        eigenstrain=es,
        material=lattice_lame(1.0),
        outer_radius=R,
        outer="free",
    ).coefficients[0]
    assert S[r < a - 1.5].mean() == pytest.approx(A, rel=0.03)
    fit = decay_exponent(r, S, r_min=a + 1.5, r_max=R - 4)
    assert fit.exponent == pytest.approx(2.0, abs=0.15)


# -- network against continuum, refining the lattice -------------------------------------------
def _outline_nodes(net) -> np.ndarray:
    faces = network_faces(net)
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    edges, count = np.unique(e, axis=0, return_counts=True)
    return np.unique(edges[count == 1])


def _unit_lattice(n: int):
    a = 1.0 / (n - 1)
    return triangular_lattice(n, round(1.0 / (a * np.sqrt(3) / 2)) + 1, spacing=a), a


def test_lattice_converges_to_the_elastic_solution_at_second_order():
    """Exact boundary data from a solution of Navier's equations (u = grad phi, phi
    harmonic): the lattice's interior error falls as a^2 (a centrosymmetric lattice is a
    second-order discretisation of lam = mu = sqrt(3) k / 4)."""

    def exact(x, y):
        return 0.01 * np.exp(x) * np.cos(y), -0.01 * np.exp(x) * np.sin(y)

    errors = []
    for n in (9, 17, 33):
        net, _ = _unit_lattice(n)
        x = net.positions
        held = np.zeros(net.n_nodes, bool)
        held[_outline_nodes(net)] = True
        fi, bi = np.flatnonzero(np.repeat(~held, 2)), np.flatnonzero(np.repeat(held, 2))
        H = cvn.hessian(x, net).tocsr()
        ue = np.column_stack(exact(*x.T)).ravel()
        u = ue.copy()
        u[fi] = spla.spsolve(H[fi][:, fi].tocsc(), -H[fi][:, bi] @ ue[bi])
        errors.append(np.linalg.norm(u - ue) / np.linalg.norm(ue))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > 1.8), rates


def _patch_source_errors(sizes, *, matched: bool) -> list[float]:
    errors = []
    for n in sizes:
        net, _ = _unit_lattice(n)
        x = net.positions
        c = x.mean(axis=0)
        shift = np.array([0.15, 0.0])
        A, B, rho = c - shift, c + shift, 0.08
        pinned, x0 = network_patch_source(net, A, B, radius=rho, opening=0.01)
        eq = cvn.relax(net, pinned=pinned, x0=x0, tol=1e-12)
        body = elastic_body(network_mesh(net, refine=1), lattice_lame(1.0), order=2)
        if matched:  # hold exactly the lattice triangles the network holds
            nodes = np.flatnonzero(pinned[:, 0])
            fixed = network_dirichlet(body, net, nodes, (x0 - x)[nodes])
        else:  # hold every DOF within the patch radius
            fixed = patch_source(body, A, B, radius=rho, opening=0.01)
        sol = solve_static(body, fixed)
        away = (np.hypot(*(x - A).T) > 2 * rho) & (np.hypot(*(x - B).T) > 2 * rho)
        uc = displacement_probe(body, x[away])(sol.u)
        un = (eq.positions - x)[away]
        errors.append(np.linalg.norm(un - uc) / np.linalg.norm(uc))
    return errors


def test_patch_source_in_a_lattice_approaches_the_continuum_of_its_shape():
    """Two rigid patches of fixed size moved apart in lattices of shrinking spacing a and in
    the continuum of the same outline, holding the same lattice triangles: the displacement
    away from the patches agrees better and better, at first order in a (the free outline
    and the patch edges carry an O(a) boundary layer; the interior is second order, see
    above). Measured: 7.8 %, 5.9 %, 4.7 % at a = 1/16, 1/24, 1/32 (rate 0.75; 1.1 from
    1/32 to 1/64, see the slow test)."""
    sizes = (17, 25, 33)
    errors = _patch_source_errors(sizes, matched=True)
    a = 1.0 / (np.array(sizes) - 1)
    rate = np.polyfit(np.log(a), np.log(errors), 1)[0]
    assert np.all(np.diff(errors) < 0)
    assert errors[-1] < 0.06
    assert 0.5 < rate < 1.5, (errors, rate)


def test_disk_patches_agree_to_a_few_percent():
    """Holding every continuum DOF within the patch radius instead (the patches' shapes
    then differ by O(a) from the lattice's, irregularly): still within 7 % at a = 1/32,
    but not monotonically convergent (12 %, 5.8 %, 6.2 % at a = 1/16, 1/24, 1/32)."""
    errors = _patch_source_errors((17, 33), matched=False)
    assert errors[1] < min(0.07, errors[0])


@pytest.mark.slow
def test_patch_source_convergence_on_a_finer_lattice():
    sizes = (17, 33, 65)
    errors = _patch_source_errors(sizes, matched=True)
    a = 1.0 / (np.array(sizes) - 1)
    rate = np.polyfit(np.log(a), np.log(errors), 1)[0]
    assert errors[-1] < 0.03
    assert 0.8 < rate < 1.3, (errors, rate)
