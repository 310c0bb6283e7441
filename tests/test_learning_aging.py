"""Directed aging: sign, relation to the clamped-energy gradient, equality with GPC."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import DirectedAging, ProspectiveConfiguration, stern_task, train
from continuum_vs_network.network.builders import triangular_lattice


@pytest.fixture(scope="module")
def lattice():
    rng = np.random.default_rng(3)
    net = triangular_lattice(6, 6, noise=0.1, rng=rng)
    return net, stern_task(net, 3, 2, rng)


def _clamped_energy(net, task, x0):
    clamps = task.source_clamps(net)
    clamps.update(zip(task.targets.tolist(), task.desired_lengths(net).tolist()))
    return cvn.relax(net, pinned=task.pinned, clamped=clamps, x0=x0).energy


@pytest.mark.parametrize("dof", ["rest_length", "stiffness"])
def test_aging_descends_the_clamped_energy_along_its_weighted_gradient(lattice, dof):
    net, task = lattice
    net = net.with_stiffness(np.random.default_rng(0).uniform(0.5, 2.0, net.n_springs))
    step = DirectedAging(1e-4, dof=dof).update(net, task)
    x, k, L = step.clamped.positions, net.stiffness, net.rest_length
    dr = net.lengths(x) - L
    grad = -k * dr if dof == "rest_length" else 0.5 * dr**2  # dE^C/dtheta
    weight = 1.0 / k if dof == "rest_length" else k / L**2
    mask = step.delta != 0
    assert mask.sum() > 0.8 * net.n_springs
    assert np.allclose(step.delta[mask], -1e-4 * weight[mask] * grad[mask], rtol=1e-12)
    # first order: the clamped energy falls by |grad|_w^2 (envelope theorem)
    e0 = step.clamped.energy
    e1 = _clamped_energy(step.apply(net), task, x)
    assert e1 < e0
    assert e1 - e0 == pytest.approx(grad @ step.delta, rel=1e-2)
    flipped = type(step)(delta=-step.delta, dof=dof, free=None, clamped=step.clamped)
    assert _clamped_energy(flipped.apply(net), task, x) > e0


def test_rest_length_aging_with_uniform_k_is_gpc_up_to_the_rate(lattice):
    net, task = lattice
    k = 2.5
    net = net.with_stiffness(np.full(net.n_springs, k))
    a = DirectedAging(0.02).update(net, task).delta
    b = ProspectiveConfiguration(0.02 / k).update(net, task).delta
    assert np.abs(a).max() > 1e-4
    assert np.allclose(a, b, rtol=1e-12, atol=1e-15)
    # with non-uniform k they differ by the k weighting, spring by spring
    net2 = net.with_stiffness(np.linspace(0.5, 2.0, net.n_springs))
    a2 = DirectedAging(0.02).update(net2, task).delta
    b2 = ProspectiveConfiguration(0.02).update(net2, task).delta
    on = np.abs(a2) > 1e-12
    assert np.allclose(b2[on] / a2[on], net2.stiffness[on])


def test_aging_trains_through_train_and_lowers_the_task_error(lattice):
    net, task = lattice
    # aging relaxes the learning springs' stress in the clamped state (a fixed point where
    # they hold the imposed strains) and lowers the task error on the way, but (sources and
    # targets frozen) it stops at a floor: the free state does not follow the clamped one
    h = train(net, task, DirectedAging(0.3), 40, progress=False)
    assert h.completed[0] == 40
    g = h.energy_gradient_clamped[0]
    assert g[-1] < 1e-6 * g[0]
    e = h.error_initial[0]
    assert e[-1] < 0.8 * e[0]
    assert e[-1] > 1e-3 * e[0]
    assert h.settings["rule"] == "DirectedAging"


def test_aging_rejects_a_bad_rate():
    with pytest.raises(ValueError, match="alpha"):
        DirectedAging(-1.0)


# -- joint learning of rest lengths and stiffnesses (dof="both") ----------------------------
@pytest.mark.parametrize(
    "make",
    [
        lambda dof: DirectedAging(1e-3, dof=dof),
        lambda dof: ProspectiveConfiguration(1e-3, dof=dof),
        lambda dof: cvn.CoupledLearning(1e-3, 1e-2, dof=dof),
        lambda dof: cvn.ExactGradient(1e-3, dof=dof),
    ],
)
def test_joint_update_stacks_the_rest_length_and_stiffness_updates(lattice, make):
    net, task = lattice
    both = make("both").update(net, task).delta
    assert both.shape == (2, net.n_springs)
    for row, dof in zip(both, ("rest_length", "stiffness")):
        assert np.allclose(row, make(dof).update(net, task).delta, rtol=1e-9, atol=1e-15)


def test_joint_exact_step_descends_along_the_full_gradient(lattice):
    net, task = lattice
    step = cvn.ExactGradient(1e-4, dof="both").update(net, task)
    new = step.apply(net)
    assert np.allclose(new.rest_length - net.rest_length, step.delta[0])
    assert np.allclose(new.stiffness - net.stiffness, step.delta[1])

    def error(n):
        return task.error(
            n, cvn.relax(n, pinned=task.pinned, clamped=task.source_clamps(n)).positions
        )

    c0, c1 = error(net), error(new)
    # first order: C falls by |grad|^2 alpha over both kinds of parameters together
    assert c1 - c0 == pytest.approx(-np.sum(step.delta**2) / 1e-4, rel=1e-2)


def test_joint_training_runs_through_train_and_learns_faster_than_k_alone(lattice):
    net, task = lattice
    h = train(net, task, cvn.CoupledLearning(0.3, 0.1, dof="both"), 30, progress=False)
    k_only = train(net, task, cvn.CoupledLearning(0.3, 0.1, dof="stiffness"), 30, progress=False)
    assert h.completed[0] == 30 and h.settings["dof"] == "both"
    assert h.error_initial[0, -1] < 0.1 * h.error_initial[0, 0]
    assert h.error_initial[0, -1] < k_only.error_initial[0, -1]
    assert np.any(h.final[0].stiffness != net.stiffness)
    assert np.any(h.final[0].rest_length != net.rest_length)
