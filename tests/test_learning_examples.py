"""Several examples at once (TaskSet): the summed update, the summed error, symmetric,
anchored."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    History,
    TaskSet,
    anchored,
    cost_gradient,
    examples_task,
    gain_examples,
    stern_task,
    symmetric,
    train,
)
from continuum_vs_network.network.builders import triangular_lattice


@pytest.fixture(scope="module")
def lattice():
    rng = np.random.default_rng(5)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    return net, examples_task(net, 3, rng)


def _free(net, task):
    return cvn.relax(net, pinned=task.pinned, clamped=task.source_clamps(net))


def test_exact_gradient_of_a_set_is_the_gradient_of_the_summed_error(lattice):
    net, tasks = lattice
    step = ExactGradient(1.0).update(net, tasks)
    frees = [_free(net, t) for t in tasks.tasks]
    summed = sum(cost_gradient(net, t, f) for t, f in zip(tasks.tasks, frees))
    mask = ExactGradient(1.0).learning_mask(net, tasks)
    assert not mask[tasks.sources].any() and not mask[tasks.targets].any()
    assert np.allclose(step.delta, np.where(mask, -summed, 0.0), rtol=1e-6, atol=1e-12)
    # finite difference of C = sum_e C_e along the step
    h = 1e-6
    new = net.with_rest_length(net.rest_length + h * step.delta)
    c0 = tasks.error(net, [f.positions for f in frees])
    c1 = tasks.error(new, [_free(new, t).positions for t in tasks.tasks])
    assert (c1 - c0) / h == pytest.approx(summed @ step.delta, rel=1e-3)


def test_train_records_the_summed_error_and_every_examples_targets(lattice, tmp_path):
    net, tasks = lattice
    h = train(net, tasks, CoupledLearning(0.3, 0.1), 6, progress=False)
    c0 = sum(t.error(net, _free(net, t).positions) for t in tasks.tasks)
    assert h.error_initial[0, 0] == pytest.approx(c0, rel=1e-9)
    assert h.target_strain.shape == (1, 7, tasks.n_targets)
    assert h.error_initial[0, -1] < h.error_initial[0, 0]
    back = History.load(h.save(tmp_path / "h.npz"))
    assert isinstance(back.tasks[0], TaskSet) and back.tasks[0].n_examples == 3
    assert np.array_equal(back.tasks[0].targets, tasks.targets)
    # a resumed run gives the uninterrupted history (warm starts of every example saved)
    ck = tmp_path / "ck.npz"
    train(net, tasks, CoupledLearning(0.3, 0.1), 4, progress=False, checkpoint=ck,
          checkpoint_every=2)  # fmt: skip
    ck.unlink()
    full = train(net, tasks, CoupledLearning(0.3, 0.1), 6, progress=False)
    assert np.allclose(full.error_initial, h.error_initial, rtol=1e-8)


def test_checkpoint_resume_with_examples(lattice, tmp_path):
    net, tasks = lattice
    rule = CoupledLearning(0.3, 0.1)
    ref = train(net, tasks, rule, 6, progress=False)
    ck = tmp_path / "ck.npz"

    class Stop(Exception):
        pass

    def stop(trial, step, cur):
        if step == 4:
            raise Stop

    with pytest.raises(Stop):
        train(net, tasks, rule, 6, progress=False, checkpoint=ck, checkpoint_every=2,
              callback=stop)  # fmt: skip
    again = train(net, tasks, rule, 6, progress=False, checkpoint=ck, checkpoint_every=2)
    assert np.allclose(again.error_initial, ref.error_initial, rtol=1e-8, atol=1e-14)


def test_symmetric_exchanges_sources_and_targets_and_learns_both_ways():
    rng = np.random.default_rng(2)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    task = stern_task(net, 1, 1, rng)
    pair = symmetric(task)
    back = pair.tasks[1]
    assert np.array_equal(back.sources, task.targets) and np.array_equal(back.targets, task.sources)
    assert np.allclose(back.source_strain, task.target_strain)
    assert np.allclose(back.source_lengths(net), task.desired_lengths(net))
    h = train(net, pair, CoupledLearning(0.3, 0.1), 60, progress=False)
    c0 = h.error_initial[0, 0]
    assert h.error_initial[0, -1] < 1e-2 * c0
    final = h.final[0]
    for t in pair.tasks:  # both directions are met, not one at the other's expense
        assert t.error(final, _free(final, t).positions) < 1e-3 * c0


def _stern_lattice(seed: int):
    from continuum_vs_network.scenes.stern import stern_network

    rng = np.random.default_rng(seed)
    net = stern_network(64, rng)
    return net, stern_task(net, 4, 2, rng, candidates=np.ones(net.n_springs, dtype=bool))


def test_anchored_rest_example_asks_for_the_initial_strains():
    net, task = _stern_lattice(0)
    # prestress the network (rest lengths off the geometry) so "at rest" is not zero strain
    L = net.rest_length * np.random.default_rng(9).uniform(0.95, 1.05, net.n_springs)
    pre = net.with_rest_length(L)
    for network, label in ((net, "stress-free"), (pre, "prestressed")):
        pair = anchored(task, network)
        assert pair.n_examples == 2 and pair.tasks[0] is task
        rest = pair.tasks[1]
        assert np.array_equal(rest.sources, task.sources)
        assert np.array_equal(rest.targets, task.targets)
        assert np.all(rest.source_strain == 0.0)
        # sources clamped at their reference rest lengths, relaxed independently
        clamps = task.with_source_strain(np.zeros(task.n_sources)).source_clamps(network)
        x = cvn.relax(network, pinned=task.pinned, clamped=clamps).positions
        S = network.lengths(x)[task.targets] / task.target_rest_length - 1.0
        assert np.allclose(rest.target_strain, S, atol=1e-8), label
        # the untrained network meets the rest example: no error with the sources off
        assert rest.error(network, x) < 1e-14
    assert np.allclose(anchored(task, net).tasks[1].target_strain, 0.0, atol=1e-8)
    assert np.abs(anchored(task, pre).tasks[1].target_strain).max() > 1e-3
    with pytest.raises(ValueError, match="task"):
        anchored(pair, net)
    with pytest.raises(ValueError, match="strain_reference"):
        anchored(task, net, strain_reference="rest")


def test_anchored_penalises_the_trivial_solution():
    net, task = _stern_lattice(0)
    pair = anchored(task, net)
    # the trivial solution: each target's rest length at its goal, 1e4 times stiffer
    L, k = net.rest_length.copy(), net.stiffness.copy()
    L[task.targets] = task.desired_lengths(net)
    k[task.targets] *= 1e4
    trivial = net.with_rest_length(L).with_stiffness(k)
    xs = [_free(trivial, t).positions for t in pair.tasks]
    # targets that sit at their goals whatever the sources do miss the rest example by C0
    c0 = 0.5 * float(np.sum(task.target_strain**2))
    assert pair.tasks[0].error(trivial, xs[0]) < 1e-4 * c0
    assert pair.error(trivial, xs) > 0.9 * c0
    assert pair.tasks[1].error(trivial, xs[1]) == pytest.approx(c0, rel=0.05)


def test_gcl_descends_an_anchored_task():
    net, task = _stern_lattice(1)
    pair = anchored(task, net)
    h = train(net, pair, CoupledLearning(0.5, 0.1, min_rest_length=1e-3), 30, progress=False)
    e = h.error_initial[0]
    assert np.all(np.isfinite(e)) and e[-1] < 0.7 * e[0]
    assert np.all(np.diff(e) <= 1e-3 * e[0])  # descends, up to solver round-off
    # both examples are recorded: 2 task targets, then the rest example's 2
    assert h.target_strain.shape[-1] == 4


def test_examples_task_springs_and_bad_input():
    rng = np.random.default_rng(0)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    distinct = examples_task(net, 4, rng, n_sources=1, n_targets=2)
    springs = np.concatenate([distinct.sources, distinct.targets])
    assert np.unique(springs).size == springs.size == 12
    shared = examples_task(net, 4, rng, shared_springs=True)
    assert np.unique(shared.sources).size == 1
    with pytest.raises(ValueError, match="n_examples"):
        examples_task(net, 0, rng)
    with pytest.raises(ValueError, match="candidate springs"):
        examples_task(net, 1000, rng)
    with pytest.raises(ValueError, match="tasks"):
        TaskSet(())


def test_scene_key_anchored_trains_the_task_with_its_rest_example():
    from continuum_vs_network.scenes import SceneError, parse_scene
    from continuum_vs_network.scenes.units_learning import builders, task_example

    data = {
        "name": "s",
        "description": "d",
        "kind": "learning",
        "network": {"builder": "triangular", "n_nodes": 64},
        "task": {"kind": "stern", "n_sources": 4, "n_targets": 2, "anchored": True},
        "learning": {"rules": ["gcl"], "trials": 1, "steps": 2},
    }
    make_net, make_task = builders(parse_scene(data, "s.toml"))
    rng = np.random.default_rng(0)
    net = make_net(rng)
    pair = make_task(net, rng)
    assert isinstance(pair, TaskSet) and pair.n_examples == 2
    assert np.all(pair.tasks[1].source_strain == 0.0)
    assert task_example(pair) is pair.tasks[0]
    data["task"]["anchored"] = "yes"
    with pytest.raises(SceneError, match="anchored"):
        parse_scene(data, "s.toml")


def test_regression_learned_on_few_examples_predicts_a_held_out_example():
    from continuum_vs_network.learning import regression_task

    rng = np.random.default_rng(4)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    train_set, test_set, gain_map = regression_task(net, 4, 3, rng, gain=0.5)
    assert gain_map.shape == (1, 2)
    for t in train_set.tasks + test_set.tasks:  # the desired strains are the map's output
        assert np.allclose(t.target_strain, gain_map @ t.source_strain)
    assert len({tuple(t.sources) for t in train_set.tasks + test_set.tasks}) == 1

    def test_error(network):
        return test_set.error(network, [_free(network, t).positions for t in test_set.tasks])

    # the slope of a linear response is set by the stiffnesses (rest lengths change it
    # only through prestress, at second order): learn k
    rule = CoupledLearning(100.0, 0.1, dof="stiffness", min_stiffness=0.3)
    h = train(net, train_set, rule, 150, progress=False)
    train_ratio = h.error_initial[0, -1] / h.error_initial[0, 0]
    test_ratio = test_error(h.final[0]) / test_error(net)
    assert train_ratio < 0.8 and test_ratio < 0.8
    with pytest.raises(ValueError, match="n_test"):
        regression_task(net, 2, 0, rng)


def test_gain_examples_ask_each_response_to_change_by_the_fraction(lattice):
    net, tasks = lattice
    changed = gain_examples(tasks, net, np.random.default_rng(0), change=0.5)
    assert changed.n_examples == tasks.n_examples
    for old, new in zip(tasks.tasks, changed.tasks):
        assert np.array_equal(old.sources, new.sources)
        r0 = net.lengths(_free(net, old).positions)[old.targets]
        s0 = old.target_strains(net, r0)
        # desired = S0 (1 +- 0.5): the untrained error is (0.5 S0)^2 / 2, whatever the sign
        assert np.allclose(np.abs(new.target_strain - s0), 0.5 * np.abs(s0), rtol=1e-9)
        assert new.error(net, _free(net, new).positions) == pytest.approx(
            0.5 * np.sum((0.5 * s0) ** 2), rel=1e-6
        )
    with pytest.raises(ValueError, match="change"):
        gain_examples(tasks, net, np.random.default_rng(0), change=0.0)
