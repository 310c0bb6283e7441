"""A clamp error float64 cannot resolve: named as such, and not retried by learning.

The case (``tests/data/clamp_roundoff_patch.npz``) is a state of the paper scene's GPC
run: a 10-node patch whose learning had grown one clamped spring to 2.7e9 (coordinates
up to 1.7e9) while another clamped spring has rest length 249.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning.states import Solver, Tracker
from continuum_vs_network.network.checks import clamp_roundoff_floor
from continuum_vs_network.network.constraints import Problem

DATA = Path(__file__).parent / "data"


def _case():
    d = np.load(DATA / "clamp_roundoff_patch.npz")
    net = cvn.SpringNetwork(d["positions"], d["springs"], d["stiffness"], d["rest_length"])
    clamped = {int(c): float(v) for c, v in zip(d["clamped_springs"], d["clamped_lengths"])}
    return net, d["pinned"], clamped, d["x0"]


def test_the_clamp_floor_is_one_rounding_unit_of_the_coordinates_over_the_rest_length():
    """At a state the floor is about the spacing of float64 at its largest coordinates
    over the shortest clamped rest length (within 4x); the same state moved 1e12 from the
    origin (1e3x the coordinates) has a floor about 1e3x higher (a factor 4 either way)."""
    net, pinned, clamped, x0 = _case()
    problem = Problem.build(net, pinned=pinned, clamped=clamped)
    floor = clamp_roundoff_floor(problem, x0)
    shortest = float(np.min(net.rest_length[problem.clamp_springs]))
    spacing = float(np.spacing(np.max(np.abs(x0))))
    assert 0.25 < floor / (spacing / shortest) < 4.0
    ratio = clamp_roundoff_floor(problem, x0 + 1e12) / floor
    assert 250 < ratio < 4000
    assert clamp_roundoff_floor(Problem.build(net, pinned=pinned), x0) == 0.0  # no clamps


def test_a_clamp_error_below_float64s_reach_is_named_and_flagged():
    """Newton balances the forces to 1e-14 of tol's scale, but one clamp stays 2e-10 off
    its length, within the float64 floor of ~1e-9 there: relax raises with that reason and
    ``roundoff`` set, the state's clamp error within 10x of the floor."""
    net, pinned, clamped, x0 = _case()
    with pytest.raises(cvn.EquilibriumError) as info:
        cvn.relax(net, pinned=pinned, clamped=clamped, x0=x0, tol=1e-10)
    err = info.value
    assert err.roundoff
    assert "float64's reach for the clamp lengths" in err.reason
    state = err.state
    assert state.relative_residual <= 1e-10
    problem = Problem.build(net, pinned=pinned, clamped=clamped)
    stop = problem.stop_rule(1e-10, max_iter=1, max_seconds=1.0)
    error = stop.clamp_error(problem.clamp_violation(state.positions))
    assert 1e-10 < error <= 10 * clamp_roundoff_floor(problem, state.positions)


def test_a_failure_at_the_roundoff_floor_is_not_retried_by_learning():
    """The learning tracker gives up at once: no trust region from the stalled point and
    no continuation from the start (each cost up to 2000 iterations), and the reason it
    raises is the floor's, not a retry's."""
    net, pinned, clamped, x0 = _case()
    tracker = Tracker(Solver(reuse=False))
    with pytest.raises(cvn.EquilibriumError) as info:
        tracker.solve(net, pinned, clamped, x0)
    assert info.value.roundoff
    assert tracker.stats.retries == 0 and tracker.stats.trust_regions == 0
    assert tracker.stats.relax_calls == 1
