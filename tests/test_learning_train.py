"""Tasks, the training loop, histories and checkpoints."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.learning import (
    AllosteryTask,
    CoupledLearning,
    History,
    ProspectiveConfiguration,
    paper_task,
    stern_task,
    train,
)
from continuum_vs_network.learning.history import MEASUREMENTS, UPDATES, stop_cause
from continuum_vs_network.learning.metrics import (
    final_values,
    length_error,
    normalised,
    rest_length_error,
    summary,
)
from continuum_vs_network.network.builders import paper_network, strain_tunable

# wall-clock columns differ between runs, and so does the core Newton's iteration count
# (it budgets conjugate-gradient solves by measured time); everything else must not
_TIMING = {"seconds", "measure_seconds", "iterations"}


def _assert_same(h1: History, h2: History, rtol: float = 0.0) -> None:
    assert h1.steps == h2.steps
    np.testing.assert_array_equal(h1.seeds, h2.seeds)
    np.testing.assert_array_equal(h1.completed, h2.completed)
    assert h1.stop_reason == h2.stop_reason
    assert set(h1.data) == set(h2.data)
    for name in h1.data:
        if name in _TIMING:
            continue
        # residuals below the tolerance are round-off: equal up to the tolerance itself
        atol = 1e-10 * h1.initial[0].force_scale if name == "residual" and rtol else 0.0
        np.testing.assert_allclose(h1.data[name], h2.data[name], rtol=rtol, atol=atol, err_msg=name)
    for a, b in zip(h1.final + h1.initial, h2.final + h2.initial):
        np.testing.assert_allclose(a.rest_length, b.rest_length, rtol=rtol)
        np.testing.assert_array_equal(a.springs, b.springs)


# -- tasks ------------------------------------------------------------------------------
def test_paper_task_draws_tunable_springs_and_the_paper_strains():
    rng = np.random.default_rng(0)
    sources, targets, spread = [], [], []
    for _ in range(800):
        net = paper_network(rng)
        task = paper_task(net, rng)
        tunable = strain_tunable(net)
        assert tunable[task.sources].all() and tunable[task.targets].all()
        sources.append(task.source_strain[0])
        targets.append(task.target_strain[0])
        spread.append(0.2 * abs(task.source_strain[0]))
    sources, targets = np.array(sources), np.array(targets)
    assert abs(sources.mean() - 5) < 0.15 and abs(sources.std() - 1) < 0.1  # ~4 sigma
    # S_T ~ N(5, 0.2 |S_s|): the standardised target strains are N(0, 1)
    z = (targets - 5) / np.array(spread)
    assert abs(z.mean()) < 0.15 and abs(z.std() - 1) < 0.1


def test_task_validation_and_conventions():
    rng = np.random.default_rng(1)
    net = paper_network(rng)
    task = AllosteryTask.create(net, [3], [0.5], [9], [0.2])
    assert task.pinned.sum() == 3  # one node fully, one coordinate of another
    np.testing.assert_allclose(task.source_lengths(net, "initial"), 1.5 * net.rest_length[3])
    grown = net.with_rest_length(2 * net.rest_length)
    np.testing.assert_allclose(task.source_lengths(grown, "current"), 3 * net.rest_length[3])
    np.testing.assert_allclose(task.source_lengths(grown, "initial"), 1.5 * net.rest_length[3])
    with pytest.raises(ValueError, match="both a source and a target"):
        AllosteryTask.create(net, [3], [0.5], [3], [0.2])
    with pytest.raises(ValueError, match="target_strain must be > -1"):
        AllosteryTask.create(net, [3], [0.5], [9], [-1.5])
    with pytest.raises(ValueError, match=r"sources\[0\] must be spring indices in 0\.\."):
        AllosteryTask.create(net, [30], [0.5], [9], [0.2])
    with pytest.raises(ValueError, match="strain_reference must be one of 'initial', 'current'"):
        task.source_lengths(net, "final")


def test_stern_task_counts():
    from continuum_vs_network.network.builders import triangular_lattice

    rng = np.random.default_rng(2)
    net = triangular_lattice(10, 10, noise=0.05, rng=rng)
    task = stern_task(net, 10, 3, rng)
    assert task.n_sources == 10 and task.n_targets == 3
    assert np.intersect1d(task.sources, task.targets).size == 0
    with pytest.raises(ValueError, match="rng"):
        stern_task(net, 10, 3)


# -- training ---------------------------------------------------------------------------
_GCL = CoupledLearning(
    2e-3, 0.1, strain_reference="initial", learn_targets=False, min_rest_length=0.1
)


def test_train_records_every_step_and_is_reproducible(tmp_path):
    h1 = train(paper_network, paper_task, _GCL, 12, seeds=[4, 7], progress=False)
    assert h1.trials == 2 and h1.completed.tolist() == [12, 12]
    for name in MEASUREMENTS:
        assert h1.data[name].shape[:2] == (2, 13), name
        assert np.all(np.isfinite(h1.data[name])), name
    for name in UPDATES:
        assert h1.data[name].shape[:2] == (2, 12), name
    # free + nudged state per step, then the final free state
    np.testing.assert_array_equal(np.diff(h1.solves, axis=1), [[2] * 11 + [1]] * 2)
    assert np.all(np.diff(h1.seconds, axis=1) > 0)
    # the two seeds made different networks and tasks
    assert not np.allclose(h1.initial[0].positions, h1.initial[1].positions)
    # strain error of the frozen-target run is the length error over L0^2 (one target)
    L0 = np.array([t.target_rest_length[0] for t in h1.tasks])[:, None]
    np.testing.assert_allclose(h1.error_initial, 0.5 * (length_error(h1) / L0) ** 2)
    h2 = train(paper_network, paper_task, _GCL, 12, seeds=[4, 7], progress=False)
    _assert_same(h1, h2, rtol=1e-7)
    path = h1.save(tmp_path / "h.npz")
    h3 = History.load(path)
    _assert_same(h1, h3)
    np.testing.assert_array_equal(h1.seconds, h3.seconds)
    assert h3.settings == h1.settings and h3.tasks[1].targets == h1.tasks[1].targets


def test_checkpoint_resume_gives_the_uninterrupted_history(tmp_path):
    full = train(
        paper_network,
        paper_task,
        _GCL,
        10,
        seeds=[4, 7],
        progress=False,
        checkpoint=tmp_path / "a.npz",
        checkpoint_every=3,
    )

    class Killed(Exception):
        pass

    def kill(trial, step, net):
        if trial == 1 and step == 7:
            raise Killed

    path = tmp_path / "b.npz"
    with pytest.raises(Killed):
        train(
            paper_network,
            paper_task,
            _GCL,
            10,
            seeds=[4, 7],
            progress=False,
            checkpoint=path,
            checkpoint_every=3,
            callback=kill,
        )
    resumed = train(
        paper_network,
        paper_task,
        _GCL,
        10,
        seeds=[4, 7],
        progress=False,
        checkpoint=path,
        checkpoint_every=3,
    )
    # equal up to the solver tolerance (the core's Newton is not bitwise reproducible)
    _assert_same(full, resumed, rtol=1e-7)
    assert resumed.solves[1, -1] == full.solves[1, -1]
    # a finished checkpoint is just loaded; another run's settings are refused
    again = train(
        paper_network,
        paper_task,
        _GCL,
        10,
        seeds=[4, 7],
        progress=False,
        checkpoint=path,
        checkpoint_every=3,
    )
    _assert_same(resumed, again)
    with pytest.raises(ValueError, match="different run"):
        train(
            paper_network,
            paper_task,
            _GCL,
            11,
            seeds=[4, 7],
            progress=False,
            checkpoint=path,
            checkpoint_every=3,
        )


def test_a_trial_that_fails_stops_with_its_reason():
    rule = ProspectiveConfiguration(10.0, strain_reference="initial")  # no floor
    h = train(paper_network, paper_task, rule, 5, seeds=[0], progress=False)
    assert h.completed[0] < 5 and "rest length" in h.stop_reason[0]
    assert np.isnan(h.error_initial[0, h.completed[0] + 1 :]).all()
    assert np.isfinite(h.error_initial[0, 0])


def test_a_stopped_trials_cause_is_read_off_its_reason():
    """The report counts early stops by cause: a real run's rest length crossing 0, and
    the reasons an equilibrium failure and an overflow give (their text as raised)."""
    rule = ProspectiveConfiguration(10.0, strain_reference="initial")  # no floor
    h = train(paper_network, paper_task, rule, 5, seeds=[0, 1], progress=False)
    assert h.stop_causes() == {"a rest length would reach 0": 2}
    reasons = {
        "step 3: EquilibriumError: newton: trust region collapsed (no decrease possible); "
        "tol is below float64's reach for the clamp lengths at this state: ...": (
            "tol below float64's reach"
        ),
        "step 7: EquilibriumError: newton: no convergence in 2000 iterations": (
            "no equilibrium found"
        ),
        "step 2: LearningError: the rest_length update of spring 4 is not finite (inf; 1 "
        "springs): the step overflowed (lower the learning rate)": "an update overflowed",
        "step 1: KeyError: 'x'": "KeyError",
    }
    for reason, cause in reasons.items():
        assert stop_cause(reason) == cause
    full = train(paper_network, paper_task, _GCL, 2, seeds=[0], progress=False)
    assert full.stop_causes() == {}  # a trial that completed has no cause


def test_gpc_without_measurement_solves_only_its_clamped_states():
    rule = ProspectiveConfiguration(1e-3, strain_reference="initial", learn_targets=True)
    h = train(paper_network, paper_task, rule, 6, seeds=[2], progress=False, measure=False)
    assert h.solves[0, -1] == 6 and np.isnan(h.error_initial).all()
    assert np.all(np.isfinite(h.energy_clamped))
    # GPC descends the clamped energy and moves L_T towards its clamp length
    assert h.energy_clamped[0, -1] < h.energy_clamped[0, 0]
    assert rest_length_error(h)[0, -1] < rest_length_error(h)[0, 0]


def test_metrics_normalise_and_summarise():
    values = np.array([[2.0, 1.0, 0.5], [4.0, 4.0, np.nan]])
    np.testing.assert_allclose(normalised(values)[0], [1.0, 0.5, 0.25])
    s = summary(values, completed=[2, 1])
    assert s["n"] == 2 and s["median"] == pytest.approx(0.625)


def test_a_trial_whose_equilibrium_was_lost_keeps_its_last_measured_value():
    """A trial that stopped because its equilibrium was lost has no measurement at its
    ``completed`` step: its final value is the last one measured, so it stays in medians and
    means instead of dropping out of them silently."""
    values = np.array([[2.0, 1.0, 0.5, 0.25], [4.0, 2.0, np.nan, np.nan]])
    np.testing.assert_allclose(final_values(values, completed=[3, 2]), [0.25, 2.0])
    s = summary(values, completed=[3, 2])
    assert s["n"] == 2 and s["missing"] == 0
    assert s["median"] == pytest.approx((0.125 + 0.5) / 2)
