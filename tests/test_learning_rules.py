"""Learning rules: signs, the eta -> 0 limit of coupled learning, exact gradients."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    LearningError,
    ProspectiveConfiguration,
    Sensitivity,
    Solver,
    Tracker,
    cost_gradient,
    gcl_limit,
    paper_task,
    stern_task,
    train,
)
from continuum_vs_network.learning.metrics import cosine, relative_error, source_sweep
from continuum_vs_network.network.builders import paper_network, triangular_lattice


def _paper(seed: int = 0):
    rng = np.random.default_rng(seed)
    net = paper_network(rng)
    return net, paper_task(net, rng)


@pytest.fixture(scope="module")
def paper():
    return _paper(0)


def _error_after(net, task, step, reference):
    new = step.apply(net)
    eq = cvn.relax(
        new, pinned=task.pinned, clamped=task.source_clamps(new, reference), x0=step.free.positions
    )
    return task.error(new, eq.positions, reference)


@pytest.mark.parametrize("dof", ["rest_length", "stiffness"])
def test_one_small_gcl_step_lowers_the_error_and_the_flipped_sign_raises_it(paper, dof):
    # dL = +(alpha/eta) k (r^C - r^F) descends E^C - E^F; Eq. 14's second line flips it
    net, task = paper
    rule = CoupledLearning(1e-6, 1e-3, dof=dof, strain_reference="initial")
    step = rule.update(net, task)
    c0 = task.error(net, step.free.positions, "initial")
    c_rule = _error_after(net, task, step, "initial")
    flipped = type(step)(delta=-step.delta, dof=dof, free=step.free, clamped=step.clamped)
    c_flip = _error_after(net, task, flipped, "initial")
    assert c_rule < c0 < c_flip
    # first order: the decrease matches the exact gradient's directional derivative
    grad = cost_gradient(net, task, step.free, strain_reference="initial", dof=dof)
    assert (c_rule - c0) == pytest.approx(grad @ step.delta, rel=0.05)


def test_gcl_update_converges_to_the_exact_gradient_as_eta_shrinks(paper):
    # initial-L strains: C is a length cost, and GCL/alpha -> -K L0^2 dC/dL, K the
    # target's effective stiffness (an independent KKT compliance solve)
    net, task = paper
    errors, cosines = [], []
    for eta in (1e-1, 1e-2, 1e-3, 1e-4):
        step = CoupledLearning(1.0, eta, strain_reference="initial").update(net, task)
        grad = cost_gradient(net, task, step.free, strain_reference="initial")
        sens = Sensitivity(net, task.pinned, task.source_clamps(net, "initial"), step.free)
        stiffness = 1.0 / sens.compliance(task.targets)[0, 0]
        reference = -stiffness * task.target_rest_length[0] ** 2 * grad
        errors.append(relative_error(step.raw, reference))
        cosines.append(cosine(step.raw, reference))
    errors = np.array(errors)
    # first order in eta: each decade of eta gains about a decade of accuracy
    assert np.all(errors[1:] / errors[:-1] < 0.2)
    assert errors[-1] < 1e-3
    assert min(cosines[1:]) > 0.9999


def test_gcl_with_learning_reference_descends_a_frozen_length_cost_not_eq_26(paper):
    # paper's convention: clamp lengths L(S + 1) move with L, GCL holds them fixed
    net, task = paper
    step = CoupledLearning(1.0, 1e-4, strain_reference="current").update(net, task)
    limit, _ = gcl_limit(net, task, step.free, strain_reference="current")
    assert relative_error(step.raw, limit) < 1e-3
    true_grad = cost_gradient(net, task, step.free, strain_reference="current")
    assert cosine(step.raw, -true_grad) < 0.9  # not a descent direction of Eq. 26 here


@pytest.mark.parametrize("dof", ["rest_length", "stiffness"])
@pytest.mark.parametrize("reference", ["current", "initial"])
def test_exact_gradient_matches_finite_differences(paper, dof, reference):
    net, task = paper
    free = Tracker().solve(net, task.pinned, task.source_clamps(net, reference), None)
    grad = cost_gradient(net, task, free, strain_reference=reference, dof=dof)
    theta = net.rest_length if dof == "rest_length" else net.stiffness

    def error(values):
        n = net.with_rest_length(values) if dof == "rest_length" else net.with_stiffness(values)
        eq = cvn.relax(
            n,
            pinned=task.pinned,
            clamped=task.source_clamps(n, reference),
            x0=free.positions,
            tol=1e-13,
        )
        return task.error(n, eq.positions, reference)

    h = 1e-5 * float(np.mean(theta))
    fd = np.array(
        [(error(theta + h * e) - error(theta - h * e)) / (2 * h) for e in np.eye(net.n_springs)]
    )
    rel = np.abs(grad - fd) / np.max(np.abs(fd))
    assert np.median(rel) < 1e-7
    assert np.max(rel) < 1e-5


def test_exact_gradient_step_lowers_eq_26(paper):
    net, task = paper
    step = ExactGradient(1e-3).update(net, task)
    c0 = task.error(net, step.free.positions, "current")
    assert _error_after(net, task, step, "current") < c0


def test_gpc_moves_the_target_rest_length_to_its_clamped_length(paper):
    net, task = paper
    rule = ProspectiveConfiguration(2e-3, strain_reference="initial", learn_targets=True)
    tracker = Tracker(rule.solver)
    step = rule.update(net, task, tracker=tracker)
    desired = task.desired_lengths(net, "initial")[0]
    t = task.targets[0]
    gap0 = abs(net.rest_length[t] - desired)
    for _ in range(100):
        net = step.apply(net)
        step = rule.update(net, task, warm=step.warm, tracker=tracker)
    # the target is clamped at its desired length, so dL_T = alpha k_T (l_T - L_T)
    assert step.clamped.positions is not None
    assert abs(net.rest_length[t] - desired) < 1e-2 * gap0


def test_learning_steps_with_float32_factorisations_match_float64_relax(monkeypatch):
    """The chord iteration and Newton need only an approximate W^-1: with every
    factorisation rough (float32 SuperLU, as above ROUGH_MIN rows) the learning steps equal
    those of relax with float64 factorisations to its tolerance, and the chord still
    finds the states (no relax after the first step)."""
    from continuum_vs_network.learning.tasks import stern_task
    from continuum_vs_network.linalg import spd
    from continuum_vs_network.scenes.stern import stern_network, stern_rules

    monkeypatch.setattr(spd, "BAND_MAX_WORK", 0)  # SuperLU, not the banded Cholesky
    made = []
    superlu = spd.sparse_lu

    def spy(W, **kw):
        made.append(W.dtype == np.float32)
        return superlu(W, **kw)

    monkeypatch.setattr(spd, "sparse_lu", spy)
    # SuperLU: the tracker's relax and chord factorise with sparse_solver="auto", which is
    # SuperLU where pypardiso does not import (relax takes no sparse_solver yet)
    monkeypatch.setattr(spd, "_pardiso", lambda: None)
    rng = np.random.default_rng(2)
    net = stern_network(400, rng)
    task = stern_task(net, 4, 2, rng, candidates=np.ones(net.n_springs, dtype=bool))
    rule = stern_rules(alpha=0.5, eta=0.1)["GCL"]
    fast, slow = Tracker(rule.solver), Tracker(replace(rule.solver, reuse=False))

    def update(tracker, rough_min, **kw):
        monkeypatch.setattr(spd, "ROUGH_MIN", rough_min)
        return rule.update(net, task, tracker=tracker, **kw)

    step_f, step_s = update(fast, 0), update(slow, 10**9)
    relaxed = fast.stats.relax_calls
    for _ in range(6):
        # both states to relax's tolerance: 3e-7 of the largest change at most here
        gap = np.max(np.abs(step_f.delta - step_s.delta))
        assert gap <= 1e-6 * np.max(np.abs(step_s.delta))
        net = step_s.apply(net)
        step_f = update(fast, 0, warm=step_f.warm)
        step_s = update(slow, 10**9, warm=step_s.warm)
    assert fast.stats.relax_calls == relaxed
    assert sum(made) >= fast.stats.factorisations >= 1  # float32 ones


def test_the_tracker_keeps_one_factorisation_alive_per_key(superlu_lifetimes):
    """A key's old factorisation is released before its next is made: GCL steps that
    refactorise at every chance (refactor_ratio 0.01) never hold two."""
    from continuum_vs_network.learning.tasks import stern_task
    from continuum_vs_network.scenes.stern import stern_network, stern_rules

    rng = np.random.default_rng(2)
    net = stern_network(400, rng)
    task = stern_task(net, 4, 2, rng, candidates=np.ones(net.n_springs, dtype=bool))
    rule = stern_rules(alpha=5.0, eta=0.1)["GCL"]
    tracker = Tracker(replace(rule.solver, refactor_ratio=0.01))
    step = rule.update(net, task, tracker=tracker)
    for _ in range(10):
        net = step.apply(net)
        step = rule.update(net, task, warm=step.warm, tracker=tracker)
    assert tracker.stats.factorisations >= 5 and list(tracker._lin) == ["free"]
    assert superlu_lifetimes.most == 1


def test_masks_and_floors():
    net, task = _paper(1)
    s, t = task.sources[0], task.targets[0]
    step = CoupledLearning(1e-3, 0.1, learn_sources=False, learn_targets=False).update(net, task)
    assert step.delta[s] == 0 and step.delta[t] == 0 and np.any(step.delta != 0)
    # a step far too large: some raw rest lengths go negative
    huge = ProspectiveConfiguration(10.0, strain_reference="initial")
    step = huge.update(net, task)
    assert np.any(net.rest_length + step.raw <= 0)
    with pytest.raises(LearningError, match="min_rest_length"):
        step.apply(net)
    floored = ProspectiveConfiguration(10.0, strain_reference="initial", min_rest_length=0.5)
    new = floored.update(net, task).apply(net)
    floor = np.minimum(net.rest_length, 0.5)
    assert np.all(new.rest_length >= floor) and np.any(new.rest_length == floor)


def test_read_out_noise_is_seeded_and_scales_with_sigma(paper):
    net, task = paper
    rule = CoupledLearning(1e-3, 0.1, strain_reference="initial")
    clean = rule.update(net, task).delta
    a = rule.update(net, task, noise=1e-4, rng=np.random.default_rng(5)).delta
    b = rule.update(net, task, noise=1e-4, rng=np.random.default_rng(5)).delta
    c = rule.update(net, task, noise=1e-3, rng=np.random.default_rng(5)).delta
    # same seed, same noise (up to the solver tolerance: the core's Newton budgets its
    # solves by measured time, so its iterates are not bitwise reproducible)
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9 * np.max(np.abs(a)))
    # GCL divides the read-out difference by eta: noise enters amplified ~ 1/eta
    assert 5 < np.linalg.norm(c - clean) / np.linalg.norm(a - clean) < 20
    with pytest.raises(ValueError, match="rng"):
        rule.update(net, task, noise=1e-3)


def test_chord_tracker_matches_relax_along_a_run(paper):
    net, task = paper
    rule = CoupledLearning(1e-5, 0.05, strain_reference="initial")
    fast, slow = Tracker(Solver()), Tracker(Solver(reuse=False))
    step_f = rule.update(net, task, tracker=fast)
    step_s = rule.update(net, task, tracker=slow)
    for _ in range(10):
        np.testing.assert_allclose(step_f.delta, step_s.delta, rtol=1e-6, atol=1e-9)
        net = step_s.apply(net)
        step_f = rule.update(net, task, warm=step_f.warm, tracker=fast)
        step_s = rule.update(net, task, warm=step_s.warm, tracker=slow)
    # 22 states; the chord iteration finds nearly all (the paper's nudges are large, so
    # it refactors: about two factorisations per state here)
    assert fast.stats.relax_calls <= 2


def test_factorisations_are_reused_across_states_and_steps_at_small_strain():
    rng = np.random.default_rng(2)
    net = triangular_lattice(8, 8, noise=0.05, rng=rng)
    task = stern_task(net, 4, 2, rng)
    rule = CoupledLearning(0.05, 0.1, strain_reference="initial")
    tracker = Tracker(rule.solver)
    step = rule.update(net, task, tracker=tracker)
    c0 = task.error(net, step.free.positions, "initial")
    for _ in range(20):
        net = step.apply(net)
        step = rule.update(net, task, warm=step.warm, tracker=tracker)
    assert task.error(net, step.free.positions, "initial") < c0
    # 42 states (free and nudged for 21 steps) with far fewer factorisations
    assert tracker.stats.solves == 42 and tracker.stats.relax_calls == 1
    assert tracker.stats.factorisations <= 10


def test_trained_network_source_sweep_is_not_the_decoupled_line():
    # Fig. 5: after training, the target still responds to the source
    rule = CoupledLearning(
        3e-3, 0.1, strain_reference="initial", learn_targets=False, min_rest_length=0.1
    )
    history = train(paper_network, paper_task, rule, 40, seeds=[3], progress=False)
    assert history.error_initial[0, -1] < 0.05 * history.error_initial[0, 0]  # it learned
    net, task = history.final[0], history.tasks[0]
    s0 = task.source_strain[0]
    sweep = source_sweep(net, task, s0 + np.linspace(-1.0, 1.0, 5), strain_reference="initial")[
        :, 0
    ]
    assert sweep[2] == pytest.approx(history.target_strain[0, -1, 0], abs=1e-6)
    # a decoupled network would give a flat line at the trained strain
    assert np.ptp(sweep) > 0.05 * abs(sweep[2])
