"""The dense trust-region Newton (network/trust.py) and the rigid placement under default pins."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.builders import paper_network, triangular_lattice
from continuum_vs_network.network.trust_model import (
    RigidBasis,
    Spectrum,
    null_basis,
    rigid_motions,
    subproblem,
)


@pytest.mark.parametrize("lowest", [-0.5, 0.01])
def test_subproblem_boundary_step_solves_the_shifted_system(lowest):
    """Outside the radius the exact step has |p| = radius and (H + s I) p = -g with
    s >= max(0, -lambda_min): the trust-region optimality conditions (More & Sorensen)."""
    rng = np.random.default_rng(0)
    vals = np.sort(np.concatenate([[lowest], rng.uniform(0.1, 10.0, 11)]))
    vecs = np.linalg.qr(rng.normal(size=(12, 12)))[0]
    g = rng.normal(size=12)
    H = vecs @ np.diag(vals) @ vecs.T
    radius = 0.05
    c, den, length = subproblem(Spectrum(vals, vecs.T @ g), radius)
    p, shift = vecs @ c, float(den[0] - vals[0])
    assert np.linalg.norm(p) == pytest.approx(radius, rel=1e-6)
    assert length == pytest.approx(np.linalg.norm(p), rel=1e-12)
    np.testing.assert_allclose(den - vals, shift, rtol=1e-12)  # one shift for every mode
    assert shift >= max(0.0, -lowest)
    np.testing.assert_allclose((H + shift * np.eye(12)) @ p, -g, atol=1e-8)


def test_subproblem_hard_case_steps_along_the_lowest_eigenvector():
    """No gradient on the negative-curvature mode (a saddle reached exactly): the boundary
    step still leaves along that mode, at the shift that makes it singular."""
    vals = np.array([-0.5, 0.2, 1.0, 3.0])
    gt = np.array([0.0, 0.1, -0.2, 0.3])
    c, den, length = subproblem(Spectrum(vals, gt), 1.0)
    assert length == pytest.approx(1.0, rel=1e-12)
    assert abs(c[0]) > 0.9  # mostly along the negative mode
    np.testing.assert_allclose(den, vals + 0.5, rtol=1e-12)  # shift = -lowest eigenvalue
    np.testing.assert_allclose(c[1:], -gt[1:] / (vals[1:] + 0.5), rtol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 1e3])
def test_rigid_basis_spans_the_rigid_free_space_of_the_svd(offset):
    """The Householder basis of a free network's moves (translations removed once, the
    rotation at each x) spans the same space as the null space of the three rigid rows,
    with orthonormal columns in scaled coordinates, also far from the origin."""
    rng = np.random.default_rng(4)
    net = paper_network(rng)
    x0 = net.positions + offset
    inv_root = rng.uniform(0.2, 2.0, 2 * net.n_nodes)
    rigid = RigidBasis(x0, inv_root, 1.0)
    x = x0 + rng.normal(scale=0.3, size=x0.shape)
    Q = rigid(x) / inv_root[:, None]
    coords = np.arange(2 * net.n_nodes)
    ref = null_basis(rigid_motions(x, coords) * inv_root[None, :])
    assert Q.shape == ref.shape
    np.testing.assert_allclose(Q.T @ Q, np.eye(Q.shape[1]), atol=1e-12)
    np.testing.assert_allclose(Q @ Q.T, ref @ ref.T, atol=1e-10)


def test_stiff_rod_among_soft_springs_converges_to_its_rest_length():
    """One spring of k = 1e10, its rest length 5 % above its length, among k = 1 springs:
    it pushes the lattice apart and ends at its rest length to within its tension / k."""
    net = triangular_lattice(10, 10)
    j = net.n_springs // 2
    k = np.ones(net.n_springs)
    k[j] = 1e10
    rest = net.lengths().copy()
    rest[j] *= 1.05
    net = net.with_stiffness(k).with_rest_length(rest)
    eq = cvn.relax(net)
    assert eq.converged and eq.relative_residual <= 1e-10
    assert eq.iterations <= 12  # 16 before the geodesic step and rigid-motion removal
    r = net.lengths(eq.positions)[j]
    tension = abs(
        np.linalg.norm(
            cvn.forces(eq.positions, net.with_stiffness(k * (k > 1)))[net.springs[j]], axis=1
        )
    ).max()
    assert abs(r - rest[j]) <= tension / 1e10 + 1e-10 * rest[j]
    # the lattice's soft springs carry the rod's push: it is really stretched
    assert r > 1.01 * net.lengths()[j]


def _prestressed_patch(seed: int) -> cvn.SpringNetwork:
    rng = np.random.default_rng(seed)
    net = paper_network(rng)
    factor = 10.0 ** rng.uniform(np.log10(0.3), np.log10(3.0), net.n_springs)
    k = 10.0 ** rng.uniform(-3, 3, net.n_springs)
    return net.with_stiffness(k).with_rest_length(net.lengths() * factor)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_default_pins_equal_explicit_pins_up_to_a_rigid_motion(seed):
    """Under default pins rigid motion is removed by the solver and the result placed on
    the pins afterwards; explicit pins (the same mask) solve the pinned problem directly.
    Where both reach the same minimum they agree: same energy, same spring lengths, the
    pinned node in place and the second pin's coordinate kept."""
    net = _prestressed_patch(seed)
    free = cvn.relax(net)
    pins = cvn.default_pins(net)
    pinned = cvn.relax(net, pinned=pins)
    full = np.flatnonzero(pins.all(axis=1))[0]
    np.testing.assert_array_equal(free.positions[full], net.positions[full])
    part = np.flatnonzero(pins.sum(axis=1) == 1)[0]
    c = np.flatnonzero(pins[part])[0]
    d, d0 = free.positions[part] - free.positions[full], net.positions[part] - net.positions[full]
    if np.linalg.norm(d) >= abs(d0[c]):  # the coordinate can be kept: it is
        assert free.positions[part, c] == pytest.approx(net.positions[part, c], abs=1e-12)
    else:  # the pair shrank below the offset: it keeps its start orientation
        np.testing.assert_allclose(d / np.linalg.norm(d), d0 / np.linalg.norm(d0), atol=1e-12)
    if abs(free.energy - pinned.energy) <= 1e-9 * max(free.energy, 1.0):
        np.testing.assert_allclose(
            net.lengths(free.positions), net.lengths(pinned.positions), rtol=1e-7, atol=1e-9
        )


