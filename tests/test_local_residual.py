"""The local stop rule: each free coordinate's net force against its own node's sum k L."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.constraints import Problem, clamp_tensions
from continuum_vs_network.network.stopping import coordinate_scale


def _chain():
    """0 -- 1 -- 2 on the x axis: a stiff spring (k = 1e6, L = 1) then a soft one (k = 1e-2,
    L = 2); both slightly stretched, node 0 pinned, y pinned everywhere."""
    net = cvn.SpringNetwork(
        [[0.0, 0.0], [1.1, 0.0], [3.3, 0.0]], [[0, 1], [1, 2]], [1e6, 1e-2], [1.0, 2.0]
    )
    pins = np.array([[True, True], [False, True], [False, True]])
    return net, pins


def test_scale_is_the_sum_of_k_times_L_at_each_node():
    net, _ = _chain()
    scale = coordinate_scale(net.springs, net.stiffness, net.rest_length, net.n_nodes)
    np.testing.assert_allclose(scale, np.repeat([1e6, 1e6 + 2e-2, 2e-2], 2))


def test_imbalance_is_the_largest_force_over_its_local_scale():
    net, pins = _chain()
    problem = Problem.build(net, pinned=pins)
    res = problem.residual(net.positions)
    # net x forces: node 1: -1e6 * 0.1 + 1e-2 * 0.2; node 2: -1e-2 * 0.2
    f1, f2 = -1e6 * 0.1 + 1e-2 * 0.2, -1e-2 * 0.2
    assert res.force == pytest.approx(abs(f1))
    assert res.imbalance == pytest.approx(max(abs(f1) / (1e6 + 2e-2), abs(f2) / 2e-2))
    # the soft node is the worse one relative to its own springs (0.1 against 0.1 - eps)
    assert abs(f2) / 2e-2 == pytest.approx(0.1)


def test_relax_balances_the_soft_end_to_tol_of_its_own_scale():
    net, pins = _chain()
    eq = cvn.relax(net, pinned=pins, tol=1e-12)
    force = cvn.forces(eq.positions, net)
    assert abs(force[2, 0]) <= 1e-12 * 2e-2  # the global scale mean(k) mean(L) ~ 7.5e5
    assert eq.relative_residual <= 1e-12
    np.testing.assert_allclose(net.lengths(eq.positions), [1.0, 2.0], rtol=1e-12)


def test_clamp_tensions_are_weighted_by_the_local_scale():
    """A clamp between a stiff node and a soft one: round-off-sized force noise at the stiff
    end must not leak into the soft end's balance."""
    A = np.array([[-1.0, 1.0]])  # clamp along x between coordinates 0 and 1
    # the soft end carries the clamp tension 5; at the stiff end (forces ~1e12 there) the
    # matching -5 is off by round-off and reads 1e-3
    g = np.array([1e-3, 5.0])
    scale = np.array([1e12, 1.0])
    mu = clamp_tensions(A, g, scale)
    residual = g + A.T @ mu
    assert abs(residual[1]) / scale[1] < 1e-9  # the soft end is balanced
    unweighted = -np.linalg.lstsq((A @ A.T), A @ g, rcond=None)[0]
    assert abs((g + A.T @ unweighted)[1]) > 1.0  # the plain least squares leaks ~2.5
