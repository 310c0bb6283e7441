"""Visco-elastic networks and continua: spring dashpots (Kelvin-Voigt), Maxwell arms
(standard linear solid), displacement steps, and lattice / continuum relaxation spectra."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import continuum_vs_network as cvn
from continuum_vs_network.network.dynamics import simulate_viscous
from continuum_vs_network.network.viscous import (
    Viscosity,
    dashpot_force,
    dashpot_matrix,
    linear_system,
)

PINNED = np.array([[True, True], [False, True]])  # node 0 pinned, node 1 moves along x


def _spring(k=2.0):
    return cvn.SpringNetwork(
        np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0, 1]]), np.array([k]), np.array([1.0])
    )


def _rates(errors):
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def test_spring_with_dashpot_and_drag_decays_with_time_c_plus_gamma_over_k():
    """(c + gamma) u' = -k u: u = u0 exp(-k t / (c + gamma)); backward Euler first order."""
    c, gamma, k, u0, T = 0.5, 1.5, 2.0, 0.1, 1.0
    errors = []
    for dt in (0.02, 0.01, 0.005):
        tr = simulate_viscous(
            _spring(k),
            Viscosity(drag=c, dashpot=gamma),
            dt=dt,
            t_end=T,
            pinned=PINNED,
            x0=[[0, 0], [1 + u0, 0]],
        )
        errors.append(abs(tr.positions[-1, 1, 0] - 1 - u0 * np.exp(-k * T / (c + gamma))))
    assert np.all(np.abs(_rates(errors) - 1.0) < 0.1)
    assert errors[-1] < 2e-3 * u0


def test_maxwell_arm_matches_the_closed_form_standard_linear_solid():
    """c u' = -k u - k2 (u - q), gamma2 q' = k2 (u - q): z(t) = expm(-C^-1 K t) z0."""
    k, k2, g2, c, u0, T = 2.0, 3.0, 2.0, 1.0, 0.1, 1.0
    K = np.array([[k + k2, -k2], [-k2, k2]])
    C = np.diag([c, g2])
    exact = sla.expm(-np.linalg.solve(C, K) * T) @ [u0, 0.0]
    errors = []
    for dt in (0.02, 0.01, 0.005):
        tr = simulate_viscous(
            _spring(k),
            Viscosity(drag=c, arm_stiffness=k2, arm_dashpot=g2),
            dt=dt,
            t_end=T,
            pinned=PINNED,
            x0=[[0, 0], [1 + u0, 0]],
            arm0=[1.0],
        )
        errors.append(np.hypot(tr.positions[-1, 1, 0] - 1 - exact[0], tr.arm[-1, 0] - 1 - exact[1]))
    assert np.all(np.abs(_rates(errors) - 1.0) < 0.15)
    # the linearised operators give the same two relaxation rates
    Kn, Cn = linear_system(_spring(k), Viscosity(drag=c, arm_stiffness=k2, arm_dashpot=g2), ~PINNED)
    np.testing.assert_allclose(
        np.sort(sla.eigh(Kn.toarray(), Cn.toarray(), eigvals_only=True)),
        np.sort(sla.eigh(K, C, eigvals_only=True)),
        rtol=1e-12,
    )


def test_stress_relaxation_of_a_held_standard_linear_solid():
    """Both ends held at a stretch: the force relaxes from (k + k2) u to k u with time
    gamma2 / k2 (the standard linear solid's stress relaxation); no drag involved."""
    k, k2, g2, u = 1.0, 3.0, 6.0, 0.05
    vis = Viscosity(drag=1.0, arm_stiffness=k2, arm_dashpot=g2)
    tr = simulate_viscous(
        _spring(k), vis, dt=0.001, t_end=4.0, pinned=[0], prescribed={1: [1 + u, 0.0]}
    )
    force = k * u + k2 * (1 + u - tr.arm[:, 0])
    expected = k * u + k2 * u * np.exp(-tr.times / vis.arm_time)
    assert np.max(np.abs(force - expected)) < 1e-3 * k2 * u


