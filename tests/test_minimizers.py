"""FIRE, L-BFGS and the paper's Adagrad against Newton and closed forms."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network import fire as fire_module
from continuum_vs_network.network.constraints import Problem
from continuum_vs_network.network.equilibrium import METHODS
from continuum_vs_network.network.objective import Objective
from continuum_vs_network.network.stopping import Trace


def _lattice(n: int, rng: np.random.Generator, *, noise: float = 0.1, random_rest: bool = False):
    """An n x n triangular lattice (spacing 1) with position noise; stress-free by default."""
    net = cvn.triangular_lattice(n, n, noise=noise, rng=rng)
    net = net.with_stiffness(rng.uniform(0.5, 2.0, net.n_springs))
    if random_rest:
        net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
    return net


def _central_spring(net: cvn.SpringNetwork) -> int:
    mid = net.positions[net.springs].mean(axis=1)
    return int(np.argmin(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1)))


@pytest.mark.parametrize("method", ["fire", "lbfgs"])
@pytest.mark.parametrize("clamped", [False, True])
def test_agrees_with_newton(method, clamped):
    rng = np.random.default_rng(3)
    net = _lattice(6, rng, random_rest=not clamped)
    c = _central_spring(net)
    clamp = {c: float(net.clamp_length(c, 0.3))} if clamped else None
    ref = cvn.relax(net, clamped=clamp, tol=1e-12)
    eq = cvn.relax(net, clamped=clamp, method=method, tol=1e-11)
    assert eq.converged and eq.relative_residual <= 1e-11
    assert np.max(np.abs(eq.positions - ref.positions)) < 1e-8
    assert eq.energy == pytest.approx(ref.energy, rel=1e-9)
    assert eq.residual_trace.size >= 2 and eq.residual_trace.size == eq.seconds_trace.size


@pytest.mark.parametrize("method", ["fire", "lbfgs"])
@pytest.mark.parametrize("strain", [-0.4, 2.0])
def test_exact_clamp_length_is_met(method, strain):
    rng = np.random.default_rng(5)
    net = _lattice(5, rng)
    c = _central_spring(net)
    length = float(net.clamp_length(c, strain))
    ramp = 2 if strain > 1 else 1
    eq = cvn.relax(net, clamped={c: length}, method=method, ramp=ramp, tol=1e-11)
    assert abs(net.lengths(eq.positions)[c] - length) <= 1e-10 * length
    # the clamp force is the tension of the clamp: Newton's, to the tolerance
    ref = cvn.relax(net, clamped={c: length}, ramp=ramp, tol=1e-11)
    assert eq.clamp_force == pytest.approx(ref.clamp_force, abs=1e-8 * net.force_scale)


@pytest.mark.parametrize("method", ["fire", "lbfgs"])
def test_rod_mode_minimises_the_rod_energy(method):
    # A soft rod (k = 50) cannot hold the clamp length to 1e-10, so ``relax`` would refuse
    # it; call the methods directly with a stop rule on the residual alone.
    rng = np.random.default_rng(7)
    net = _lattice(5, rng)
    c = _central_spring(net)
    length = float(net.clamp_length(c, 0.2))
    problem = Problem.build(net, clamped={c: length}, clamp="rod", rod_stiffness=50.0)
    stop = problem.stop_rule(1e-11, max_iter=100_000, max_seconds=60.0)
    x0 = problem.start(net.positions)
    ref = METHODS["newton"](problem, x0, stop, Trace())
    out = METHODS[method](problem, x0, stop, Trace())
    assert ref.converged and out.converged
    assert np.max(np.abs(out.x - ref.x)) < 1e-8
    assert problem.residual(out.x).imbalance <= stop.tol
    # the rod stretches under load: not the clamp length, but close (load / stiffness)
    assert 1e-6 < abs(net.lengths(out.x)[c] - length) < 1e-2


def _one_spring_problem(x1: float) -> tuple[Problem, np.ndarray]:
    """Node 0 pinned at the origin, node 1 free along x only; k = 1, L = 1."""
    net = cvn.SpringNetwork([[0.0, 0.0], [x1, 0.0]], [[0, 1]], [1.0], [1.0])
    pins = np.array([[True, True], [False, True]])
    problem = Problem.build(net, pinned=pins)
    return problem, net.positions.copy()


def test_fire_power_is_force_dot_velocity():
    # From rest at x = 1.3 in the well of minimum x = 1: with P = F.V the node runs
    # downhill (P > 0) and the first reset comes only once it has overshot the minimum.
    problem, x = _one_spring_problem(1.3)
    obj = Objective(problem)
    stats = fire_module._FireStats()
    stop = problem.stop_rule(1e-12, max_iter=10_000, max_seconds=10.0)
    res = fire_module._fire_inner(obj, x, 0.0, stop, Trace(), stop.max_iter, stats)
    assert res.status == "stop"
    assert abs(res.x[1, 0] - 1.0) < 1e-11
    assert stats.resets >= 1
    assert stats.first_reset_x[1, 0] < 1.0  # past the minimum, on the far side


def test_objective_gradient_and_stop_test_match_the_problem():
    # The first-order methods' gradient (a sparse incidence matvec) and their stop test
    # (cheap part every iteration, clamp projection on demand) against the network's own
    # gradient and Problem.residual, at a strained state far from equilibrium.
    rng = np.random.default_rng(17)
    net = _lattice(7, rng, random_rest=True)
    c = _central_spring(net)
    for clamp in ("exact", "rod"):
        problem = Problem.build(net, clamped={c: float(net.clamp_length(c, 0.4))}, clamp=clamp)
        obj = Objective(problem)
        x = problem.start(net.positions + rng.normal(0.0, 0.05, net.positions.shape))
        G = obj.grad(x)  # augmented terms vanish while lam = rho = 0
        assert np.allclose(G, problem.gradient(x).ravel(), rtol=1e-12, atol=1e-12)
        imbalance, clamp_error = obj.check(x, G)
        res = problem.residual(x)
        assert imbalance == pytest.approx(res.imbalance, rel=1e-9)
        assert clamp_error == pytest.approx(res.clamp, rel=1e-9)
        assert 0.0 < obj.rest_imbalance(G) <= imbalance


def test_fire_two_spring_chain_closed_form():
    # 0 -- 1 -- 2 along x, k = (1, 3), L = (1, 2): node 0 pinned, y pinned, node 2 pinned
    # at x = 4: the middle node sits where the tensions balance: 1 (x - 1) = 3 (4 - x - 2).
    net = cvn.SpringNetwork([[0, 0], [1.7, 0], [4, 0]], [[0, 1], [1, 2]], [1.0, 3.0], [1.0, 2.0])
    pins = np.array([[True, True], [False, True], [True, True]])
    eq = cvn.relax(net, pinned=pins, method="fire", tol=1e-12)
    assert eq.positions[1, 0] == pytest.approx(7.0 / 4.0, abs=1e-11)


def test_budgets_raise_with_the_last_state():
    rng = np.random.default_rng(11)
    net = _lattice(6, rng, random_rest=True)
    with pytest.raises(cvn.EquilibriumError, match="no convergence in 5 iterations") as err:
        cvn.relax(net, method="fire", max_iter=5)
    state = err.value.state
    assert not state.converged and np.isfinite(state.residual)
    with pytest.raises(cvn.EquilibriumError, match="lbfgs"):
        cvn.relax(net, method="lbfgs", max_iter=3)


def test_paper_adagrad_lowers_energy_but_stalls():
    pytest.importorskip("torch")
    rng = np.random.default_rng(13)
    net = _lattice(4, rng, random_rest=True)
    c = _central_spring(net)
    clamp = {c: float(net.clamp_length(c, 0.5))}
    problem = Problem.build(net, clamped=clamp, clamp="rod")
    start = problem.start(net.positions)
    with pytest.raises(cvn.EquilibriumError, match="paper") as err:
        cvn.relax(net, clamped=clamp, method="paper", max_iter=200)
    state = err.value.state
    assert np.isfinite(state.residual) and state.residual > 1e-10 * net.force_scale
    assert problem.energy(state.positions) < problem.energy(start)
    assert state.residual_trace.size >= 2


def test_torch_is_not_imported_with_the_module():
    code = (
        "import sys, continuum_vs_network.network.minimizers, continuum_vs_network; "
        "print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
