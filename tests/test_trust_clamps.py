"""The trust region's model of the energy along exact clamps is exact to second order
away from equilibrium when its multipliers and its projection back onto the clamps use
one metric, and that projection meets the clamps where the metric alone does not
(network/trust.py, Problem.onto_clamps)."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.builders import triangular_lattice
from continuum_vs_network.network.constraints import Problem, clamp_tensions
from continuum_vs_network.network.energy import spring_energy_change
from continuum_vs_network.network.lagrangian import Frame, lagrangian_hessian


def _model_error(weights: str) -> tuple[float, float]:
    """``E(onto_clamps(x + t s)) - (E + t g.s + t^2 s.W(mu).s / 2)`` at t = 2e-4 and 1e-4
    for a tangent move ``s`` at a state far from equilibrium; the projection is
    minimum-norm in the metric ``1 / kappa``, ``mu`` the least-squares tensions weighted
    by ``weights``: ``kappa`` (the same metric) or the residual's local force scale."""
    rng = np.random.default_rng(7)
    net = triangular_lattice(5, 5, noise=0.1, rng=rng)
    net = net.with_stiffness(10.0 ** rng.uniform(-2, 2, net.n_springs))
    net = net.with_rest_length(net.rest_length * rng.uniform(0.5, 2.0, net.n_springs))
    problem = Problem.build(net, pinned=[0, 24], clamped={20: 2.5, 33: 0.6})
    coords = Frame(net, problem.free).coords
    k = net.stiffness
    kappa = np.bincount(net.springs.ravel(), np.repeat(k, 2), net.n_nodes)
    kappa = np.repeat(kappa, 2)[coords]
    metric = 1.0 / kappa
    x = problem.onto_clamps(net.positions + 0.05 * rng.normal(size=net.positions.shape))
    g = problem.gradient(x).ravel()[coords]
    A = problem.clamp_jacobian(x, coords, dense=True)
    scale = np.sqrt(kappa) if weights == "kappa" else problem.scale[coords]
    mu = clamp_tensions(A, g, scale)
    assert np.linalg.norm(g + A.T @ mu) > 0.1 * np.linalg.norm(g)  # far from equilibrium
    W = lagrangian_hessian(problem, x, mu, rho=0.0).toarray()
    r = rng.normal(size=coords.size)
    s = r - A.T @ np.linalg.solve(A @ A.T, A @ r)  # tangent: A s = 0
    errors = []
    for t in (2e-4, 1e-4):
        y = x.copy()
        y.ravel()[coords] += t * s
        y = problem.onto_clamps(y, coords, metric)
        change = spring_energy_change(y, x, net.springs, k, net.rest_length)
        errors.append(abs(change - (t * g @ s + 0.5 * t * t * s @ W @ s)))
    return errors[0], errors[1]


def test_the_model_is_third_order_accurate_with_multipliers_in_the_projection_metric():
    big, small = _model_error("kappa")
    assert big / small == pytest.approx(8.0, rel=0.15)  # error ~ t^3


def test_the_model_is_only_second_order_with_the_residual_weighting():
    big, small = _model_error("scale")
    assert big / small == pytest.approx(4.0, rel=0.15)  # error ~ t^2: the creep's cause


def test_a_projection_the_metric_makes_heavy_falls_back_to_the_identity():
    """A chain of clamps 82 + 2 + 30 long between two nodes 3 apart that the metric makes
    1000x heavier: 20 Gauss-Newton steps in that metric leave the clamps 2 off; the
    projection then goes on in the identity and meets them."""
    pos = np.array([[0.0, 0.0], [1.0, 0.1], [2.0, -0.1], [3.0, 0.0], [1.5, 1.0]])
    springs = np.array([[0, 1], [1, 2], [2, 3], [0, 4], [1, 4], [2, 4], [3, 4]])
    net = cvn.SpringNetwork(pos, springs, np.ones(7), np.ones(7))
    problem = Problem.build(net, pinned=np.zeros((5, 2), bool), clamped={0: 82, 1: 2, 2: 30})
    coords = problem.free_flat
    metric = np.ones(coords.size)
    metric[[0, 1, 6, 7]] = 1e-3  # nodes 0 and 3
    y = pos.copy()
    for _ in range(20):
        y = problem.toward_clamps(y, coords, metric=metric)
    assert np.abs(problem.clamp_violation(y)).max() > 1.0
    z = problem.onto_clamps(pos, coords, metric)
    assert np.abs(problem.clamp_violation(z)).max() <= 1e-14 * 82
