"""The beyond_paper scene: its keys, a tiny run end to end, the capacity rule."""

from __future__ import annotations

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from continuum_vs_network.report.sections.beyond_paper.examples import capacity
from continuum_vs_network.scenes import SceneError, load_scene, run_scene

TINY = """
name = "tiny_beyond"
description = "tiny"
seed = 0
kind = "beyond_paper"

[network]
builder = "triangular"
sizes = [4, 6]

[task]
kind = "stern"
n_sources = 1
n_targets = 1

[learning]
rules = ["aging", "gpc", "gcl"]
compare_tasks = ["paper", "lattice"]
steps = 8
examples = [1, 2]
capacity_seeds = 2
etas = [0.01, 1.0]
temperatures = [0.0, 1e-6]
"""


def _write(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return path


def test_capacity_is_the_largest_m_learned_by_at_least_half_the_draws():
    learned, trivial, missed = "learned (coupled)", "met trivially (decoupled)", "not met"
    part = "learned, partially coupled"
    assert capacity({1: [learned, missed], 2: [part, part], 4: [missed, missed]}) == 2
    assert capacity({1: [missed, learned, learned], 2: [learned, missed, missed]}) == 1
    # a trivially met run (decoupled) is not learned
    assert capacity({1: [trivial, trivial], 2: [missed, missed]}) == 0
    # not a prefix: a later m learned by most draws counts even if an earlier one did not
    assert capacity({1: [missed, missed, learned], 4: [learned, learned, missed]}) == 4


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ('rules = ["aging", "gpc", "gcl"]', 'rules = ["gcl_all"]', "rules"),
        ("steps = 8", "steps = 8\ntrials = 3", "trials"),
        ("steps = 8", "steps = 8\nnoise = [0.0, 1e-3]", "noise"),
        ("examples = [1, 2]", "examples = [2, 1]", "examples"),
        ("capacity_seeds = 2", "capacity_seeds = 0", "capacity_seeds"),
        ("n_targets = 1", 'n_targets = 1\nnode_outputs = ["relative", "both"]', "node_outputs"),
        ('compare_tasks = ["paper", "lattice"]', 'compare_tasks = ["stern"]', "compare_tasks"),
        ("temperatures = [0.0, 1e-6]", "temperatures = [-1.0]", "temperatures"),
    ],
)
def test_bad_or_unused_keys_name_the_key(tmp_path, old, new, key):
    with pytest.raises(SceneError) as err:
        load_scene(_write(tmp_path, TINY.replace(old, new)))
    assert err.value.key == key


@pytest.mark.parametrize("key", ["alpha_aging", "alpha_gcl", "alpha_gpc"])
def test_raw_rate_keys_are_refused_the_scene_uses_default_rates(tmp_path, key):
    with pytest.raises(SceneError, match=key):
        load_scene(_write(tmp_path, TINY.replace("steps = 8", f"steps = 8\n{key} = 0.5")))


def test_rules_are_the_default_objects_bounded_like_the_optimum(tmp_path):
    from continuum_vs_network.learning.ranges import REST_LENGTH_RANGE
    from continuum_vs_network.scenes.units_beyond import DOFS, rule

    scene = load_scene(_write(tmp_path, TINY))
    for name, dof in DOFS.items():
        r = rule(name, scene)
        assert r.alpha is None and r.rate is None  # the default scale-free rate
        assert r.dof == dof
        assert r.rest_length_range == (None if dof == "stiffness" else REST_LENGTH_RANGE)
    assert rule("gcl", scene, eta=0.3).eta == 0.3


def test_helpers_basis_reason_and_verdicts():
    from continuum_vs_network.report.findings import (
        NOT_COMPARABLE,
        NOT_REPRODUCED,
        REPRODUCED,
        reasoned,
        runs_basis,
    )
    from continuum_vs_network.report.sections.beyond_paper.aging import rule_verdict
    from continuum_vs_network.report.sections.beyond_paper.thermal import baseline_converged
    from continuum_vs_network.scenes.results.beyond_paper import OptimumResult

    coupled = SimpleNamespace(outcome="learned (coupled)", coupling="coupled")
    missed = SimpleNamespace(outcome="not met", coupling="decoupled")
    trivial = SimpleNamespace(outcome="met trivially (decoupled)", coupling="decoupled")
    assert runs_basis([coupled, coupled]) == "coupled"
    assert runs_basis([coupled, missed]) == "" and runs_basis([]) == ""
    assert runs_basis([coupled, trivial]) == "met trivially"
    assert runs_basis([coupled, SimpleNamespace()]) == ""  # a run without a coupling
    assert reasoned("r", REPRODUCED, "why") == "r"
    assert reasoned("r.", NOT_COMPARABLE, "why") == "r. Not comparable here: why"
    feasible = OptimumResult(
        outcome="feasible", ratio=1e-6, worst_example=1e-5, feasible=True, source_share=1.0,
        coupling="coupled", seconds=0.1, max_iter=8, dof="stiffness",
    )  # fmt: skip
    infeasible = dataclasses.replace(
        feasible, outcome="infeasible", feasible=False, worst_example=0.2
    )
    assert rule_verdict(coupled, feasible) == (REPRODUCED, "")
    assert rule_verdict(missed, feasible) == (NOT_REPRODUCED, "")
    verdict, reason = rule_verdict(missed, infeasible)
    assert verdict == NOT_COMPARABLE and reason.startswith("infeasible") and "0.2" in reason
    assert rule_verdict(trivial, feasible)[0] == NOT_COMPARABLE
    assert baseline_converged(1e-6, [1e-4, 1e-2])
    assert not baseline_converged(2e-5, [1e-4, 1e-2])  # only 5x below the lowest floor
    assert not baseline_converged(float("nan"), [1e-4])


