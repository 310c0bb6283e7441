"""The beyond_paper scene: its keys, a tiny run end to end, the capacity rule."""

from __future__ import annotations

import json

import numpy as np
import pytest

from continuum_vs_network.report.sections.beyond_paper import capacity
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
n_sources = 2
n_targets = 1

[learning]
rules = ["aging", "gpc", "gcl"]
steps = 8
alpha_gcl = 0.5
alpha_gpc = 0.5
alpha_aging = 0.5
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
        ("temperatures = [0.0, 1e-6]", "temperatures = [-1.0]", "temperatures"),
    ],
)
def test_bad_or_unused_keys_name_the_key(tmp_path, old, new, key):
    with pytest.raises(SceneError) as err:
        load_scene(_write(tmp_path, TINY.replace(old, new)))
    assert err.value.key == key


def test_aging_key_is_refused_without_an_aging_rule(tmp_path):
    text = TINY.replace('rules = ["aging", "gpc", "gcl"]', 'rules = ["gcl"]')
    with pytest.raises(SceneError, match="alpha_aging"):
        load_scene(_write(tmp_path, text))


def test_tiny_scene_runs_and_reports_computed_findings(tmp_path):
    scene = load_scene(_write(tmp_path, TINY))
    result = run_scene(scene, tmp_path / "out", progress=False)
    units = result.units
    assert {"beyond/compare/paper/aging", "beyond/compare/stern/gcl", "beyond/symmetric"} <= set(
        units
    )
    assert "beyond/capacity/size6/examples2/seed0" in units
    for outputs in ("absolute", "relative"):
        assert {f"beyond/node/{outputs}/{r}" for r in ("aging", "gcl", "gcl_k")} <= set(units)
    assert units["beyond/node/relative/gcl_k"].meta["learns"] == "stiffness"
    # uniform k on the lattice and equal rates: aging and GPC take identical steps
    a = np.asarray(units["beyond/compare/stern/aging"].arrays["error"])
    g = np.asarray(units["beyond/compare/stern/gpc"].arrays["error"])
    assert np.allclose(a, g, rtol=1e-10, atol=0)
    for u in units.values():
        assert u.meta["coupling"] in ("coupled", "partially coupled", "decoupled", "not measured")
    from continuum_vs_network.report.writer import write_report

    write_report(result, tmp_path / "report")
    doc = json.loads((tmp_path / "report" / "report.json").read_text())
    claims = {f["claim"]: f["verdict"] for f in doc["findings"]}
    key = "GPC of rest lengths is directed aging of rest lengths with a k-weighted rate"
    assert claims[f"{key} (Stern's task)"] == "reproduced"
    assert claims[f"{key} (the paper's task)"] == "not comparable"
    assert any(c.startswith("a larger network holds more") for c in claims)
    assert "gcl learns a task of relative node displacements" in claims
    reg = units["beyond/regression"].meta
    assert reg["n_train"] == 4 and reg["n_test"] == 3
    assert np.isfinite(reg["test_initial"]) and reg["test_initial"] > 0
    assert any(c.startswith("a network trained on a few examples of a linear map") for c in claims)
    assert {"beyond/thermal/T1/gcl_eta0.01", "beyond/thermal/T0/exact"} <= set(units)
    assert units["beyond/thermal/T1/gcl_eta0.01"].meta["temperature"] == 1e-6
    assert "GCL's error floor grows with the temperature at every nudge" in claims
