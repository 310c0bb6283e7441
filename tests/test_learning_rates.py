"""Scale-free rates, the physical stiffness range and the field's allosteric task."""

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    DirectedAging,
    ExactGradient,
    ProspectiveConfiguration,
    anchored,
    measure_coupling,
    train,
)
from continuum_vs_network.learning.allostery import allostery_task, spring_distances
from continuum_vs_network.learning.ranges import STIFFNESS_RANGE
from continuum_vs_network.learning.rates import NOISE, Adaptive, RateState, Scaled


def _raw(seed: int, n: int = 50) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=n) * np.logspace(-2, 2, n)


def test_adaptive_first_step_is_the_sign_and_does_not_depend_on_the_raw_scale():
    raw = _raw(0)
    rate = Adaptive(step=0.05)
    start = RateState.start(np.ones_like(raw))
    one, state = rate.delta(raw, np.array([2.0]), start)
    # Adam's bias-corrected first step is step * scale * sign(raw), softened by the round-off
    # floor (NOISE of the largest): raw / (|raw| + NOISE max|raw|)
    sign = raw / (np.abs(raw) + NOISE * np.max(np.abs(raw)))
    np.testing.assert_allclose(one, 0.05 * 2.0 * sign, rtol=1e-12)
    scaled, _ = rate.delta(1e7 * raw, np.array([2.0]), start)
    np.testing.assert_allclose(scaled, one, rtol=1e-12)
    # a spring whose update changes sign is damped: m averages out while v stays
    two, _ = rate.delta(-raw, np.array([2.0]), state)
    assert np.all(np.abs(two) < 0.05 * 2.0 * 0.6)


def test_scaled_rate_fixes_its_gain_at_the_first_step():
    raw = _raw(1)
    rate = Scaled(step=0.02)
    first, state = rate.delta(raw, np.array([3.0]), RateState.start(np.ones_like(raw)))
    assert np.max(np.abs(first)) == pytest.approx(0.02 * 3.0, rel=1e-12)
    second, _ = rate.delta(0.5 * raw, np.array([3.0]), state)
    np.testing.assert_allclose(second, 0.5 * first, rtol=1e-12)  # a fixed rate: linear


def test_rate_options_are_checked():
    with pytest.raises(ValueError, match="not both"):
        CoupledLearning(0.1, 0.1, rate=Adaptive())
    with pytest.raises(ValueError, match="rate"):
        CoupledLearning(rate="adam")
    with pytest.raises(ValueError, match="stiffness_range"):
        ExactGradient(stiffness_range=(2.0, 3.0))
    with pytest.raises(ValueError, match="step"):
        Adaptive(step=0.0)
    assert CoupledLearning().adaptive == Adaptive()
    assert ProspectiveConfiguration().adaptive == Scaled()
    assert DirectedAging().adaptive == Scaled()
    assert ExactGradient(0.3).adaptive is None  # the raw rate as printed


def test_raw_rate_update_is_alpha_times_the_adaptive_free_line():
    # the raw line does not depend on the rate; the raw step is alpha times it
    net = cvn.paper_network(np.random.default_rng(2))
    task = cvn.paper_task(net, np.random.default_rng(3))
    raw = CoupledLearning(0.01, 0.1, dof="stiffness", stiffness_range=None).update(net, task)
    free = CoupledLearning(eta=0.1, dof="stiffness").update(net, task)
    np.testing.assert_allclose(raw.raw, 0.01 * free.raw, rtol=1e-10, atol=1e-14)
    bulk = CoupledLearning(eta=0.1).learning_mask(net, task)
    np.testing.assert_allclose(raw.delta, np.where(bulk, raw.raw, 0.0), rtol=1e-12, atol=0)


@pytest.fixture(scope="module")
def jammed():
    rng = np.random.default_rng(12)  # a draw the bounded optimum solves (89 nodes)
    net = cvn.jammed_network(120, rng, phi=0.86)
    task = allostery_task(net, rng, ratio=0.3, distance=0.3)
    return net, task


def test_allostery_task_asks_for_a_response_ratio_at_a_distance(jammed):
    net, task = jammed
    assert task.target_strain[0] == pytest.approx(0.3 * task.source_strain[0])
    d = spring_distances(net, task.sources)[task.targets[0]]
    assert abs(d - 0.3) <= 0.1 * 0.3 + 0.05  # in the band, or the nearest spring to it
    many = allostery_task(net, np.random.default_rng(1), n_sources=4, n_targets=2, ratio=-0.5)
    np.testing.assert_allclose(np.abs(many.target_strain), 0.5 * 0.05)
    with pytest.raises(ValueError, match="ratio"):
        allostery_task(net, np.random.default_rng(1), ratio=0.0)


def test_default_coupled_learning_learns_a_response_within_the_stiffness_range(jammed):
    net, task = jammed
    tasks = anchored(task, net)
    h = train(net, tasks, CoupledLearning(dof="stiffness"), 300, progress=False)
    c = h.data["error_initial"][0]
    assert h.completed[0] == 300
    assert c[-1] <= 1e-2 * c[0]  # learned: two decades, nothing tuned
    k0, k = net.stiffness, h.final[0].stiffness
    lo, hi = STIFFNESS_RANGE
    assert np.all(k >= lo * k0 * (1 - 1e-12)) and np.all(k <= hi * k0 * (1 + 1e-12))
    coupling = measure_coupling(net, h.final[0], task)
    assert coupling.verdict == "coupled"  # the target follows the source, not prestress


def test_adaptive_state_survives_a_checkpoint(tmp_path, jammed):
    net, task = jammed
    tasks = anchored(task, net)
    rule = ExactGradient(dof="stiffness")
    full = train(net, tasks, rule, 12, progress=False)

    class Killed(Exception):
        pass

    def kill(trial, step, cur):
        if step == 7:
            raise Killed

    path = tmp_path / "run.npz"
    with pytest.raises(Killed):
        train(net, tasks, rule, 12, progress=False, checkpoint=path, checkpoint_every=5,
              callback=kill)  # fmt: skip
    resumed = train(net, tasks, rule, 12, progress=False, checkpoint=path, checkpoint_every=5)
    # equal up to the solver tolerance (Newton is not bitwise reproducible; a restart without
    # the saved running averages would differ by whole steps, ~5e-2 of k)
    np.testing.assert_allclose(
        resumed.final[0].stiffness, full.final[0].stiffness, rtol=1e-5, atol=0
    )
