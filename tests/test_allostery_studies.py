"""Allostery scenes as studies: read-out noise levels, GCL nudges, the raw rate, and sweeps of
them (the ``noise`` and ``eta_alpha`` scenes)."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.report import write_report
from continuum_vs_network.report.sections.sweep.rates import _nudge, _rate_bracket
from continuum_vs_network.scenes import SceneError, load_scene, parse_scene, run_scene
from continuum_vs_network.scenes.sweep_rows import allostery_rows
from continuum_vs_network.scenes.units_allostery import _rule, runs

NOISY = {
    "name": "allostery_noisy",
    "description": "tiny noise study",
    "seed": 0,
    "kind": "allostery",
    "allostery": {
        "n_nodes": [64],
        "rules": ["gcl"],
        "etas": [0.1, 1.0],
        "noise": [0.0, 1e-3],
        "draws": 1,
        "steps": 40,
        "step": 0.2,
        "map_draws": 0,
    },
}


def test_runs_name_every_rule_nudge_and_noise_level():
    scene = parse_scene({**NOISY, "allostery": {**NOISY["allostery"], "rules": ["gcl", "gpc"]}})
    names = [r.name for r in runs(scene)]
    assert names == [
        "gcl_eta0.1_noise0",
        "gcl_eta0.1_noise0.001",
        "gcl_eta1_noise0",
        "gcl_eta1_noise0.001",
        "gpc_noise0",
        "gpc_noise0.001",
    ]
    plain = parse_scene({**NOISY, "allostery": {"n_nodes": [64], "rules": ["gcl", "gpc"]}})
    assert [r.name for r in runs(plain)] == ["gcl", "gpc"]


def test_a_raw_rate_and_a_step_together_are_refused():
    bad = {**NOISY, "allostery": {**NOISY["allostery"], "alpha": 1e5}}
    with pytest.raises(SceneError, match="step"):
        parse_scene(bad)


def test_the_scene_rates_reach_the_rule_objects():
    assert _rule("gcl", "stiffness", step=0.3).adaptive.step == 0.3
    assert _rule("gpc", "stiffness", step=0.3).adaptive.step == 0.3
    raw = _rule("gcl", "stiffness", eta=0.5, alpha=1e4)
    assert raw.adaptive is None and raw.alpha == 1e4 and raw.eta == 0.5


def test_the_builtin_studies_are_allostery_scenes_on_coupled_tasks():
    noise = load_scene("noise")
    assert noise.kind == "allostery" and noise.report.default
    assert len(noise.allostery.noise) >= 3 and 0.0 in noise.allostery.noise
    assert len(noise.allostery.etas) >= 2 and "gpc" in noise.allostery.rules
    sweep = load_scene("eta_alpha")
    assert sweep.kind == "allostery" and sweep.sweep is not None
    keys = dict(sweep.sweep.axes)
    assert "allostery.alpha" in keys and len(keys["allostery.alpha"]) >= 3


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    scene = parse_scene(NOISY)
    folder = tmp_path_factory.mktemp("noisy")
    return run_scene(scene, folder, workers=1, progress=False), folder


def test_noise_raises_the_floor_a_noise_free_run_reaches(noisy):
    """Read-out noise limits learning: at sigma = 1e-3 the floor lies above the noise-free
    run's final C/C0, the more so at the smaller nudge ((sigma/eta)^2)."""
    result, _ = noisy
    u = result.units
    base = "allostery/train/n64/1to1/stiffness/draw0/gcl_eta"
    clean = u[base + "1_noise0"].meta["ratio"]
    noisy_big = u[base + "1_noise0.001"].meta["floor"]
    noisy_small = u[base + "0.1_noise0.001"].meta["floor"]
    assert clean < noisy_big < noisy_small
    assert u[base + "1_noise0.001"].meta["noise"] == 1e-3


def test_the_sweep_table_has_a_row_per_run_and_draw(noisy):
    result, _ = noisy
    rows = allostery_rows(result, threshold=1e-2)
    assert len(rows) == 4
    clean = next(r for r in rows if r["rule"] == "gcl_eta1_noise0")
    assert clean["relative_error"] == pytest.approx(
        result.units["allostery/train/n64/1to1/stiffness/draw0/gcl_eta1_noise0"].meta["ratio"]
    )
    errors = result.units["allostery/train/n64/1to1/stiffness/draw0/gcl_eta1_noise0"].arrays[
        "error"
    ]
    hit = np.flatnonzero(errors / errors[0] <= 1e-2)
    assert clean["steps_to_threshold"] == (int(hit[0]) if hit.size else None)


def test_the_noise_report_states_its_fit(noisy, tmp_path):
    result, _ = noisy
    text = write_report(result, tmp_path / "report", render=False).read_text()
    assert "Read-out noise" in text and "(sigma/eta)^" in text


def _stats(table):
    """{(alpha, eta): (share, steps, rows)} from {alpha: [(share, steps) per eta]}."""
    return {(a, e): (s, n, 4) for a, cells in table.items() for e, (s, n) in zip((0.1, 1.0), cells)}


class _Doc:
    def __init__(self):
        self.findings, self.text = [], []

    def add(self, *lines):
        self.text += lines

    def finding(self, f):
        self.findings.append(f)


def test_a_rate_grid_is_judged_bracketed_only_with_a_worse_rate_on_both_sides():
    bracketed = {1e4: [(0.25, 90), (0.25, 95)], 1e5: [(1, 40), (1, 42)], 1e6: [(0.5, 9), (0, None)]}
    stats = _stats(
        {a: [(s, np.nan if n is None else n) for s, n in c] for a, c in bracketed.items()}
    )
    doc = _Doc()
    _rate_bracket(doc, sorted(bracketed), (0.1, 1.0), stats)
    assert doc.findings[-1].verdict == "reproduced"
    open_top = {1e4: [(0.25, 90), (0.25, 95)], 1e5: [(1, 40), (1, 42)], 1e6: [(1, 9), (1, 8)]}
    stats = _stats(open_top)
    doc = _Doc()
    _rate_bracket(doc, sorted(open_top), (0.1, 1.0), stats)
    assert doc.findings[-1].verdict == "not reproduced"  # the best rate is the largest run


def test_the_nudge_is_compared_on_the_stable_side_only():
    table = {1e4: [(1, 100), (1, 110)], 1e5: [(1, 40), (1, 44)], 1e6: [(0.25, 5), (0.5, 60)]}
    doc = _Doc()
    _nudge(doc, sorted(table), (0.1, 1.0), _stats(table))
    f = doc.findings[-1]
    assert f.verdict == "reproduced" and f.measured["rates compared"] == 2
    assert f.measured["ratio"] == pytest.approx(1.1)
