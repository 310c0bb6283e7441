"""Newton's start: the linear elastic response to the clamps (``newton._clamp_predictor``)."""

from __future__ import annotations

import numpy as np

import continuum_vs_network as cvn
from continuum_vs_network.network import newton as nw
from continuum_vs_network.network.builders import triangular_lattice
from continuum_vs_network.network.constraints import Problem
from continuum_vs_network.network.lagrangian import pattern_for
from continuum_vs_network.network.stopping import Trace


def _lattice_and_clamp(strain: float, seed: int = 3):
    """A 16 x 16 noisy lattice (512 free coordinates: the sparse Newton), one clamp near
    the centre at ``strain``."""
    rng = np.random.default_rng(seed)
    net = triangular_lattice(16, 16, noise=0.1, rng=rng)
    mid = net.positions[net.springs].mean(axis=1)
    centre = int(np.argmin(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1)))
    return net, {centre: float(net.clamp_length(centre, strain))}


def _predict(net, clamped):
    problem = Problem.build(net, clamped=clamped)
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    stop = problem.stop_rule(1e-10, max_iter=100, max_seconds=60.0)
    rho = float(np.max(net.stiffness))
    y, factor = nw._clamp_predictor(problem, pattern, net.positions, rho, stop, True)
    return problem, stop, (problem.start(y), factor)  # the start newton() takes


def test_the_predictor_is_the_first_order_response():
    """From a stress-free network the predicted start differs from the equilibrium by
    O(strain^2): halving the strain divides the error by 4 (3.5-4.5 allowed), and at
    strain 1e-3 it is below 1e-5 of a spring length."""
    errors = []
    for strain in (2e-3, 1e-3):
        net, clamped = _lattice_and_clamp(strain)
        _, _, (start, factor) = _predict(net, clamped)
        assert factor is not None
        eq = cvn.relax(net, clamped=clamped)
        errors.append(float(np.max(np.abs(start - eq.positions))))
    assert 3.5 < errors[0] / errors[1] < 4.5
    assert errors[1] < 1e-5 * float(np.mean(net.rest_length))


def test_a_predictor_that_turns_a_spring_over_is_refused():
    """At strain 5 the linear response crosses springs over: the start is the clamped
    springs set to their lengths alone (Problem.start). The factorisation made for the
    step is kept (Newton preconditions with it), and Newton reaches the same equilibrium
    as from Problem.start."""
    net, clamped = _lattice_and_clamp(5.0)
    problem, stop, (start, factor) = _predict(net, clamped)
    assert factor is not None and factor.n == problem.free_flat.size
    np.testing.assert_array_equal(start, problem.start(net.positions))
    predicted = nw.newton(problem, net.positions, stop, Trace())
    plain = nw.newton(problem, start, stop, Trace())
    assert predicted.converged and plain.converged
    np.testing.assert_allclose(predicted.x, plain.x, atol=1e-8)


def test_the_predicted_start_reaches_the_same_equilibrium():
    """Strain 1: Newton from the predictor and Newton from Problem.start alone (a start
    whose clamps are met skips the predictor) converge to the same positions, the
    predicted one in fewer iterations."""
    net, clamped = _lattice_and_clamp(1.0)
    problem = Problem.build(net, clamped=clamped)
    stop = problem.stop_rule(1e-11, max_iter=200, max_seconds=60.0)
    predicted = nw.newton(problem, net.positions, stop, Trace())
    plain = nw.newton(problem, problem.start(net.positions), stop, Trace())
    assert predicted.converged and plain.converged
    np.testing.assert_allclose(predicted.x, plain.x, atol=1e-8)
    assert predicted.iterations < plain.iterations
