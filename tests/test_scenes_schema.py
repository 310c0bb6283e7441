"""Scene files: every built-in scene is valid; bad files name the file, the table and the key."""

from __future__ import annotations

import dataclasses
import tomllib

import pytest

from continuum_vs_network.report.provenance import scene_toml
from continuum_vs_network.scenes.schema import (
    _TABLES,
    KIND_TABLES,
    SceneError,
    builtin_names,
    builtin_path,
    key_reference,
    load_scene,
    parse_scene,
)

TINY = """
name = "tiny"
description = "a tiny learning scene"
seed = 1
kind = "learning"

[network]
builder = "paper"

[task]
kind = "paper"

[learning]
rules = ["gcl_floor"]
trials = 2
steps = 5
"""


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", builtin_names())
def test_builtin_scene_is_valid_and_round_trips(name):
    scene = load_scene(name)
    assert scene.name == name  # the file name is the scene name (folders use it)
    assert builtin_path(name).name == f"{name}.toml"
    # the report's settings block is TOML that parses back to the same scene
    again = parse_scene(tomllib.loads(scene_toml(scene.to_dict())), "roundtrip")
    assert again == scene


def test_builtin_set_covers_the_issue():
    scenes = {n: load_scene(n) for n in builtin_names()}
    kinds = {s.kind for s in scenes.values()}
    assert kinds == set(KIND_TABLES)
    default = [s for s in scenes.values() if s.report.default]
    assert {s.kind for s in default} == set(KIND_TABLES)  # the default report shows every kind
    paper = scenes["paper"].learning
    assert {"gcl", "gpc", "gpc_frozen"} <= set(paper.rules) and paper.trials == 10
    assert set(scenes["paper_adagrad"].solver.methods) == {"paper", "newton"}
    full = scenes["paper_full"]
    assert (full.learning.trials, full.learning.steps) == (10, 300) and not full.report.default
    stern = scenes["stern"].allostery
    assert stern.n_nodes[0] >= 512 and stern.tasks == ("10to3",)
    assert max(scenes["stability"].network.stiffness_ratios) >= 1e12
    assert max(scenes["stability"].task.strains) >= 10
    assert set(scenes["solvers"].solver.methods) == {"newton", "fire", "lbfgs", "paper"}
    assert max(scenes["solvers_large"].network.sizes) ** 2 >= 1e4


def test_tiny_scene_parses_with_defaults(tmp_path):
    scene = load_scene(_write(tmp_path, TINY))
    assert scene.learning.trials == 2 and scene.learning.strain_reference == "initial"
    assert scene.solver is None and scene.export is None and scene.continuum is None
    assert scene.report.default is False and scene.report.images is False


