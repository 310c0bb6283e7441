"""The learning tracker's recovery after a failed ``relax``: the engine's trust region
from the failed state, then ``relax`` again from where it got."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import Solver, Tracker, paper_task, stern_task
from continuum_vs_network.network.builders import paper_network


def _paper(seed: int):
    rng = np.random.default_rng(seed)
    net = paper_network(rng)
    task = paper_task(net, rng)
    return net, task, task.source_clamps(net, "initial")


@pytest.mark.parametrize("seed", [0, 1])
def test_a_relax_out_of_budget_is_recovered_from_its_failed_state(seed):
    """``relax`` with a budget of 3 iterations stops short of the paper patch's
    equilibrium (strains ~5); the trust region goes on from that state to 100 tol and
    ``relax`` polishes: the equilibrium of an unbounded ``relax``, no continuation retry."""
    net, task, clamped = _paper(seed)
    reference = cvn.relax(net, pinned=task.pinned, clamped=clamped)
    assert reference.iterations > 3
    tracker = Tracker(Solver(reuse=False, max_iter=3, retry_ramps=()))
    state = tracker.solve(net, task.pinned, clamped, net.positions)
    assert state.converged and state.relative_residual <= 1e-10
    assert tracker.stats.trust_regions == 1 and tracker.stats.retries == 0
    assert tracker.stats.relax_calls == 2  # the failed one and the polish
    np.testing.assert_allclose(state.positions, reference.positions, atol=1e-7)
    # without the recovery (and no retry) the same solve fails
    bare = Tracker(Solver(reuse=False, max_iter=3, retry_ramps=(), trust_region=False))
    with pytest.raises(cvn.EquilibriumError):
        bare.solve(net, task.pinned, clamped, net.positions)


def test_the_recovery_stays_within_trust_region_max_free():
    net, task, clamped = _paper(1)
    tracker = Tracker(Solver(reuse=False, max_iter=3, retry_ramps=(), trust_region_max_free=10))
    with pytest.raises(cvn.EquilibriumError):
        tracker.solve(net, task.pinned, clamped, net.positions)
    assert tracker.stats.trust_regions == 0


@pytest.mark.slow
def test_a_large_learning_step_that_stalls_the_sparse_newton_is_recovered():
    """A Stern network of 250 nodes (509 free coordinates: relax runs the sparse Newton),
    every rest length scaled by exp(1.5 N(0, 1)) at once: from the old equilibrium
    ``relax`` ran out of its 2000 iterations (on the machine where this was found); the
    dense trust region from its failed state recovers it in a few iterations."""
    from continuum_vs_network.scenes.stern import stern_network

    rng = np.random.default_rng(12)
    net = stern_network(250, rng)
    task = stern_task(net, 10, 3, rng, candidates=np.ones(net.n_springs, dtype=bool))
    clamped = task.source_clamps(net, "initial")
    tracker = Tracker(Solver(reuse=False))
    before = tracker.solve(net, task.pinned, clamped, None)
    stepped = net.with_rest_length(
        net.rest_length * np.exp(1.5 * rng.standard_normal(net.n_springs))
    )
    state = tracker.solve(stepped, task.pinned, clamped, before.positions)
    assert state.converged and state.relative_residual <= 1e-10
    assert tracker.stats.retries == 0
    if tracker.stats.trust_regions == 0:  # the sparse Newton's iterations are timed
        pytest.skip("relax converged without the recovery here")
    assert tracker.stats.relax_calls == 3  # first state, the failed solve, the polish
