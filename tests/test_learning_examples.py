"""Several examples at once (TaskSet): the summed update, the summed error, symmetric."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    History,
    TaskSet,
    cost_gradient,
    examples_task,
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