def test_strongly_prestressed_patches_converge_in_few_iterations():
    """Rest lengths 0.3-3x the geometry and k over six decades: a rotation left nearly free
    by the pins and stiff springs turning about soft ones made the trust region creep
    (median 42, up to 320 iterations on the 10-node patches of the benchmark family)."""
    its = [cvn.relax(_prestressed_patch(seed)).iterations for seed in range(12)]
    assert np.median(its) <= 30
    assert max(its) <= 80


def test_trust_region_on_a_reordered_frame_agrees_with_the_sparse_newton():
    """Above ``spd.DENSE_MAX`` free coordinates the frame puts rows in a fill-reducing
    order; the trust region, called on such a problem, must still move each coordinate by
    its own step (it once read the rows as natural order when every coordinate was free)."""
    from continuum_vs_network.network.constraints import Problem
    from continuum_vs_network.network.lagrangian import Frame
    from continuum_vs_network.network.stopping import Trace
    from continuum_vs_network.network.trust import trust_region_newton

    rng = np.random.default_rng(3)
    net = triangular_lattice(16, 16, noise=0.15, rng=rng)
    net = net.with_rest_length(net.lengths() * rng.uniform(0.9, 1.1, net.n_springs))
    free = np.ones((net.n_nodes, 2), dtype=bool)
    problem = Problem.build(net).with_free(free)
    coords = Frame(net, free).coords
    assert coords.size == 2 * net.n_nodes and np.any(np.diff(coords) < 0)  # reordered
    stop = problem.stop_rule(1e-10, max_iter=200, max_seconds=60.0)
    outcome = trust_region_newton(problem, net.positions, stop, Trace())
    assert outcome.converged
    assert problem.residual(outcome.x).imbalance <= 1e-10
    reference = cvn.relax(net)
    energy = problem.energy(outcome.x)
    assert abs(energy - reference.energy) <= 1e-8 * max(reference.energy, 1e-12)


def _trial_radii(nets, monkeypatch) -> list[list[float]]:
    """The radius of every trust-region trial of each relax of ``nets``, in order."""
    from continuum_vs_network.network import trust

    made = trust._trial
    radii: list[float] = []

    def recorded(problem, model, radius, *rest):
        radii.append(radius)
        return made(problem, model, radius, *rest)

    monkeypatch.setattr(trust, "_trial", recorded)
    out = []
    for net in nets:
        radii.clear()
        cvn.relax(net)
        out.append(list(radii))
    monkeypatch.setattr(trust, "_trial", made)
    return out


def test_shorter_tries_are_made_only_where_stiff_springs_are_projected(monkeypatch):
    """The halved trials after a poor step exist for trials whose stiff-spring projection
    gave up. On the paper's patches (k in U(0.5, 50): no spring 10x the median) the trials
    are exactly those of a trust region without halvings (measured on 200 patches: 18
    trials per relax, against 21 with halvings); on prestressed patches with k over six
    decades the halvings are still made."""
    from continuum_vs_network.network import trust
    from continuum_vs_network.network.constraints import Problem
    from continuum_vs_network.network.stiff_springs import StiffSprings

    plain = [paper_network(np.random.default_rng(seed)) for seed in range(8)]
    for net in plain:
        problem = Problem.build(net)
        assert StiffSprings.find(problem, problem.free_flat) is None
    stiff = [_prestressed_patch(seed) for seed in range(8)]
    default = _trial_radii(plain + stiff, monkeypatch)
    monkeypatch.setattr(trust, "_SHORTER_TRIES", 0)
    without = _trial_radii(plain + stiff, monkeypatch)
    assert default[: len(plain)] == without[: len(plain)]
    assert default[len(plain) :] != without[len(plain) :]
