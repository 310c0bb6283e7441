"""Clamps whose directions are linearly dependent hold a node only to first order: no
finite clamp tensions balance a force across them, and the error says so."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.checks import dependent_clamps
from continuum_vs_network.network.constraints import Problem

DATA = Path(__file__).parent / "data"


def _taut_chain(lengths: tuple[float, float]) -> cvn.SpringNetwork:
    """Nodes 0 - 1 - 2 on a line 2 apart (0 and 2 to be pinned), node 3 above node 1
    pulling it sideways: springs 0-3 and 2-3 at 1.3 > their length 1.41 * 0.92."""
    positions = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0]])
    springs = np.array([[0, 1], [1, 2], [0, 3], [1, 3], [2, 3]])
    rest = np.array([lengths[0], lengths[1], 1.3, 0.8, 1.3])
    return cvn.SpringNetwork(positions, springs, np.ones(5), rest)


@pytest.mark.parametrize("lengths", [(1.0, 1.0), (0.9, 1.1)])
def test_clamped_springs_in_a_straight_line_are_named_degenerate(lengths):
    """Clamp lengths that add up to the pins' distance leave node 1 on the line: its
    sideways load would need infinite tension (the two circles touch at one point)."""
    net = _taut_chain(lengths)
    clamped = {0: lengths[0], 1: lengths[1]}
    with pytest.raises(cvn.EquilibriumError, match=r"clamps on springs \[0, 1\] are degenerate"):
        cvn.relax(net, pinned=[0, 2], clamped=clamped)
    # rods of finite stiffness stretch: node 1 leaves the line and the tension is finite
    eq = cvn.relax(net, pinned=[0, 2], clamped=clamped, clamp="rod")
    assert eq.converged and abs(eq.positions[1, 1]) > 1e-6
    assert np.all(np.isfinite(eq.clamp_force)) and np.all(eq.clamp_force != 0)


def test_clamps_with_room_to_bend_are_not_degenerate():
    """Started on the line, where the clamp directions are dependent (the projection onto
    the clamps once divided by their singular Gram matrix), with lengths that add up to
    more than the distance: node 1 bends off the line and the equilibrium is found."""
    net = _taut_chain((1.05, 1.05))
    clamped = {0: 1.05, 1: 1.05}
    eq = cvn.relax(net, pinned=[0, 2], clamped=clamped)
    problem = Problem.build(net, pinned=[0, 2], clamped=clamped)
    assert eq.converged and dependent_clamps(problem, np.asarray(eq.positions)).size == 0
    assert dependent_clamps(problem, np.asarray(net.positions)).tolist() == [0, 1]


def test_folded_clamps_with_free_ends_are_not_degenerate():
    """Network 406's two clamped springs are folded onto each other (1e-7 rad) at a soft
    node, but their far ends are free: their directions stay independent."""
    data = np.load(DATA / "folded_clamps_lattice.npz")
    net = cvn.SpringNetwork(
        data["positions"], data["springs"], data["stiffness"], data["rest_length"]
    )
    clamped = dict(zip(data["clamped_springs"].tolist(), data["clamped_lengths"].tolist()))
    problem = Problem.build(net, clamped=clamped)
    assert dependent_clamps(problem, data["stalled_positions"]).size == 0


@pytest.mark.parametrize("clamp", ["exact", "rod"])
def test_a_clamp_between_two_pinned_nodes_at_another_length_is_refused(clamp):
    """No move can change that length: one ValueError naming the spring and the distance
    (it was 'augmented Lagrangian: no convergence in 60 outer steps' or a projection
    failure, and for rods a residual of 0 reported as not converged)."""
    net = _taut_chain((1.0, 1.0))
    with pytest.raises(ValueError, match=r"clamped: spring 0 has both end nodes pinned, 1 apart"):
        cvn.relax(net, pinned=[0, 1], clamped={0: 1.5}, clamp=clamp)
    eq = cvn.relax(net, pinned=[0, 1], clamped={0: 1.0}, clamp=clamp)  # its own length: met
    assert eq.converged


def _straight_pair(side: int) -> tuple[cvn.SpringNetwork, int, int, int, int, int]:
    """A noise-free ``side x side`` lattice and a straight line ``a - b - c`` of two springs
    ``i = (a, b)``, ``j = (b, c)`` through its most central node ``b``."""
    from continuum_vs_network.network.builders import triangular_lattice

    net = triangular_lattice(side, side, noise=0.0)
    x, springs = net.positions, net.springs
    b = int(np.argmin(np.linalg.norm(x - x.mean(axis=0), axis=1)))
    at_b = np.flatnonzero((springs == b).any(axis=1))
    ends = np.array([s[0] if s[1] == b else s[1] for s in springs[at_b]])
    unit = (x[ends] - x[b]) / np.linalg.norm(x[ends] - x[b], axis=1)[:, None]
    i, j = np.unravel_index(np.argmin(unit @ unit.T), (ends.size, ends.size))
    return net, int(ends[i]), b, int(ends[j]), int(at_b[i]), int(at_b[j])


def test_the_sparse_newton_bends_clamps_started_in_a_line():
    """The same start on the sparse Newton's path (a 16 x 16 lattice: 508 free
    coordinates): it failed with 'singular Schur complement' at the first KKT step; it now
    starts from a nudged point and node b leaves the line a - c."""
    net, a, b, c, i, j = _straight_pair(16)
    problem = Problem.build(net, pinned=[a, c], clamped={i: 1.05, j: 1.05})
    assert problem.free_flat.size > 400  # above the dense trust region: the sparse Newton
    assert dependent_clamps(problem, np.asarray(net.positions)).tolist() == sorted([i, j])
    eq = cvn.relax(net, pinned=[a, c], clamped={i: 1.05, j: 1.05})
    x = np.asarray(eq.positions)
    (u, v), (p, q) = x[c] - x[a], x[b] - x[a]
    off_line = abs(u * q - v * p) / np.hypot(u, v)
    assert eq.converged and off_line > 0.1  # 1.05 + 1.05 over a distance of 2
    assert np.allclose(net.lengths(x)[[i, j]], 1.05, rtol=1e-9)


@pytest.mark.parametrize("clamp", ["exact", "rod"])
def test_clamps_too_short_for_the_pins_are_named(clamp):
    """Three collinear springs of a 16 x 19 lattice (the sparse Newton) clamped to 0.7
    each between pinned nodes 3 apart cannot be met. The errors were 'Hessian could not be
    made positive definite' (exact) and 'did not reach the requested residual' at a
    residual of 4e-16 (rods). Exact clamps are now refused before the solve, naming the
    chain; rods (which stretch, so no chain is impossible for them) fail saying the clamps
    are far from their lengths, and why that can be."""
    from continuum_vs_network.network.builders import triangular_lattice

    net = triangular_lattice(16, 19)
    chain = [int(j) for j in np.flatnonzero(np.isin(net.springs, [80, 81, 82, 83]).all(axis=1))]
    assert net.springs[chain].tolist() == [[80, 81], [81, 82], [82, 83]]
    if clamp == "exact":
        error, match = ValueError, r"nodes 80 and 83 are pinned 3 apart, .* springs \[230, 233"
    else:
        error, match = cvn.EquilibriumError, "clamps are far from their lengths"
    with pytest.raises(error, match=match):
        cvn.relax(net, pinned=[80, 83], clamped=dict.fromkeys(chain, 0.7), clamp=clamp)
    # long enough to span the pins: relaxed
    assert cvn.relax(net, pinned=[80, 83], clamped=dict.fromkeys(chain, 1.2)).converged


def test_a_clamp_longer_than_a_chain_through_pinned_nodes_is_refused():
    """Nodes 0 and 1 pinned 1 apart, springs 0-2 and 1-3 clamped to 1: nodes 2 and 3 are at
    most 3 apart, so clamping spring 2-3 to 4 is refused before the solve, naming the chain
    (a clamp, the pinned pair, a clamp); clamped to 2.9 it is relaxed."""
    net = cvn.SpringNetwork(
        [[0, 0], [1, 0], [0, 1], [1, 1]],
        [[0, 1], [0, 2], [1, 3], [2, 3], [0, 3]],
        [1.0] * 5,
        [1.0, 1.0, 1.0, 1.0, 1.4],
    )
    match = r"spring 3 is clamped to 4, .* springs \[1, 2\] and pinned node pairs \[\(0, 1\)\]"
    with pytest.raises(ValueError, match=match):
        cvn.relax(net, pinned=[0, 1], clamped={1: 1.0, 2: 1.0, 3: 4.0})
    eq = cvn.relax(net, pinned=[0, 1], clamped={1: 1.0, 2: 1.0, 3: 2.9})
    assert eq.converged
    assert np.linalg.norm(eq.positions[3] - eq.positions[2]) == pytest.approx(2.9, rel=1e-9)
