"""Node tasks: the exact gradient against finite differences, GCL against it as eta -> 0."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    History,
    NodeTask,
    ProspectiveConfiguration,
    Sensitivity,
    node_cost_gradient,
    node_task,
    train,
)
from continuum_vs_network.network.builders import triangular_lattice


@pytest.fixture(scope="module")
def lattice():
    rng = np.random.default_rng(1)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    return net, node_task(net, rng, n_targets=1)


def _free(net, task):
    return cvn.relax(net, pinned=task.pinned, clamped=task.source_clamps(net))


@pytest.mark.parametrize("dof", ["rest_length", "stiffness"])
def test_node_gradient_matches_finite_differences(lattice, dof):
    net, task = lattice
    g = node_cost_gradient(net, task, _free(net, task), dof=dof)
    rng = np.random.default_rng(0)
    d = rng.standard_normal(net.n_springs)
    h = 1e-6
    theta = net.rest_length if dof == "rest_length" else net.stiffness

    def error(t):
        n = net.with_rest_length(t) if dof == "rest_length" else net.with_stiffness(t)
        return task.error(n, _free(n, task).positions)

    fd = (error(theta + h * d) - error(theta - h * d)) / (2 * h)
    assert fd == pytest.approx(g @ d, rel=1e-5)


def test_gcl_over_alpha_tends_to_minus_k_times_the_gradient(lattice):
    # one target coordinate: GCL / alpha -> -K dC/dtheta, K = 1 / (its compliance)
    net, task = lattice
    free = _free(net, task)
    sens = Sensitivity(net, task.pinned, task.source_clamps(net), free)
    load = np.zeros((net.n_nodes, 2))
    load[task.nodes, task.coords] = 1.0
    v, _ = sens.solve(load)
    K = 1.0 / float(v[task.nodes[0], task.coords[0]])
    want = -K * node_cost_gradient(net, task, free)
    errs = []
    for eta in (1e-1, 1e-2, 1e-3):
        raw = CoupledLearning(1.0, eta).update(net, task).raw
        errs.append(np.linalg.norm(raw - want) / np.linalg.norm(want))
    assert errs[-1] < 1e-3
    assert errs[1] < errs[0] / 5 and errs[2] < errs[1] / 5


def test_node_tasks_train_and_round_trip(lattice, tmp_path):
    net, task = lattice
    for rule in (CoupledLearning(0.5, 0.1), ProspectiveConfiguration(0.5), ExactGradient(1.0)):
        h = train(net, task, rule, 30, progress=False)
        assert h.completed[0] == 30, h.stop_reason
        assert h.error_initial[0, -1] < 1e-2 * h.error_initial[0, 0]
        assert np.allclose(h.target_strain[0, 0], h.target_length[0, 0] - task.reference)
    back = History.load(h.save(tmp_path / "h.npz"))
    assert isinstance(back.tasks[0], NodeTask)
    assert np.array_equal(back.tasks[0].nodes, task.nodes)


def test_node_task_bad_input(lattice):
    net, task = lattice
    with pytest.raises(ValueError, match="pinned"):
        NodeTask.create(net, task.sources, 0.1, [35], [0], 0.1, pinned=task.pinned)
    with pytest.raises(ValueError, match="coords"):
        NodeTask.create(net, task.sources, 0.1, [10], [2], 0.1)
    with pytest.raises(ValueError, match="noise"):
        CoupledLearning(0.5, 0.1).update(net, task, noise=1e-3, rng=np.random.default_rng(0))
