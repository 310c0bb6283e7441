"""Network-to-continuum mappings: lattice moduli, pre-tension, dashpots, homogenisation."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.continuum.materials import (
    Material,
    lattice_area_per_node,
    lattice_lame,
    lattice_viscous_lame,
    network_moduli,
    node_drag_to_continuum,
    voigt_isotropic,
)
from continuum_vs_network.continuum.mesh import network_faces
from continuum_vs_network.network.builders import triangular_lattice


def _isotropic_voigt(m: Material) -> np.ndarray:
    return np.array([[m.lam + 2 * m.mu, m.lam, 0], [m.lam, m.lam + 2 * m.mu, 0], [0, 0, m.mu]])


def _continuum_density(m: Material, eps: np.ndarray) -> float:
    return 0.5 * m.lam * np.trace(eps) ** 2 + m.mu * np.sum(eps * eps)


def _affine_spring_density(net, k, eps) -> float:
    """Sum over springs of k (L n.eps.n)^2 / 2, outline springs (one face) counted half,
    divided by the area of the faces: written independently of network_moduli."""
    x = net.positions
    faces = network_faces(net)
    d = x[net.springs[:, 1]] - x[net.springs[:, 0]]
    stretch = np.einsum("si,ij,sj->s", d, eps, d) / np.linalg.norm(d, axis=1)
    pairs = {tuple(sorted(e)) for f in faces for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    count = {p: 0 for p in pairs}
    for f in faces:
        for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            count[tuple(sorted(e))] += 1
    w = np.array([count.get(tuple(sorted(s)), 2) / 2 for s in net.springs])
    e1, e2 = x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]]
    area = np.sum(0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]))
    return float(np.sum(0.5 * k * w * stretch**2) / area)


@pytest.mark.parametrize("spacing", [0.3, 1.0, 2.5])
def test_affine_lattice_energy_density_matches_the_continuum(spacing):
    """lambda = mu = sqrt(3) k / 4, independent of the spacing, to 1e-9."""
    k = 1.7
    net = triangular_lattice(7, 6, spacing=spacing, stiffness=k)
    mat = lattice_lame(k, spacing=spacing)
    assert mat.lam == mat.mu == pytest.approx(np.sqrt(3) * k / 4, rel=1e-15)
    rng = np.random.default_rng(0)
    for _ in range(5):
        eps = rng.normal(size=(2, 2)) * 1e-2
        eps = 0.5 * (eps + eps.T)
        w_net = _affine_spring_density(net, k, eps)
        assert w_net == pytest.approx(_continuum_density(mat, eps), rel=1e-9)
    for relaxed in (False, True):
        C = network_moduli(net, relaxed=relaxed).C
        np.testing.assert_allclose(C, _isotropic_voigt(mat), rtol=0, atol=1e-9 * k)


def test_pre_tension_splits_lambda_and_mu():
    a, k, T = 0.8, 2.0, 0.3
    net = triangular_lattice(8, 7, spacing=a, stiffness=k, rest_length=a - T / k)
    expect = lattice_lame(k, spacing=a, tension=T)
    assert expect.mu - expect.lam == pytest.approx(np.sqrt(3) / 2 * T / a)
    for relaxed in (False, True):
        got = network_moduli(net, relaxed=relaxed)
        np.testing.assert_allclose(got.C, _isotropic_voigt(expect), rtol=0, atol=1e-9 * k)


def test_relaxation_softens_a_disordered_network():
    """Non-affine relaxation can only lower the energy: C_affine - C_relaxed is positive
    semi-definite, and strictly positive for random spring constants."""
    rng = np.random.default_rng(4)
    net = triangular_lattice(14, 14, stiffness=1.0)
    net = net.with_stiffness(rng.uniform(0.2, 1.8, size=net.n_springs))
    affine = network_moduli(net, relaxed=False)
    relaxed = network_moduli(net, relaxed=True)
    gap = np.linalg.eigvalsh(affine.C - relaxed.C)
    assert gap.min() > 0
    assert relaxed.material.mu < 0.97 * affine.material.mu
    # the affine estimate is the mean spring constant's lattice value (up to the outline)
    assert affine.material.mu == pytest.approx(np.sqrt(3) / 4 * net.stiffness.mean(), rel=0.05)


def test_relaxed_moduli_need_an_equilibrium():
    net = triangular_lattice(6, 6)
    rng = np.random.default_rng(0)
    shaken = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
    with pytest.raises(ValueError, match="relax"):
        network_moduli(shaken, relaxed=True)


def test_dashpots_dissipate_like_the_viscous_continuum():
    """Dashpot force gamma dr/dt: the dissipation function sum gamma (dr/dt)^2 / 2 per area
    under a uniform strain rate equals lam_v tr(D)^2 / 2 + mu_v D:D."""
    gamma = 0.6
    net = triangular_lattice(6, 7, spacing=1.3)
    lam_v, mu_v = lattice_viscous_lame(gamma)
    D = np.array([[0.3, -0.2], [-0.2, 0.05]])
    assert _affine_spring_density(net, gamma, D) == pytest.approx(
        _continuum_density(Material(lam_v, mu_v), D), rel=1e-9
    )


def test_node_drag_maps_to_density_and_drag_per_area():
    a, m, c = 0.5, 2.0, 3.0
    rho, eta = node_drag_to_continuum(c, area_per_node=lattice_area_per_node(a), mass=m)
    # a lattice of n nodes holds n * sqrt(3)/2 a^2 of area in the bulk
    net = triangular_lattice(30, 30, spacing=a)
    x = net.positions
    bulk = (np.ptp(x[:, 0]) - a / 2) * np.ptp(x[:, 1])
    assert rho * bulk == pytest.approx(m * net.n_nodes, rel=0.1)
    assert eta / rho == pytest.approx(c / m)
    with pytest.raises(ValueError, match="drag"):
        node_drag_to_continuum(-1.0, area_per_node=1.0)


def test_voigt_isotropic_recovers_isotropic_tensors_and_rejects_bad_shapes():
    m = Material(0.4, 1.3)
    got = voigt_isotropic(_isotropic_voigt(m))
    assert got.lam == pytest.approx(m.lam) and got.mu == pytest.approx(m.mu)
    with pytest.raises(ValueError, match="shape"):
        voigt_isotropic(np.eye(2))