def test_kelvin_voigt_network_under_a_displacement_step_is_elastic_at_once():
    """Dashpots proportional to the springs, no drag: the step's impulse puts the network
    on its elastic equilibrium at t = 0+, and it stays there."""
    net = cvn.triangular_lattice(5, 5)
    x = net.positions
    col = np.arange(net.n_nodes) % 5
    left, right = np.flatnonzero(col == 0), np.flatnonzero(col == 4)
    step = {int(i): x[i] + [1e-4, 0.0] for i in right}
    tr = simulate_viscous(
        net, Viscosity(drag=0.0, dashpot=3.0), dt=0.5, t_end=2.0, pinned=left, prescribed=step
    )
    pinned = np.zeros(net.n_nodes, bool)
    pinned[left] = pinned[right] = True
    x0 = x.copy()
    for i, p in step.items():
        x0[i] = p
    eq = cvn.relax(net, pinned=np.flatnonzero(pinned), x0=x0)
    for frame in tr.positions:  # the impulse is linear: O(step^2) off, not a creep O(step)
        assert np.max(np.abs(frame - eq.positions)) < 1e-3 * 1e-4


def test_dashpot_matrix_is_the_force_per_velocity():
    net = cvn.triangular_lattice(4, 4)
    rng = np.random.default_rng(1)
    x = net.positions + 0.05 * rng.standard_normal(net.positions.shape)
    v = rng.standard_normal(x.shape)
    D = dashpot_matrix(x, net, 2.5)
    np.testing.assert_allclose(dashpot_force(x, net, 2.5, v).ravel(), -(D @ v.ravel()))
    assert np.min(np.linalg.eigvalsh(D.toarray())) > -1e-12  # dissipative


def test_bad_viscosity_is_named():
    with pytest.raises(ValueError, match="arm_stiffness and arm_dashpot"):
        Viscosity(arm_stiffness=1.0)
    with pytest.raises(ValueError, match="drag"):
        Viscosity(drag=-1.0)
    with pytest.raises(ValueError, match="no dissipation"):
        Viscosity(drag=0.0)
    with pytest.raises(ValueError, match="arm0"):
        simulate_viscous(_spring(), Viscosity(), dt=0.1, t_end=1.0, arm0=[1.0])


# -- lattice against its continuum --------------------------------------------------------
def _slowest_times(n: int, vis: Viscosity) -> tuple[float, float]:
    """Slowest relaxation time of a lattice n nodes wide (left and right columns held) and
    of the continuum of its outline with the mapped damping (:func:`lattice_damping`)."""
    pytest.importorskip("skfem")
    from continuum_vs_network.continuum.body import elastic_body, near_segments
    from continuum_vs_network.continuum.materials import lattice_lame
    from continuum_vs_network.continuum.mesh import network_mesh
    from continuum_vs_network.continuum.static import fix
    from continuum_vs_network.continuum.viscoelastic import (
        lattice_damping,
        slowest_relaxation_time,
    )
    from continuum_vs_network.continuum.viscoelastic import linear_system as body_system

    net = cvn.triangular_lattice(n, round(n * 2 / np.sqrt(3)))
    x = net.positions
    col = np.arange(net.n_nodes) % n
    left, right = np.flatnonzero(col == 0), np.flatnonzero(col == n - 1)
    held = np.zeros(net.n_nodes, bool)
    held[left] = held[right] = True
    free = np.repeat(~held[:, None], 2, axis=1)
    t_net = slowest_relaxation_time(*linear_system(net, vis, free))
    body = elastic_body(network_mesh(net, refine=1), lattice_lame(1.0), order=2)

    def side(nodes):
        pairs = [s for s in net.springs if s[0] in nodes and s[1] in nodes]
        return near_segments(x[[p[0] for p in pairs]], x[[p[1] for p in pairs]])

    fixed = fix(body, side(set(left))) + fix(body, side(set(right)))
    t_body = slowest_relaxation_time(*body_system(body, lattice_damping(vis), fixed))
    return t_net, t_body


DRAG = Viscosity(drag=1.0)
KELVIN_VOIGT = Viscosity(drag=1.0, dashpot=5.0)
STANDARD_SOLID = Viscosity(drag=1.0, arm_stiffness=1.0, arm_dashpot=20.0)


@pytest.mark.parametrize("vis", [DRAG, KELVIN_VOIGT, STANDARD_SOLID], ids=["drag", "kv", "sls"])
def test_lattice_and_mapped_continuum_have_the_same_slowest_time(vis):
    for n in (6, 9):
        t_net, t_body = _slowest_times(n, vis)
        assert t_body == pytest.approx(t_net, rel=0.05), (n, t_net, t_body)


