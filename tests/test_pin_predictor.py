"""Newton's start when pinned nodes are displaced: the linear elastic response of the
geometry to the pins' displacement (``newton._pin_predictor``)."""

from __future__ import annotations

import numpy as np
from pulled_lattices import pulled_apart

import continuum_vs_network as cvn
from continuum_vs_network.network import newton as nw
from continuum_vs_network.network.constraints import Problem
from continuum_vs_network.network.energy import spring_energy
from continuum_vs_network.network.lagrangian import pattern_for


def _predict(net, pins, x0):
    problem = Problem.build(net, pinned=pins)
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    return nw._pin_predictor(problem, pattern, x0)


def _energy(net, x):
    return spring_energy(x, net.springs, net.stiffness, net.rest_length)


def test_the_pin_predictor_is_the_first_order_response():
    """The predicted start differs from the equilibrium by O(strain^2): halving the
    strain divides the error by 4 (3.5-4.5 allowed); at strain 1e-3 it is below 1e-5 of a
    spring length and 1e-2 of the start's offset from the equilibrium."""
    errors = []
    for strain in (2e-3, 1e-3):
        net, pins, x0 = pulled_apart(16, strain)
        y, factor = _predict(net, pins, x0)
        assert factor is not None and y is not x0
        np.testing.assert_array_equal(y[pins], x0[pins])  # the pins stay where they are
        eq = cvn.relax(net, pinned=pins, x0=x0, tol=1e-12)
        errors.append(float(np.max(np.abs(y - eq.positions))))
        given = float(np.max(np.abs(x0 - eq.positions)))
    length = float(np.mean(net.rest_length))
    assert 3.5 < errors[0] / errors[1] < 4.5
    assert errors[1] < min(1e-5 * length, 1e-2 * given)


def test_a_prediction_that_raises_the_energy_is_refused():
    """At strain 4 (16 x 16) the linear response raises the energy above the start's: the
    start is kept, with the factorisation made for it (Newton preconditions with it)."""
    net, pins, x0 = pulled_apart(16, 4.0)
    y, factor = _predict(net, pins, x0)
    assert y is x0 and factor is not None


def test_other_starts_are_left_alone_without_a_factorisation():
    """A start whose free nodes are off the geometry (a warm start), or whose pins are
    where the network has them, is not predicted: nothing is factorised."""
    net, pins, x0 = pulled_apart(16, 1.0)
    warm = x0 + 1e-3 * np.random.default_rng(1).standard_normal(x0.shape) * ~pins
    for start in (warm, net.positions.copy()):
        y, factor = _predict(net, pins, start)
        assert y is start and factor is None


def test_displaced_pins_reach_the_same_equilibrium_in_fewer_iterations(monkeypatch):
    """A 24 x 24 lattice pulled apart at strain 2: Newton with the predictor and without
    it (the start as given) reach the same positions; with it in at most 6 iterations
    (the predictor counted), without it in 9."""
    net, pins, x0 = pulled_apart(24, 2.0)
    predicted = cvn.relax(net, pinned=pins, x0=x0, tol=1e-11)
    monkeypatch.setattr(nw, "_pin_predictor", lambda problem, pattern, x: (x, None))
    plain = cvn.relax(net, pinned=pins, x0=x0, tol=1e-11)
    np.testing.assert_allclose(predicted.positions, plain.positions, atol=1e-8)
    assert predicted.iterations <= 6 < plain.iterations
    assert _energy(net, predicted.positions) < _energy(net, x0)