def test_tiny_scene_runs_and_reports_computed_findings(tmp_path):
    scene = load_scene(_write(tmp_path, TINY))
    result = run_scene(scene, tmp_path / "out", progress=False)
    units = result.units
    assert {"beyond/compare/paper/aging", "beyond/compare/lattice/gcl_k",
            "beyond/optimum/lattice/rest_length", "beyond/optimum/paper/stiffness",
            "beyond/symmetric"} <= set(units)  # fmt: skip
    assert "beyond/capacity/size6/examples2/seed0" in units
    for outputs in ("absolute", "relative"):
        assert {f"beyond/node/{outputs}/{r}" for r in ("aging", "gcl", "gcl_k")} <= set(units)
    assert units["beyond/node/relative/gcl_k"].meta["learns"] == "stiffness"
    # every rule ran its default rate: no raw alpha in the recorded settings
    for r in ("aging", "gpc", "gcl", "gcl_k"):
        assert units[f"beyond/compare/lattice/{r}"].meta["rule"].get("alpha") is None
    # uniform k on the lattice and both at their scaled rate: aging and GPC take identical steps
    a = np.asarray(units["beyond/compare/lattice/aging"].arrays["error"])
    g = np.asarray(units["beyond/compare/lattice/gpc"].arrays["error"])
    assert np.allclose(a, g, rtol=1e-10, atol=0)
    # stiffness learning of a network at rest cannot prestress: coupled by construction
    for n in (4, 6):
        for m in (1, 2):
            meta = units[f"beyond/capacity/size{n}/examples{m}/seed0"].meta
            assert meta["coupling"] == "coupled", meta
            assert meta["exact"]["max_iter"] == 8  # the optimum's budget is the rules' steps
    for u in units.values():
        if "coupling" in u.meta:
            assert u.meta["coupling"] in (
                "coupled", "partially coupled", "decoupled", "not measured"
            )  # fmt: skip
    # every unit reads back as its result class; the exact gradient's null eta is stored
    from continuum_vs_network.scenes.results import read_results
    from continuum_vs_network.scenes.results.beyond_paper import CLASSES

    typed = read_results(units, CLASSES)
    assert set(typed) == set(units)
    assert typed["beyond/thermal/T0/exact"].eta is None
    assert units["beyond/thermal/T0/exact"].meta["eta"] is None
    assert typed["beyond/capacity/size6/examples2/seed0"].optimum.max_iter == 8
    from continuum_vs_network.report.writer import write_report

    write_report(result, tmp_path / "report")
    doc = json.loads((tmp_path / "report" / "report.json").read_text())
    findings = {f["claim"]: f for f in doc["findings"]}
    claims = {c: f["verdict"] for c, f in findings.items()}
    key = "GPC of rest lengths is directed aging of rest lengths with a k-weighted rate"
    assert claims[f"{key} (Rocks et al.'s task on the lattice)"] == "reproduced"
    assert claims[f"{key} (the paper's task)"] == "not comparable"
    assert any(c.startswith("a larger network holds more") for c in claims)
    assert any(c.startswith("GCL learns as many examples") for c in claims)
    assert "gcl learns a task of relative node displacements (with its rest example)" in claims
    assert (
        "GCL of stiffnesses learns Rocks et al.'s task on the lattice (with its rest example)"
        in claims
    )
    for f in findings.values():
        assert f["basis"] != "met trivially", f["claim"]
        if f["verdict"] == "not comparable":
            assert "Not comparable here: " in f["rule"], f["claim"]
    reg = units["beyond/regression"].meta
    assert reg["n_train"] == 4 and reg["n_test"] == 3
    assert np.isfinite(reg["test_initial"]) and reg["test_initial"] > 0
    assert any(c.startswith("a network trained on a few examples of a linear map") for c in claims)
    assert {"beyond/thermal/T1/gcl_eta0.01", "beyond/thermal/T0/exact"} <= set(units)
    assert units["beyond/thermal/T1/gcl_eta0.01"].meta["temperature"] == 1e-6
    assert units["beyond/thermal/T1/gcl_eta0.01"].meta["rule"]["dof"] == "stiffness"
    assert "GCL's error floor grows with the temperature at every nudge" in claims


def test_the_compare_caption_names_exactly_the_curves_drawn_on_top_of_one_another():
    from continuum_vs_network.report.figures import Panel, Series
    from continuum_vs_network.report.sections.beyond_paper.aging import _hidden

    x = np.arange(4.0)
    same = Panel([Series(x, [1, 0.5, 0.2, 0.1], "gpc"), Series(x, [1, 0.5, 0.2, 0.1], "aging")])
    apart = Panel([Series(x, [1, 0.5, 0.2, 0.1], "gcl"), Series(x, [1, 0.5, 0.2, 0.2], "exact")])
    assert _hidden([same]) == "; on top of one another (drawn, hidden): aging lies under gpc"
    assert _hidden([apart]) == ""