def test_kelvin_voigt_adds_gamma_over_k_to_every_drag_time_in_both_media():
    """Dashpots proportional to the springs: C = c I + (gamma / k) K, so every relaxation
    time is the drag one plus gamma / k, in the lattice and in its continuum; without drag
    every mode relaxes in gamma / k exactly."""
    drag = _slowest_times(6, DRAG)
    kv = _slowest_times(6, KELVIN_VOIGT)
    np.testing.assert_allclose(np.subtract(kv, drag), 5.0, rtol=1e-8)
    np.testing.assert_allclose(_slowest_times(6, Viscosity(drag=0.0, dashpot=2.0)), 2.0, rtol=1e-8)


def test_dashpot_and_arm_mappings_add_no_gap_to_the_drag_one():
    """The lattice / continuum gap is the node-drag one (outline and lattice-spacing
    effects, ~1/n): with spring dashpots the absolute gap of the slowest time is the drag
    gap exactly (every time shifts by gamma / k), with Maxwell arms it is smaller (the
    arm's time, the same in both media, shares the slowest mode), so the relative SLS gap
    grows with size while the arm's share shrinks (0.4 % at 6, 1.6 % at 12) towards the
    drag gap (measured: 1.96, 1.83, 1.62 % at 18, 24, 30 against 2.61, 2.11, 1.76 %)."""
    for n in (6, 9):
        drag = np.subtract(*_slowest_times(n, DRAG)[::-1])
        kv = np.subtract(*_slowest_times(n, KELVIN_VOIGT)[::-1])
        sls = np.subtract(*_slowest_times(n, STANDARD_SOLID)[::-1])
        assert drag > 0
        assert kv == pytest.approx(drag, rel=1e-6)
        assert 0 < sls < drag, (n, drag, sls)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("vis", "sizes"),
    [(DRAG, (12, 18, 24)), (KELVIN_VOIGT, (12, 18, 24)), (STANDARD_SOLID, (18, 24, 30))],
    ids=["drag", "kv", "sls"],
)
def test_slowest_times_converge_with_size(vis, sizes):
    """The relative lattice / continuum gap of the slowest time shrinks with size (drag
    3.38, 2.61, 2.11 %; Kelvin-Voigt 2.97, 2.47, 2.04 %; standard linear solid, once the
    drag-limited time dominates the arm's, 1.96, 1.83, 1.62 %): below 3.5 %, then 2.5 %."""
    times = [_slowest_times(n, vis) for n in sizes]
    gaps = [abs(b - a) / a for a, b in times]
    assert gaps[0] > gaps[1] > gaps[2], gaps
    assert gaps[0] < 0.035 and gaps[2] < 0.025, gaps


# -- continuum ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def block():
    pytest.importorskip("skfem")
    from continuum_vs_network.continuum.body import elastic_body
    from continuum_vs_network.continuum.materials import Material
    from continuum_vs_network.continuum.mesh import rectangle_mesh

    return elastic_body(rectangle_mesh(2.0, 1.0, h=0.25), Material(1.0, 1.0), order=2)


@pytest.mark.parametrize(
    "kind", ["kelvin_voigt", "rayleigh_stiffness"], ids=["kelvin_voigt", "rayleigh"]
)
def test_continuum_damping_proportional_to_stiffness_is_elastic_after_a_displacement_step(
    block, kind
):
    """C = tau K: the step's impulse through C_fb puts the body on its elastic solution
    at t = 0+ (it crept to 0.62 of it at t = tau before the coupling was kept)."""
    from continuum_vs_network.continuum.static import fix, solve_static
    from continuum_vs_network.continuum.viscoelastic import Damping, simulate_body

    fixed = fix(block, lambda x, y: x < 1e-9) + fix(
        block, lambda x, y: x > 2 - 1e-9, displacement=(0.01, 0.0)
    )
    elastic = solve_static(block, fixed).u
    damping = (
        Damping(viscous_lam=1.0, viscous_mu=1.0)
        if kind == "kelvin_voigt"
        else Damping(rayleigh_stiffness=1.0)
    )
    for scheme in ("backward_euler", "newmark"):
        tr = simulate_body(block, fixed=fixed, dt=0.05, t_end=1.0, damping=damping, scheme=scheme)
        assert np.linalg.norm(tr.u - elastic) < 1e-10 * np.linalg.norm(elastic)
        np.testing.assert_allclose(tr.energy, tr.energy[-1], rtol=1e-10)


