"""Node tasks (absolute and relative outputs): the exact gradient against finite differences,
GCL against it as eta -> 0, the held state's reactions, and a relative task learned by
changing how the sources drive the outputs (coupled, not prestressed)."""

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
    Solver,
    TaskSet,
    Tracker,
    anchored,
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


@pytest.fixture(scope="module")
def relative():
    """A relative task (node a's coordinate against node b's) on the same kind of lattice."""
    rng = np.random.default_rng(1)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    return net, node_task(net, rng, n_targets=1, relative=True)


def _compliance(net, task, free):
    """``B H^-1 B^T`` of the outputs at the free state (one target: a number)."""
    sens = Sensitivity(net, task.pinned, task.source_clamps(net), free)
    B = task.selector(net.n_nodes)
    return np.array([[np.sum(b * sens.solve(c)[0]) for c in B] for b in B])


def _free(net, task):
    # finite differences of step 1e-6 to 1e-5 need states solved well below relax's
    # default 1e-10 (a state left at 2e-12 against its neighbour's 2e-16 put the
    # difference 0.3 % off)
    return cvn.relax(net, pinned=task.pinned, clamped=task.source_clamps(net), tol=1e-12)


@pytest.mark.parametrize("which", ["lattice", "relative"])
@pytest.mark.parametrize("dof", ["rest_length", "stiffness"])
def test_node_gradient_matches_finite_differences(request, which, dof):
    net, task = request.getfixturevalue(which)
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


def test_relative_output_is_a_difference_of_coordinates(relative):
    net, task = relative
    a, b, c = task.nodes[0], task.relative_to[0], task.coords[0]
    assert task.relative.all() and a != b
    x = net.positions + 0.01 * np.random.default_rng(2).standard_normal(net.positions.shape)
    assert task.outputs(x)[0] == x[a, c] - x[b, c]
    assert task.reference[0] == net.positions[a, c] - net.positions[b, c]
    # a rigid translation moves both nodes: the relative output does not change
    assert task.outputs(x + np.array([0.3, -0.2]))[0] == pytest.approx(
        task.outputs(x)[0], abs=1e-14
    )


def test_hold_meets_the_values_with_equal_and_opposite_reactions(relative):
    net, task = relative
    free = _free(net, task)
    want = task.outputs(free.positions) + 0.02
    held = task.hold(net, Tracker(Solver()), free.positions, want, key="nodes")
    assert task.outputs(held.positions) == pytest.approx(want, abs=1e-8)
    # net force on the free coordinates: zero except the reactions on (a, c) and (b, c),
    # which are equal and opposite (the constraint's multiplier)
    from continuum_vs_network.network.constraints import Problem

    problem = Problem.build(net, pinned=task.pinned, clamped=task.source_clamps(net))
    g = problem.gradient(held.positions)
    mu = -np.asarray(held.clamp_force)
    from continuum_vs_network.network.lagrangian import Frame

    frame = Frame(net, problem.free)
    A = frame.rows(net, held.positions, problem.clamp_springs, dense=True)
    force = frame.put(frame.take(g) + A.T @ mu).reshape(-1, 2)
    a, b, c = task.nodes[0], task.relative_to[0], task.coords[0]
    fa, fb = force[a, c], force[b, c]
    scale = np.abs(g).max()
    assert abs(fa) > 1e-3 * scale  # a real reaction holds the nodes apart
    assert fa + fb == pytest.approx(0.0, abs=1e-8 * scale)
    rest = force.copy()
    rest[a, c] = rest[b, c] = 0.0
    assert np.abs(rest).max() < 1e-8 * scale
    # grad E = load at equilibrium: the load on a pushes the output up (values above free)
    assert fa > 0


def test_gcl_on_a_relative_target_tends_to_minus_k_times_the_gradient(relative):
    net, task = relative
    free = _free(net, task)
    K = 1.0 / float(_compliance(net, task, free)[0, 0])
    grad = node_cost_gradient(net, task, free)
    want = -K * grad
    errs, cosines = [], []
    for eta in (1e-1, 1e-2, 1e-3):
        raw = CoupledLearning(1.0, eta).update(net, task).raw
        errs.append(np.linalg.norm(raw - want) / np.linalg.norm(want))
        cosines.append(-raw @ grad / np.linalg.norm(raw) / np.linalg.norm(grad))
    assert errs[-1] < 1e-3
    assert errs[1] < errs[0] / 5 and errs[2] < errs[1] / 5
    assert cosines[-1] > 1 - 1e-6


