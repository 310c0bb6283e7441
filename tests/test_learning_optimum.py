"""The exact-gradient optimum of several examples (learning.optimum): what a network can hold."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import examples_task, gain_examples
from continuum_vs_network.learning.coupling import coupling_verdict, measure_coupling
from continuum_vs_network.learning.optimum import exact_optimum
from continuum_vs_network.network.builders import triangular_lattice


def _gain_set(m, seed):
    rng = np.random.default_rng(seed)
    net = triangular_lattice(5, 5, noise=0.1, rng=rng)
    tasks = gain_examples(examples_task(net, m, rng), net, rng, change=0.5)
    return net, tasks


@pytest.mark.parametrize("m", [1, 2])
def test_optimum_meets_every_gain_example_by_changing_the_response(m):
    net, tasks = _gain_set(m, 3)
    floor = 0.1 * float(np.mean(net.stiffness))
    o = exact_optimum(net, tasks, floor=floor)
    assert o.converged
    # each example's own error, re-measured on freshly relaxed free states of the optimum
    for task, ratio in zip(tasks.tasks, o.example_ratio):
        free = cvn.relax(o.net, pinned=task.pinned, clamped=task.source_clamps(o.net))
        free0 = cvn.relax(net, pinned=task.pinned, clamped=task.source_clamps(net))
        measured = task.error(o.net, free.positions) / task.error(net, free0.positions)
        assert measured == pytest.approx(ratio, rel=1e-3, abs=1e-9)
        assert measured <= 1e-2
        # the sources cause the new response (a stiffness-only network has no prestress)
        share = measure_coupling(net, o.net, task).share
        assert coupling_verdict(share) == "coupled"
    # bulk learning above the floor: sources and targets keep their stiffnesses
    frozen = np.zeros(net.n_springs, dtype=bool)
    for task in tasks.tasks:
        frozen[task.sources] = frozen[task.targets] = True
    assert np.array_equal(o.net.stiffness[frozen], net.stiffness[frozen])
    assert o.net.stiffness.min() >= floor * (1 - 1e-12)
    assert not np.allclose(o.net.stiffness, net.stiffness)


def test_optimum_rejects_a_non_positive_floor():
    net, tasks = _gain_set(1, 3)
    with pytest.raises(ValueError, match="floor"):
        exact_optimum(net, tasks, floor=0.0)