def test_continuum_standard_linear_solid_relaxes_its_arm_energy_exponentially(block):
    """Every DOF held on an affine stretch: the arm's internal strain relaxes as
    exp(-t / tau) with tau = viscous / elastic arm moduli, so the energy is
    E_inf + E_arm exp(-2 t / tau); backward Euler converges at first order."""
    from continuum_vs_network.continuum.static import Dirichlet
    from continuum_vs_network.continuum.viscoelastic import Damping, simulate_body

    loc = block.dof_locations
    u_affine = np.where(block.dof_component == 0, 0.01 * loc[:, 0], 0.0)
    fixed = Dirichlet(np.arange(block.n_dofs), u_affine)
    tau = 2.0
    damping = Damping(
        drag=1.0, arm_lam=0.5, arm_mu=0.5, arm_viscous_lam=tau * 0.5, arm_viscous_mu=tau * 0.5
    )
    errors = []
    for dt in (0.1, 0.05, 0.025):
        tr = simulate_body(block, fixed=fixed, dt=dt, t_end=2.0, damping=damping)
        e_inf = 0.5 * (u_affine @ (stiffness_k(block) @ u_affine))
        e_arm = 0.5 * e_inf  # arm moduli half the body's
        expected = e_inf + e_arm * np.exp(-2 * tr.times / tau)
        errors.append(abs(tr.energy[-1] - expected[-1]) / e_arm)
        assert tr.energy[0] == pytest.approx(e_inf + e_arm, rel=1e-10)
    assert np.all(np.abs(_rates(errors) - 1.0) < 0.15)


def stiffness_k(body):
    from continuum_vs_network.continuum.body import stiffness_matrix

    return stiffness_matrix(body)


def test_stiff_rod_is_stable_at_any_step():
    """A rod of k = 1e10 among k = 1 springs, dt far above 2 c / k_rod: backward Euler
    stays bounded and lands on the equilibrium with the rod at its rest length."""
    net = cvn.triangular_lattice(4, 4)
    k = net.stiffness.copy()
    k[5] = 1e10
    L = net.rest_length.copy()
    L[5] *= 1.05  # the rod wants to be 5 % longer
    net = net.with_stiffness(k).with_rest_length(L)
    vis = Viscosity(drag=1.0, dashpot=0.5, arm_stiffness=1.0, arm_dashpot=2.0)
    tr = simulate_viscous(net, vis, dt=1.0, t_end=200.0, pinned=cvn.default_pins(net))
    assert np.all(np.isfinite(tr.positions))
    assert tr.residual[-1] < 1e-6 * tr.residual[0]  # settled: net forces gone
    assert np.all(np.diff(tr.energy) <= 1e-12 * tr.energy[0])  # dissipative
    assert net.lengths(tr.positions[-1])[5] == pytest.approx(L[5], rel=1e-6)


def test_a_first_iterate_changes_the_cost_of_a_step_not_its_result():
    """Backward Euler has one solution per step: a predictor ``2 x1 - x0`` (or a poor guess)
    gives the same state to the tolerance, and the predictor needs fewer iterations."""
    from continuum_vs_network.network.held_boundary import held_boundary
    from continuum_vs_network.network.stepper import Stepper

    net = cvn.triangular_lattice(6, 6)
    rng = np.random.default_rng(1)
    net = net.with_rest_length(net.rest_length * (1 + 0.05 * rng.standard_normal(net.n_springs)))
    pins = np.zeros((net.n_nodes, 2), bool)
    pins[:6] = True  # the bottom row held
    free = held_boundary(net, pins, None, None, net.positions)[1]
    steppers = [Stepper(net, Viscosity(drag=1.0), free, 0.01) for _ in range(3)]
    xs = [net.positions] * 3
    prev = None
    for _ in range(20):
        plain = steppers[0].step(net, xs[0])[0]
        guess = None if prev is None else 2 * xs[1] - prev
        predicted = steppers[1].step(net, xs[1], guess=guess)[0]
        poor = steppers[2].step(net, xs[2], guess=xs[2] + 0.01)[0]
        np.testing.assert_allclose(predicted, plain, atol=1e-8)
        np.testing.assert_allclose(poor, plain, atol=1e-8)
        prev = xs[1]
        xs = [plain, predicted, poor]
    assert steppers[1].newton_iterations < steppers[0].newton_iterations