def test_a_small_gcl_step_lowers_the_relative_error(relative):
    # the sign of the rule: a small step along GCL's update descends C
    net, task = relative
    step = CoupledLearning(1e-3, 1e-2).update(net, task)
    before = task.error(net, _free(net, task).positions)
    moved = net.with_rest_length(net.rest_length + step.delta)
    after = task.error(moved, _free(moved, task).positions)
    assert after < before
    grad = node_cost_gradient(net, task, _free(net, task))
    assert after - before == pytest.approx(grad @ step.delta, rel=1e-2)


def test_a_relative_task_is_learned_through_the_sources():
    # GCL of the stiffnesses on a network at rest: no prestress, so meeting the task means
    # the sources now drive node a relative to node b by the desired displacement
    rng = np.random.default_rng([0, 5, 4, 0])
    net = triangular_lattice(5, 5, noise=0.1, rng=rng)
    task = node_task(
        net, rng, n_sources=3, n_targets=1, source_std=0.1, displacement_std=0.05, relative=True
    )
    off = task.with_source_strain(np.zeros(task.n_sources))
    miss = abs(task.outputs(_free(net, task).positions)[0] - task.desired[0])
    rule = CoupledLearning(1000.0, 0.1, dof="stiffness", min_stiffness=0.1)
    h = train(net, task, rule, 100, progress=False)
    assert h.completed[0] == 100, h.stop_reason
    assert h.error_initial[0, -1] < 1e-4 * h.error_initial[0, 0]
    trained = h.final[0]
    moved = task.outputs(_free(trained, task).positions) - task.reference
    assert moved == pytest.approx(task.displacement, abs=1e-2 * miss)
    # node a alone moves by something else: the output is the relative displacement
    a, c = task.nodes[0], task.coords[0]
    alone = _free(trained, task).positions[a, c] - net.positions[a, c]
    assert abs(alone - task.displacement[0]) > 0.1 * abs(task.displacement[0])
    from continuum_vs_network.learning.coupling import coupling_verdict, source_share

    share = source_share(
        moved,
        task.outputs(_free(trained, off).positions) - task.reference,
        task.outputs(_free(net, off).positions) - task.reference,
        task.outputs(_free(net, task).positions) - task.reference,
    )
    assert coupling_verdict(share) == "coupled" and share > 0.99


def test_an_anchored_node_task_trains_as_two_examples(relative, tmp_path):
    net, task = relative
    pair = anchored(task, net)
    assert isinstance(pair, TaskSet) and pair.node_outputs and pair.n_examples == 2
    rest = pair.tasks[1]
    # the rest example asks for the outputs of the untrained network with the sources off
    assert rest.error(net, _free(net, rest).positions) < 1e-20
    h = train(net, pair, CoupledLearning(0.5, 0.1), 5, progress=False)
    assert h.completed[0] == 5, h.stop_reason
    assert h.error_initial[0, -1] < h.error_initial[0, 0]
    assert h.target_strain.shape[-1] == 2
    back = History.load(h.save(tmp_path / "pair.npz"))
    assert np.array_equal(back.tasks[0].tasks[0].relative_to, task.relative_to)


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
    with pytest.raises(ValueError, match="own node"):
        NodeTask.create(net, task.sources, 0.1, [10], [0], 0.1, relative_to=[10])
    with pytest.raises(ValueError, match="relative_to"):
        NodeTask.create(net, task.sources, 0.1, [10], [0], 0.1, relative_to=[net.n_nodes])
    with pytest.raises(ValueError, match="temperature"):
        CoupledLearning(0.5, 0.1).update(
            net, anchored(task, net), temperature=1e-6, rng=np.random.default_rng(0)
        )


def test_a_load_needs_the_chord_path(relative):
    net, task = relative
    load = np.zeros((net.n_nodes, 2))
    with pytest.raises(ValueError, match="external loads"):
        Tracker(Solver(reuse=False)).solve(
            net, task.pinned, task.source_clamps(net), net.positions, load=load
        )


def test_a_small_load_moves_the_network_by_its_compliance(relative):
    # Tracker.solve with a load: x - x_free -> H^-1 f for small f (linear response)
    net, task = relative
    free = _free(net, task)
    f = np.zeros((net.n_nodes, 2))
    f[task.nodes[0], task.coords[0]] = 1e-6
    loaded = Tracker(Solver()).solve(
        net, task.pinned, task.source_clamps(net), free.positions, load=f
    )
    sens = Sensitivity(net, task.pinned, task.source_clamps(net), free)
    v, _ = sens.solve(f)
    d = np.asarray(loaded.positions) - free.positions
    assert np.linalg.norm(d - v) < 1e-4 * np.linalg.norm(v)
