"""Stiff and extreme cases: each converges to the requested residual or raises a clear error."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.builders import paper_network, strain_tunable, triangular_lattice


def _converged(eq, net, tol=1e-10):
    assert eq.converged
    assert eq.residual <= tol * net.force_scale
    assert np.all(np.isfinite(eq.positions))
    return eq


def _stiff_lattice(ratio, seed):
    rng = np.random.default_rng(seed)
    net = triangular_lattice(8, 8, noise=0.1, rng=rng)
    k = np.where(rng.random(net.n_springs) < 0.2, ratio, 1.0)
    return net.with_stiffness(k), int(np.flatnonzero(k == 1.0)[len(k) // 4])


@pytest.mark.parametrize("ratio", [1e3, 1e6, 1e12])
def test_stiffness_ratio_up_to_1e12(ratio):
    net, soft = _stiff_lattice(ratio, 0)
    eq = _converged(cvn.relax(net, clamped={soft: net.clamp_length(soft, 0.2)}), net)
    assert eq.clamp_error <= 1e-10 * np.mean(net.rest_length)


def test_stiff_clusters_converge_or_raise_a_clear_error():
    """20 % of springs 1e9 times stiffer: rotating stiff clusters is strongly nonlinear and
    Newton may need more than its budget; it then says so, with a finite last state."""
    net, soft = _stiff_lattice(1e9, 0)
    try:
        _converged(cvn.relax(net, clamped={soft: net.clamp_length(soft, 0.2)}), net)
    except cvn.EquilibriumError as err:
        assert "no convergence" in str(err) and "residual=" in str(err)
        assert np.all(np.isfinite(err.state.positions)) and np.isfinite(err.state.residual)


@pytest.mark.parametrize("rod_stiffness", [1e6, 1e10, 1e12])
def test_paper_rods_of_extreme_stiffness(rod_stiffness):
    net = triangular_lattice(6, 6, noise=0.1, rng=np.random.default_rng(1))
    eq = cvn.relax(
        net, clamped={30: net.clamp_length(30, 0.5)}, clamp="rod", rod_stiffness=rod_stiffness
    )
    _converged(eq, net)
    # the rod yields by tension / stiffness and no more
    assert eq.clamp_error <= 2 * abs(eq.clamp_force[0]) / rod_stiffness + 1e-12


@pytest.mark.parametrize("strain", [-0.9, -0.5, 0.5, 2.0, 5.0, 10.0])
def test_source_strains_from_minus_0p9_to_10(strain):
    rng = np.random.default_rng(2)
    net = paper_network(rng)
    source = int(np.flatnonzero(strain_tunable(net))[0])
    length = net.clamp_length(source, strain)
    eq = _converged(cvn.relax(net, clamped={source: length}, ramp=4), net)
    assert net.strains(eq.positions)[source] == pytest.approx(strain, abs=1e-9)


def test_clamp_to_near_zero_length():
    net = triangular_lattice(6, 6, noise=0.05, rng=np.random.default_rng(3))
    eq = _converged(cvn.relax(net, clamped={40: net.clamp_length(40, -0.999)}, ramp=3), net)
    assert net.lengths(eq.positions)[40] == pytest.approx(1e-3 * net.rest_length[40], rel=1e-6)


@pytest.mark.parametrize("height", [1e-3, 1e-6, 1e-9])
def test_nearly_collinear_triangle(height):
    # apex almost on the base: the tangential stiffness of the base is nearly singular
    net = cvn.SpringNetwork(
        [[0.0, 0.0], [2.0, 0.0], [1.0, height]],
        [[0, 1], [1, 2], [2, 0]],
        [1.0, 1.0, 1.0],
        [2.0, 1.2, 1.2],
    )
    eq = _converged(cvn.relax(net, pinned=np.array([[1, 1], [0, 1], [0, 0]], bool)), net)
    # the sides reach their rest length by lifting the apex to sqrt(1.2^2 - 1)
    np.testing.assert_allclose(net.lengths(eq.positions), [2.0, 1.2, 1.2], atol=1e-10)
    assert abs(eq.positions[2, 1]) == pytest.approx(np.sqrt(1.2**2 - 1), rel=1e-9)


def test_floppy_lattice_reports_its_zero_modes():
    net = triangular_lattice(5, 5)
    keep = np.ones(net.n_springs, bool)
    keep[:12] = False  # 12 springs gone: at least 12 - (56 - 47 - ...) modes appear
    floppy = cvn.SpringNetwork(
        net.positions, net.springs[keep], net.stiffness[keep], net.rest_length[keep]
    )
    expected = 2 * floppy.n_nodes - 3 - floppy.n_springs
    assert expected > 0
    with pytest.raises(ValueError, match=f"floppy: at least {expected} zero modes"):
        cvn.relax(floppy)


def test_float32_inputs_give_float64_results_equal_to_float64_inputs():
    net64 = triangular_lattice(5, 5, noise=0.1, rng=np.random.default_rng(4))
    net32 = cvn.SpringNetwork(
        net64.positions.astype(np.float32),
        net64.springs.astype(np.int32),
        net64.stiffness.astype(np.float32),
        net64.rest_length.astype(np.float32),
    )
    ref = net64.with_positions(net32.positions).with_rest_length(net32.rest_length)
    a = cvn.relax(net32, clamped={10: 1.2})
    b = cvn.relax(ref, clamped={10: 1.2})
    assert a.positions.dtype == np.float64
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-12)


def test_large_strain_minima_are_stable_whatever_the_path():
    """At large strain the energy has several minima and the one found depends on the path
    (``ramp``); each one found is stable: perturbed and relaxed again, it comes back."""
    rng = np.random.default_rng(5)
    net = paper_network(rng)
    source = int(np.flatnonzero(strain_tunable(net))[1])
    clamped = {source: net.clamp_length(source, 5.0)}
    pins = cvn.default_pins(net, avoid=[source])
    for ramp in (1, 2, 8):
        eq = _converged(cvn.relax(net, pinned=pins, clamped=clamped, ramp=ramp), net)
        kick = 1e-3 * np.mean(net.rest_length) * rng.standard_normal(eq.positions.shape)
        again = cvn.relax(net, pinned=pins, clamped=clamped, x0=eq.positions + kick * ~pins)
        assert again.energy == pytest.approx(eq.energy, rel=1e-9)
        np.testing.assert_allclose(
            net.lengths(again.positions),
            net.lengths(eq.positions),
            atol=1e-7 * np.mean(net.rest_length),
        )
