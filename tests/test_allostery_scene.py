"""The ``allostery`` scene kind: schema, a tiny run end to end, and its report's numbers."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from continuum_vs_network.report import write_report
from continuum_vs_network.report.sections.allostery.data import (
    LEARNED,
    Group,
    groups,
    tally,
    verdict,
)
from continuum_vs_network.scenes import SceneError, load_scene, parse_scene, run_scene
from continuum_vs_network.scenes.units_allostery import FEASIBLE

TINY = {
    "name": "allostery_tiny",
    "description": "tiny allostery scene",
    "seed": 0,
    "kind": "allostery",
    "allostery": {
        "n_nodes": [64],
        "draws": 2,
        "steps": 20,
        "clamped_steps": 5,
        "map_distances": [0.3],
        "map_ratios": [0.3],
        "map_draws": 1,
    },
}


def test_the_builtin_scenes_load():
    default = load_scene("allostery")
    full = load_scene("allostery_full")
    assert default.kind == full.kind == "allostery"
    assert default.report.default and not full.report.default
    a = default.allostery
    assert (a.n_nodes, a.tasks, a.dofs, a.draws, a.steps) == (
        (512,),
        ("1to1",),
        ("stiffness",),
        10,
        1000,
    )
    assert set(a.rules) == {"gcl", "exact", "gpc", "aging"}
    f = full.allostery
    assert f.n_nodes == (512, 1024) and set(f.tasks) == {"1to1", "10to3"}
    assert set(f.dofs) == {"stiffness", "rest_length", "both"}


def test_an_unknown_key_is_rejected_naming_it():
    data = {**TINY, "allostery": {**TINY["allostery"], "n_draws": 3}}
    with pytest.raises(SceneError, match=r"n_draws.*unknown key|unknown key.*draws") as err:
        parse_scene(data, "x.toml")
    assert "n_draws" in str(err.value) and "allostery" in str(err.value)


def test_an_unknown_rule_and_a_foreign_table_are_rejected():
    with pytest.raises(SceneError, match="rules"):
        parse_scene({**TINY, "allostery": {**TINY["allostery"], "rules": ["gcl_all"]}})
    with pytest.raises(SceneError, match="learning"):
        parse_scene({**TINY, "learning": {"rules": ["gcl"]}})


def _opt(feasible: bool, ratio: float):
    return SimpleNamespace(feasible=feasible, ratio=ratio)


def _train(outcome: str, ratio: float, steps_to=None):
    return SimpleNamespace(
        outcome=outcome,
        ratio=ratio,
        rule_seconds=1.0,
        contrast=2.0,
        steps_to=steps_to or {"0.01": 5, "0.001": None},
    )


def test_an_infeasible_draw_is_flagged_and_counted_apart():
    assert verdict(_train(LEARNED, 1e-4), _opt(False, 0.4)).startswith(
        "infeasible (optimum C/C0 = 0.4"
    )
    assert verdict(_train("not met", 0.5), _opt(True, 1e-5)) == "not met"
    g = Group(
        64,
        "1to1",
        "stiffness",
        opt=[_opt(True, 1e-6), _opt(False, 0.3), _opt(True, 1e-5)],
        train={"gcl": [_train(LEARNED, 1e-4), _train(LEARNED, 1e-4), _train("not met", 0.5)]},
    )
    t = tally(g, "gcl")
    assert t.verdicts[1].startswith("infeasible")
    assert (t.draws, t.feasible, t.learned) == (3, 2, 1)  # the infeasible draw is not counted
    assert t.share == 0.5
    assert t.ratio == pytest.approx(np.median([1e-4, 0.5]))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    folder = tmp_path_factory.mktemp("allostery")
    scene = parse_scene(TINY, "tiny.toml")
    result = run_scene(scene, folder / "results", progress=False)
    text = write_report(result, folder / "report", render=False).read_text()
    return result, text


def test_the_tiny_scene_runs_and_stores_every_unit(tiny):
    result, _ = tiny
    a = result.scene.allostery
    train = result.select("allostery/train/")
    opt = result.select("allostery/opt/")
    assert len(train) == a.draws * len(a.rules) and len(opt) == a.draws
    assert len(result.select("allostery/map/")) == a.map_draws
    for key, u in train.items():
        steps = a.clamped_steps if key.endswith(("gpc", "aging")) else a.steps
        assert u.arrays["error"].shape == (steps + 1,)
        assert u.arrays["sweep"].shape == (5, 1)
        assert u.meta["coupling"] in ("coupled", "partially coupled", "decoupled")
        assert u.meta["contrast"] >= 1.0
    for u in opt.values():
        assert u.meta["feasible"] == (u.meta["ratio"] <= FEASIBLE)
        assert u.arrays["sweep0"].shape == (5, 1)
    ratios = [
        result.units[f"allostery/train/n64/1to1/stiffness/draw{i}/gcl"].meta["task_ratio"]
        for i in range(2)
    ]
    assert ratios[0] == pytest.approx(0.3) and ratios[1] == pytest.approx(-0.3)


def test_the_report_states_the_counts_of_the_stored_units(tiny):
    result, text = tiny
    a = result.scene.allostery
    units = result.units
    base = "allostery/%s/n64/1to1/stiffness/draw%d"
    feasible = [units[base % ("opt", i)].meta["ratio"] <= FEASIBLE for i in range(a.draws)]
    assert f"{sum(feasible)} of {a.draws} draws are feasible" in text
    names = {"gcl": "GCL", "exact": "exact gradient", "gpc": "GPC", "aging": "directed aging"}
    for rule in a.rules:
        learned = sum(
            ok and units[f"{base % ('train', i)}/{rule}"].meta["outcome"] == LEARNED
            for i, ok in enumerate(feasible)
        )
        assert f"{names[rule]} learned (coupled) {learned} of {sum(feasible)} feasible" in text
        row = re.search(rf"\| {names[rule]} \| \d+ \| (\d+) / (\d+) \|", text)
        assert row and (int(row[1]), int(row[2])) == (learned, sum(feasible))
    g = groups(result.scene, units)[0]
    for rule in ("gcl", "exact"):
        t = tally(g, rule)
        assert t.learned == sum(v == LEARNED for v in t.verdicts)
    assert text.index("fig_allostery_map.png") < text.index("_curves.png")  # map comes first
    for stem in (
        "map",
        "n64_1to1_stiffness_curves",
        "n64_1to1_stiffness_sweeps",
        "n64_1to1_stiffness_render",
    ):
        assert (result.directory.parent / "report" / f"fig_allostery_{stem}.png").is_file()
