"""Visco-elastic stepping: orders in time, stability, kinds of dissipation, relaxation time."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh

pytest.importorskip("skfem")

import continuum_vs_network as cvn
from continuum_vs_network.continuum.body import (
    elastic_body,
    mass_matrix,
    near_segments,
    pressure_load,
    stiffness_matrix,
)
from continuum_vs_network.continuum.materials import (
    Material,
    lattice_area_per_node,
    lattice_lame,
    node_drag_to_continuum,
)
from continuum_vs_network.continuum.mesh import network_mesh, rectangle_mesh
from continuum_vs_network.continuum.probes import displacement_probe
from continuum_vs_network.continuum.static import fix, solve_static
from continuum_vs_network.continuum.viscoelastic import (
    Damping,
    explicit_limit,
    relaxation_time,
    simulate_body,
    slowest_relaxation_time,
)
from continuum_vs_network.network.builders import triangular_lattice

UNIT = Material(1.0, 1.0)


@pytest.fixture(scope="module")
def cantilever():
    """A 2 x 1 block clamped on the left, P2, and its lowest mode (unit density)."""
    body = elastic_body(rectangle_mesh(2.0, 1.0, h=0.25), UNIT, order=2)
    fixed = fix(body, lambda x, y: x < 1e-9)
    K, M = stiffness_matrix(body), mass_matrix(body, 1.0)
    free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    w2, phi = eigsh(K[free][:, free].tocsc(), k=1, M=M[free][:, free].tocsc(), sigma=0)
    mode = np.zeros(body.n_dofs)
    mode[free] = phi[:, 0]
    return body, fixed, float(w2[0]), mode


def _rates(errors):
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def test_newmark_is_second_order_and_conserves_energy(cantilever):
    body, fixed, w2, mode = cantilever
    w = np.sqrt(w2)
    period = 2 * np.pi / w
    errors = []
    for n in (20, 40, 80):
        tr = simulate_body(
            body,
            fixed=fixed,
            dt=period / n,
            t_end=0.3 * period,
            scheme="newmark",
            density=1.0,
            u0=mode,
        )
        errors.append(np.linalg.norm(tr.u - mode * np.cos(w * tr.times[-1])))
        total = tr.energy + tr.kinetic
        assert np.max(np.abs(total / total[0] - 1)) < 1e-10
    assert np.all(np.abs(_rates(errors) - 2.0) < 0.1)


@pytest.mark.parametrize(("scheme", "order"), [("backward_euler", 1.0), ("newmark", 2.0)])
def test_overdamped_schemes_reach_their_order(cantilever, scheme, order):
    """Substrate drag eta: the mode decays as exp(-lambda t / eta) exactly."""
    body, fixed, w2, mode = cantilever
    eta = 2.0
    tau = eta / w2
    errors = []
    for n in (10, 20, 40):
        tr = simulate_body(
            body,
            fixed=fixed,
            dt=tau / n,
            t_end=tau,
            scheme=scheme,
            damping=Damping(drag=eta),
            u0=mode,
        )
        errors.append(np.linalg.norm(tr.u - mode * np.exp(-1.0)))
    assert np.all(np.abs(_rates(errors) - order) < 0.1)
    K = stiffness_matrix(body)
    free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    C = eta * mass_matrix(body)
    assert slowest_relaxation_time(K[free][:, free], C[free][:, free]) == pytest.approx(tau)


def test_time_steps_far_above_the_explicit_limit(cantilever):
    body, fixed, _, mode = cantilever
    dt_explicit = explicit_limit(body, density=1.0)
    dt = 1e4 * dt_explicit
    load = pressure_load(body, -1e-3, where=lambda x, y: x > 2 - 1e-9)
    static = solve_static(body, fixed, load=load).u
    # backward Euler with mass and drag: unconditionally stable, settles on the static answer
    be = simulate_body(
        body, fixed=fixed, dt=dt, t_end=400 * dt, density=1.0, damping=Damping(drag=1.0), load=load
    )
    assert np.linalg.norm(be.u - static) < 1e-6 * np.linalg.norm(static)
    # undamped Newmark: bounded, energy (with the load's work) conserved
    nm = simulate_body(
        body, fixed=fixed, dt=dt, t_end=50 * dt, scheme="newmark", density=1.0, u0=mode
    )
    total = nm.energy + nm.kinetic
    assert np.max(np.abs(total / total[0] - 1)) < 1e-9
    with pytest.raises(ValueError, match="nothing to integrate"):
        simulate_body(body, fixed=fixed, dt=dt, t_end=dt)


@pytest.fixture(scope="module")
def strip():
    """An 8 x 1 strip clamped at x = 0, pulled at x = 8 by a step traction."""
    body = elastic_body(rectangle_mesh(8.0, 1.0, h=0.25), UNIT, order=2)
    fixed = fix(body, lambda x, y: x < 1e-9)
    load = pressure_load(body, -1e-3, where=lambda x, y: x > 8 - 1e-9)
    probe = displacement_probe(body, [[6.0, 0.5], [4.0, 0.5], [2.0, 0.5]])  # 2, 4, 6 away
    final = probe(solve_static(body, fixed, load=load).u)[:, 0]
    return body, fixed, load, probe, final


def _arrival(tr, threshold):
    ux = tr.observed[:, :, 0]
    return np.array([tr.times[np.argmax(ux[:, i] > threshold)] for i in range(ux.shape[1])])


def test_kelvin_voigt_without_mass_has_no_delay(strip):
    body, fixed, load, probe, final = strip
    tr = simulate_body(
        body,
        fixed=fixed,
        dt=0.05,
        t_end=3.0,
        load=load,
        observe=probe,
        damping=Damping(viscous_lam=1.0, viscous_mu=1.0),
    )
    normalised = tr.observed[:, :, 0] / final
    assert np.max(np.abs(normalised - normalised[:, :1])) < 1e-10
    assert 0.9 < normalised[-1, 0] < 1.0


def test_substrate_drag_diffuses_and_inertia_propagates(strip):
    body, fixed, load, probe, final = strip
    threshold = 3e-3 * final[0]
    drag = simulate_body(
        body, fixed=fixed, dt=0.01, t_end=2.0, load=load, observe=probe, damping=Damping(drag=1.0)
    )
    t_drag = _arrival(drag, threshold)
    assert t_drag[2] / t_drag[0] > 4.5  # 6 vs 2 away: far beyond linear (3), towards 9
    waves = simulate_body(
        body,
        fixed=fixed,
        dt=0.02,
        t_end=4.0,
        load=load,
        observe=probe,
        scheme="newmark",
        density=1.0,
    )
    t_wave = _arrival(waves, threshold)
    assert t_wave[2] / t_wave[0] == pytest.approx(3.0, rel=0.12)  # linear in distance
    speed = 4.0 / (t_wave[2] - t_wave[0])
    assert speed == pytest.approx(np.sqrt(UNIT.p_wave), rel=0.1)  # the P-wave speed


def _step_response(n: int):
    """A lattice n nodes wide, left column pinned, right column stepped by 1e-3 in x,
    with unit node drag; the continuum of its outline with the mapped drag. Returns the
    1/e times of the centre node's x displacement and the slowest-mode times."""
    from continuum_vs_network.network.dynamics import simulate

    net = triangular_lattice(n, round(n * 2 / np.sqrt(3)))
    x = net.positions
    col = np.arange(net.n_nodes) % n
    left, right = np.flatnonzero(col == 0), np.flatnonzero(col == n - 1)
    centre = int(np.argmin(np.hypot(*(x - x.mean(axis=0)).T)))
    width = np.ptp(x[:, 0])
    tau_guess = width**2 / (np.pi**2 * 0.75)
    dt, t_end, step = tau_guess / 40, 6 * tau_guess, 1e-3

    traj = simulate(
        net,
        dt=dt,
        t_end=t_end,
        pinned=left,
        damping=1.0,
        inertia=False,
        prescribed={int(i): x[i] + [step, 0.0] for i in right},
        scheme="implicit",
        jacobian="frozen",
    )
    tau_net = relaxation_time(traj.times, traj.positions[:, centre, 0] - x[centre, 0])
    held = np.zeros(net.n_nodes, bool)
    held[left] = held[right] = True
    H = cvn.hessian(x, net).tocsr()[np.repeat(~held, 2)][:, np.repeat(~held, 2)]
    slow_net = slowest_relaxation_time(H, sp.identity(H.shape[0]))

    _, eta = node_drag_to_continuum(1.0, area_per_node=lattice_area_per_node(1.0))
    body = elastic_body(network_mesh(net, refine=1), lattice_lame(1.0), order=2)

    def side(nodes):
        pairs = [s for s in net.springs if s[0] in nodes and s[1] in nodes]
        return near_segments(x[[p[0] for p in pairs]], x[[p[1] for p in pairs]])

    fixed = fix(body, side(set(left))) + fix(body, side(set(right)), displacement=(step, 0.0))
    tr = simulate_body(
        body,
        fixed=fixed,
        dt=dt,
        t_end=t_end,
        damping=Damping(drag=eta),
        observe=displacement_probe(body, x[centre]),
    )
    tau_cont = relaxation_time(tr.times, tr.observed[:, 0, 0])
    K, M1 = stiffness_matrix(body), mass_matrix(body)
    free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    slow_cont = slowest_relaxation_time(K[free][:, free], eta * M1[free][:, free])
    return width, tau_net, tau_cont, slow_net, slow_cont


