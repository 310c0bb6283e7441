"""The paper's own setting: the notebook's GCL sign, per-rule conventions and steps, runaway
trials judged as failures, and the captions that state numbers of the same run."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from continuum_vs_network.learning.rules import CoupledLearning
from continuum_vs_network.learning.tasks import paper_task
from continuum_vs_network.report.sections.learning import MEAN_OVER_MEDIAN, mean_note
from continuum_vs_network.report.sections.learning.paper import degenerate
from continuum_vs_network.report.verdicts.claims import MIN_STEPS, diverged
from continuum_vs_network.scenes.paper_setting import (
    NotebookCoupledLearning,
    draw_feasibility,
    paper_setting_experiments,
)
from continuum_vs_network.scenes.replication import _network


def _draw(seed=0):
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    net = _network(rng)
    return net, paper_task(net, rng)


def test_notebook_sign_is_the_negative_of_the_derived_step():
    net, task = _draw()
    kw = {"strain_reference": "current", "learn_sources": False, "learn_targets": True}
    a = CoupledLearning(1e-3, 0.1, **kw).update(net, task)
    b = NotebookCoupledLearning(1e-3, 0.1, **kw).update(net, task)
    assert np.linalg.norm(a.delta) > 0
    np.testing.assert_allclose(b.delta, -a.delta, rtol=1e-12, atol=1e-15)
    assert a.delta[task.sources[0]] == 0  # the source does not learn (as in the notebook)


def test_each_rule_runs_in_its_notebook_convention_and_rate():
    exps = {e.name: e.rule for e in paper_setting_experiments()}
    assert set(exps) == {"gcl", "gcl_notebook", "gpc", "gpc_frozen", "exact"}
    assert exps["gcl"].strain_reference == exps["gcl_notebook"].strain_reference == "current"
    assert exps["gpc"].strain_reference == exps["gpc_frozen"].strain_reference == "initial"
    assert exps["gcl"].alpha == 1e-3 and exps["gcl"].eta == 0.1 and exps["gpc"].alpha == 5e-3
    assert exps["gpc_frozen"].learn_targets is False and exps["gpc"].learn_targets is True


def test_a_runaway_trial_is_judged_not_left_out():
    class H:
        steps = 100
        completed = np.array([100, 14, 30])
        stop_reason = ("", "step 14: LearningError: a rest length would reach 0", "step 30: x tol")

    d = diverged(H())
    assert d.tolist() == [False, True, False]
    assert MIN_STEPS == 100


def test_mean_note_names_the_trials_that_carry_the_mean():
    finals = np.array([0.5, 0.6, 0.7, 0.4, 1e3])
    note = mean_note(finals)
    med = float(np.median(finals))
    assert np.mean(finals) > MEAN_OVER_MEDIAN * med
    assert "carried by 1 of 5 trials" in note and f"({med:.3g})" in note and "1e+03" in note
    assert mean_note(np.array([0.5, 0.6, 0.7])) == ""  # mean near the median: no note


def test_degenerate_draws_follow_the_stated_rule():
    a = {"slope": np.array([0.2, 1e-5, 0.2, 0.2]), "optimum": np.array([1e-6, 1e-6, 0.3, np.nan])}
    assert degenerate(a).tolist() == [False, True, True, True]


@pytest.mark.parametrize("seed", [0])
def test_draw_feasibility_measures_one_draw(seed):
    net, task = _draw(seed)
    out = draw_feasibility(net, task, max_iter=20, adagrad_iterations=20)
    assert np.isfinite(out["slope"]) and out["nonlinearity"] >= 0
    assert 0 <= out["aspect"] <= 1 and 0 <= out["self_stress"] <= 1 + 1e-12
    # Eq. 23 as printed ascends the clamped energy, the derived sign descends it
    assert out["eq23_printed"] > 0 > out["eq23_derived"]
    assert out["adagrad_residual"] > 1e-6  # the paper's relaxation leaves net forces
    assert 0 <= out["optimum"] <= 1 + 1e-9
    # the task as drawn: unchanged
    assert dataclasses.is_dataclass(task)


PAPER_SETTING = """
name = "paper_setting_tiny"
description = "the paper's own setting, tiny"
seed = 0
kind = "learning"
[network]
builder = "paper"
[task]
kind = "paper"
[learning]
paper_setting = true
rules = ["gcl", "gcl_notebook", "gpc", "gpc_frozen", "exact"]
trials = 2
steps = 3
steps_gpc = 4
alpha_gpc = 5e-3
strain_reference = "current"
[solver]
methods = ["newton"]
"""


def test_paper_setting_report_states_numbers_of_its_own_run(tmp_path):
    import re

    from continuum_vs_network.learning.metrics import final_values, normalised
    from continuum_vs_network.report.writer import write_report
    from continuum_vs_network.scenes import run_scene
    from continuum_vs_network.scenes.schema import load_scene

    path = tmp_path / "scene.toml"
    path.write_text(PAPER_SETTING)
    result = run_scene(load_scene(path), tmp_path / "results", progress=False)
    text = write_report(result, tmp_path / "report", render=False).read_text()
    H = result.histories
    assert H["newton/gpc/noise0"].steps == 4 and H["newton/gcl/noise0"].steps == 3
    assert H["newton/gpc/noise0"].strain_reference == "initial"
    assert H["newton/gcl_notebook/noise0"].strain_reference == "current"
    # every paper claim has a row with its run and figures
    for rule, figs in (
        ("gcl", "Fig. 4"),
        ("gcl_notebook", "Fig. 4"),
        ("gpc", "Fig. 6-9"),
        ("gpc_frozen", "Fig. 10"),
    ):
        assert re.search(rf"^\| {rule} \| {re.escape(figs)}", text, re.M), rule
    # the Eq. 14 paragraph's counts are those of the histories
    nb = final_values(
        normalised(H["newton/gcl_notebook/noise0"].error_current),
        H["newton/gcl_notebook/noise0"].completed,
    )
    pk = final_values(
        normalised(H["newton/gcl/noise0"].error_current), H["newton/gcl/noise0"].completed
    )
    assert f"reaches C/C0 <= 1e-2 in {int(np.sum(nb <= 1e-2))} of 2 trials" in text
    assert f"makes C rise in {int(np.sum(pk > 1))} of 2" in text
    # the per-draw table: one row per draw, the degenerate count stated from it
    feas = result.units["feasibility"].arrays
    assert f"Degenerate draws: **{int(degenerate(feas).sum())} of 2**" in text
    assert "## Why the paper's runs do what they do" in text