@pytest.mark.parametrize(
    ("old", "new", "table", "key", "words"),
    [
        ("steps = 5", "steps = 5\nbogus = 1", "learning", "bogus", "unknown key"),
        (
            "steps = 5",
            'steps = 5\nreference = "initial"',
            "learning",
            "reference",
            "strain_reference",
        ),
        ('rules = ["gcl_floor"]', 'rules = ["gcl_all"]', "learning", "rules", "Stern-scale"),
        ("trials = 2", 'trials = "two"', "learning", "trials", "must be an integer"),
        ("trials = 2", "trials = true", "learning", "trials", "must be an integer"),
        ("trials = 2", "trials = 0", "learning", "trials", "must be >= 1"),
        ('rules = ["gcl_floor"]', 'rules = ["gcl", "hebb"]', "learning", "rules", "'hebb'"),
        ('rules = ["gcl_floor"]', 'rules = ["gcl", "gcl"]', "learning", "rules", "repeat"),
        (
            'rules = ["gcl_floor"]',
            'rules = ["gcl_notebook"]',
            "learning",
            "rules",
            "needs paper_setting",
        ),
        (
            'rules = ["gcl_floor"]',
            'rules = ["gcl_floor"]\npaper_setting = true',
            "learning",
            "rules",
            "paper's own setting",
        ),
        ('rules = ["gcl_floor"]', "rules = []", "learning", "rules", "at least one"),
        ('builder = "paper"', 'builder = "paper"\nnoise = -0.1', "network", "noise", ">= 0"),
        ('builder = "paper"', 'builder = "hexagonal"', "network", "builder", "'hexagonal'"),
        ('kind = "paper"', 'kind = "paper"\nstrain = -1.5', "task", "strain", "> -1"),
        ('kind = "paper"', 'kind = "source"', "task", "kind", "'paper'"),
        (
            'kind = "learning"',
            'kind = "learning"\n[solvers]\nx = 1',
            "(top level)",
            "solvers",
            "unknown key or table",
        ),
        ("seed = 1", "seed = -3", "(top level)", "seed", "in 0..2**63-1"),
        ('name = "tiny"', 'name = "../etc"', "(top level)", "name", "plain name"),
        (
            'kind = "learning"\n',
            'kind = "learning"\n[continuum]\nrefine = 1\n',
            "continuum",
            "",
            "does not use",
        ),
        ('[task]\nkind = "paper"\n', "", "task", "", "needs a [task]"),
        ("steps = 5", "steps = 5\n[export]\ntrials = [0, 4]", "export", "trials", "does not exist"),
        ("steps = 5", 'steps = 5\n[solver]\nmethods = ["fire"]', "solver", "methods", "'fire'"),
        ("steps = 5", "steps = 5\n[solver]\ntol = 2.0", "solver", "tol", "between 0 and 1"),
        ("steps = 5", "steps = 5\n[report]\ndpi = 10000", "report", "dpi", "[40, 300]"),
    ],
)
def test_errors_name_file_table_and_key(tmp_path, old, new, table, key, words):
    assert old in TINY
    path = _write(tmp_path, TINY.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    err = info.value
    assert (err.file, err.table, err.key) == (str(path), table, key)
    msg = str(err)
    assert str(path) in msg and words in msg
    if key:
        assert key in msg
    if not table.startswith("("):
        assert f"[{table}]" in msg


def test_missing_required_and_syntax_errors(tmp_path):
    path = _write(tmp_path, TINY.replace('kind = "learning"\n', ""))
    with pytest.raises(SceneError, match=r"\(top level\) kind: is required"):
        load_scene(path)
    path = _write(tmp_path, TINY.replace("trials = 2", "trials = = 2"))
    with pytest.raises(SceneError, match=r"\(syntax\): not valid TOML") as info:
        load_scene(path)
    assert info.value.file == str(path)
    with pytest.raises(SceneError, match="no such scene file"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(SceneError, match="no built-in scene 'nope'"):
        load_scene("nope")


def test_kind_specific_keys_are_required(tmp_path):
    text = """
name = "t"
description = "transmission without sizes"
kind = "transmission"
[network]
builder = "triangular"
[task]
kind = "source"
"""
    with pytest.raises(SceneError) as info:
        load_scene(_write(tmp_path, text))
    assert (info.value.table, info.value.key) == ("network", "sizes")
    with pytest.raises(SceneError, match="strictly increasing"):
        load_scene(
            _write(
                tmp_path,
                text.replace('builder = "triangular"', 'builder = "triangular"\nsizes = [8, 4]'),
            )
        )


def test_scene_is_data_only(tmp_path):
    # TOML has no way to run code, and strings are never evaluated: a string where a number
    # belongs is an error, not an expression
    path = _write(tmp_path, TINY.replace("steps = 5", "steps = \"__import__('os').getpid()\""))
    with pytest.raises(SceneError, match="must be an integer"):
        load_scene(path)


def test_key_reference_lists_every_key():
    text = key_reference()
    for table, cls in _TABLES.items():
        assert f"[{table}]" in text
        for f in dataclasses.fields(cls):
            assert f"  {f.name} (" in text


def test_paper_scene_runs_each_rule_with_its_own_steps():
    from continuum_vs_network.scenes.schema import load_scene
    from continuum_vs_network.scenes.units_learning import plan_learning
    from continuum_vs_network.scenes.units_learning_build import rule_steps

    scene = load_scene("paper")
    assert scene.learning.paper_setting
    assert rule_steps(scene, "gcl") == rule_steps(scene, "gcl_notebook") == 100
    assert rule_steps(scene, "gpc") == rule_steps(scene, "gpc_frozen") == 150
    weights = {
        u.key.split("/")[2]: u.weight for u in plan_learning(scene) if u.key.startswith("train/")
    }
    assert weights["gpc"] == 150 and weights["gcl_notebook"] == 100
    assert any(u.key == "feasibility" for u in plan_learning(scene))