def test_relaxation_time_grows_as_size_squared_in_network_and_continuum():
    """Same dissipation on both sides (node drag c = 1 and its continuum eta = c / A): the
    relaxation times agree and both grow as L^2 (diffusive), the paper's point that
    relaxation limits learning speed in large networks."""
    rows = np.array([_step_response(n) for n in (6, 9, 12)])
    L = rows[:, 0]
    for j in (1, 3):
        np.testing.assert_allclose(rows[:, j + 1], rows[:, j], rtol=0.05)
    for j in range(1, 5):
        exponent = np.polyfit(np.log(L), np.log(rows[:, j]), 1)[0]
        assert 1.8 < exponent < 2.4, (j, exponent)


def test_relaxation_time_helper():
    t = np.linspace(0.0, 10.0, 1001)
    y = 2.0 - 2.0 * np.exp(-t / 1.7)
    assert relaxation_time(t, y, final=2.0) == pytest.approx(1.7, rel=1e-4)
    with pytest.raises(ValueError, match="settle"):
        relaxation_time(t[:50], y[:50], final=2.0)


@pytest.mark.slow
def test_relaxation_time_scaling_on_larger_lattices():
    """As above up to 24 nodes across (L = 23.5 spacings): exponents within 2.2 of the
    diffusive 2 and network / continuum times within 3 % at the largest size."""
    rows = np.array([_step_response(n) for n in (9, 12, 18, 24)])
    L = rows[:, 0]
    for j in (1, 3):
        assert rows[-1, j + 1] == pytest.approx(rows[-1, j], rel=0.03)
    for j in range(1, 5):
        exponent = np.log(rows[-1, j] / rows[-2, j]) / np.log(L[-1] / L[-2])
        assert 1.95 < exponent < 2.2, (j, exponent)
