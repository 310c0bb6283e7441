"""Damped network dynamics against closed forms, relax, and physical scaling."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.dynamics import (
    relaxation_time,
    simulate,
    simulate_viscous,
    stability_limit,
)
from continuum_vs_network.network.viscous import Viscosity


def _lattice(n: int, rng: np.random.Generator | None = None, *, random_rest: bool = False):
    """An n x n triangular lattice (spacing 1, k = 1); noisy and prestressed on request."""
    net = cvn.triangular_lattice(n, n, noise=0.0 if rng is None else 0.1, rng=rng)
    if random_rest:
        net = net.with_rest_length(net.rest_length * rng.uniform(0.85, 1.15, net.n_springs))
    return net


# node 0 pinned at the origin, node 1 moves along x only: x'' = -c x' - k (x - L)
_ONE_D = np.array([[True, True], [False, True]])


def _spring(k: float, x1: float = 1.3) -> cvn.SpringNetwork:
    return cvn.SpringNetwork([[0.0, 0.0], [x1, 0.0]], [[0, 1]], [k], [1.0])


def test_overdamped_decay_is_exponential_and_backward_euler_first_order():
    k, c, delta = 2.0, 0.5, 0.3
    errors = []
    for dt in (0.02, 0.01, 0.005):
        tr = simulate(
            _spring(k, 1 + delta), pinned=_ONE_D, dt=dt, t_end=1.0, inertia=False, damping=c
        )
        exact = 1.0 + delta * np.exp(-k / c * tr.times)
        errors.append(np.max(np.abs(tr.positions[:, 1, 0] - exact)))
    assert errors[-1] < 2e-3
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 1.8) & (ratios < 2.2)), ratios


def _angular_frequency(tr) -> float:
    u = tr.positions[:, 1, 0] - 1.0
    i = np.flatnonzero(np.sign(u[:-1]) != np.sign(u[1:]))
    crossings = tr.times[i] - u[i] * (tr.times[i + 1] - tr.times[i]) / (u[i + 1] - u[i])
    return np.pi / np.mean(np.diff(crossings))


def test_underdamped_frequency_newmark_second_order():
    k, c = 1.0, 0.2
    omega = np.sqrt(k - c * c / 4)
    errors = []
    for dt in (0.1, 0.05, 0.025):
        tr = simulate(_spring(k), pinned=_ONE_D, dt=dt, t_end=40.0, damping=c, scheme="newmark")
        errors.append(abs(_angular_frequency(tr) - omega))
    assert errors[-1] < 1e-4 * omega
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios
    # the amplitude decays at rate c / 2
    u = np.abs(tr.positions[:, 1, 0] - 1.0)
    late = tr.times > 30
    assert np.max(u[late]) <= 0.3 * np.exp(-c / 2 * 30.0) * 1.01


def test_overdamped_implicit_energy_never_increases():
    rng = np.random.default_rng(2)
    net = _lattice(7, rng, random_rest=True)
    tr = simulate(net, dt=0.5, t_end=20.0, inertia=False)
    assert np.all(np.diff(tr.energy) <= 1e-12 * tr.energy[0])
    assert tr.energy[-1] < 0.5 * tr.energy[0]
    # damped inertial dynamics: the mechanical energy E + K never increases either
    tr = simulate(net, dt=0.5, t_end=20.0, damping=0.5)
    total = tr.energy + tr.kinetic
    assert np.all(np.diff(total) <= 1e-12 * total[0])


@pytest.mark.parametrize("inertia", [False, True])
def test_final_state_matches_relax(inertia):
    rng = np.random.default_rng(4)
    net = _lattice(6, rng, random_rest=True)
    pins = cvn.default_pins(net)
    # a prestressed lattice has soft modes (relaxing over ~1e3 time units): implicit steps
    # of dt = 1e3 reach the equilibrium in a few dozen steps
    tr = simulate(net, pinned=pins, dt=1e3, t_end=4e4, inertia=inertia, tol=1e-12, record_every=10)
    eq = cvn.relax(net, pinned=pins, tol=1e-12)
    assert np.max(np.abs(tr.positions[-1] - eq.positions)) < 1e-8
    assert tr.residual[-1] < 1e-9
    assert np.all(np.diff(tr.seconds) >= 0)


def test_clamp_as_prescribed_end_displacement_matches_relax_with_pinned_ends():
    rng = np.random.default_rng(6)
    net = _lattice(6, rng)
    spring = 30
    length = float(net.clamp_length(spring, 0.5))
    # no pins: held only at the clamped spring, the network swings slowly (over ~1e3 time
    # units) into its relaxed orientation against the drag; long implicit steps get there
    tr = simulate(
        net, clamped={spring: length}, dt=1e3, t_end=4e4, inertia=False, record_every=10, tol=1e-12
    )
    a, b = net.springs[spring]
    assert np.hypot(*(tr.positions[-1, b] - tr.positions[-1, a])) == pytest.approx(length)
    assert not tr.free[a].any() and not tr.free[b].any()
    eq = cvn.relax(net, pinned=~tr.free, x0=tr.positions[0], tol=1e-12)
    assert np.max(np.abs(tr.positions[-1] - eq.positions)) < 1e-8


def test_explicit_refuses_unstable_dt():
    net = _lattice(4)
    limit = stability_limit(net, damping=0.0)
    assert limit == pytest.approx(2.0 / np.sqrt(2 * 6.0))  # interior node: 6 springs of k = 1
    with pytest.raises(ValueError, match=r"dt = 0\.6 .*stability limit 0\.57"):
        simulate(net, dt=0.6, t_end=1.0, damping=0.0, scheme="explicit")
    # just below the limit it runs and agrees with the implicit schemes
    x0 = net.positions + 0.02 * np.random.default_rng(0).normal(size=net.positions.shape)
    ex = simulate(net, x0=x0, dt=0.01, t_end=5.0, damping=1.0, scheme="explicit", record_every=100)
    nm = simulate(net, x0=x0, dt=0.01, t_end=5.0, damping=1.0, scheme="newmark", record_every=100)
    assert np.max(np.abs(ex.positions - nm.positions)) < 5e-4  # first order in dt
    # overdamped forward Euler: dt < 2 c / lambda
    with pytest.raises(ValueError, match="stability limit"):
        simulate(net, dt=0.2, t_end=1.0, inertia=False, scheme="explicit")


@pytest.mark.parametrize("inertia", [False, True])
def test_stiff_rod_is_stable_with_implicit_dt_one(inertia):
    net = _lattice(5)
    rod = 30
    k = net.stiffness.copy()
    k[rod] = 1e10
    L = net.rest_length.copy()
    L[rod] *= 1.2  # the rod pushes its nodes apart
    net = cvn.SpringNetwork(net.positions, net.springs, k, L)
    tr = simulate(net, dt=1.0, t_end=30.0, inertia=inertia)
    assert np.all(np.isfinite(tr.positions))
    total = tr.energy + tr.kinetic
    assert np.all(np.diff(total) <= 1e-9 * total[0])
    assert tr.energy[-1] < 1e-3 * tr.energy[0]
    a, b = net.springs[rod]
    assert np.hypot(*(tr.positions[-1, b] - tr.positions[-1, a])) == pytest.approx(L[rod], rel=1e-8)
    with pytest.raises(ValueError, match="stability limit"):
        simulate(net, dt=1.0, t_end=1.0, inertia=inertia, scheme="explicit")


def test_relaxation_time_grows_diffusively_with_size():
    # n x n lattice, left column pinned, right column stepped inwards by 1% of the width;
    # overdamped, the slowest mode relaxes at ~ k (pi / n)^2 / c: time ~ n^2
    sizes = np.array([6, 8, 12, 16])
    times = []
    for n in sizes:
        net = _lattice(int(n))
        x = net.positions
        left = np.flatnonzero(x[:, 0] < 0.6)
        right = np.flatnonzero(x[:, 0] > x[:, 0].max() - 0.6)
        step = {int(i): x[i] - [0.01 * n, 0.0] for i in right}
        tau = 0.05 * n * n
        tr = simulate(
            net,
            pinned=left,
            prescribed=step,
            dt=tau / 10,
            t_end=15 * tau,
            inertia=False,
            jacobian="frozen",
        )
        assert tr.factorisations <= 2  # a nearly linear run reuses its factorisation
        # the displacement to the final state: the force maximum sits at the stepped edge
        # and relaxes fast, locally; the configuration relaxes with the slowest mode
        times.append(relaxation_time(tr, 1e-2, measure="displacement"))
    exponent = np.polyfit(np.log(sizes), np.log(times), 1)[0]
    print(f"relaxation time ~ n^{exponent:.2f} for n = {sizes.tolist()}: {np.round(times, 2)}")
    assert 1.5 < exponent < 2.5
    assert np.all(np.diff(times) > 0)


def test_relaxation_time_of_a_single_spring():
    k, c = 2.0, 1.0
    tr = simulate(
        _spring(k), pinned=_ONE_D, dt=1e-3, t_end=4.0, inertia=False, damping=c, jacobian="frozen"
    )
    # residual k |x - L| decays as exp(-k t / c): 1% after ln(100) c / k
    assert relaxation_time(tr, 1e-2) == pytest.approx(np.log(100) * c / k, rel=2e-3)
    with pytest.raises(ValueError, match="run longer"):
        relaxation_time(tr, 1e-9)


@pytest.mark.parametrize("inertia", [False, True])
def test_node_drag_is_the_viscous_step_without_dashpots_or_arms(inertia):
    """simulate and simulate_viscous take the same backward-Euler step (one Stepper)."""
    net = _lattice(5, np.random.default_rng(3), random_rest=True)
    kw = {"pinned": np.arange(5), "dt": 0.5, "t_end": 5.0, "inertia": inertia}
    plain = simulate(net, damping=0.7, jacobian="frozen", max_newton=100, **kw)
    viscous = simulate_viscous(net, Viscosity(drag=0.7), **kw)
    np.testing.assert_array_equal(plain.positions, viscous.positions)
    assert plain.factorisations == viscous.factorisations


def test_bad_input_is_named():
    net = _lattice(3)
    with pytest.raises(ValueError, match="dt"):
        simulate(net, dt=0.0, t_end=1.0)
    with pytest.raises(ValueError, match="scheme"):
        simulate(net, dt=0.1, t_end=1.0, scheme="rk4")
    with pytest.raises(ValueError, match="damping"):
        simulate(net, dt=0.1, t_end=1.0, inertia=False, damping=0.0)
    with pytest.raises(ValueError, match="prescribed"):
        simulate(net, dt=0.1, t_end=1.0, prescribed={99: (0.0, 0.0)})
    with pytest.raises(ValueError, match="clamped spring 0 shares node"):
        simulate(net, dt=0.1, t_end=1.0, prescribed={0: (0.0, 0.0)}, clamped={0: 1.2})
