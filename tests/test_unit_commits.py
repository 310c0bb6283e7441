"""Units record the commit that computed them, and the report says when a result mixes
units of other commits (a unit is reused whatever the code is when the scene reruns)."""

from __future__ import annotations

from scene_texts import TRANS

from continuum_vs_network.report.provenance import unit_commits
from continuum_vs_network.scenes import provenance, store
from continuum_vs_network.scenes.runner import run_scene
from continuum_vs_network.scenes.schema import load_scene


def _environment(commit):
    env = dict(provenance.environment())
    env["commit"] = commit
    return lambda: env


def test_a_rerun_after_a_code_change_reports_the_commits_of_its_units(tmp_path, monkeypatch):
    path = tmp_path / "trans.toml"
    path.write_text(TRANS)
    scene = load_scene(path)
    folder = tmp_path / "results"
    from continuum_vs_network.scenes import runner

    for module in (runner, store):
        monkeypatch.setattr(module, "environment", _environment("a" * 40))
    first = run_scene(scene, folder, progress=False)
    n = len(first.units)
    assert first.provenance.unit_commits == {"a" * 40: n}
    assert unit_commits("a" * 40, first.provenance.unit_commits) == "this commit (all)"
    # the code changes and one unit is lost: only that one is recomputed at the new commit
    (folder / "units" / "transmission__n6.json").unlink()
    for module in (runner, store):
        monkeypatch.setattr(module, "environment", _environment("b" * 40))
    again = run_scene(scene, folder, progress=False)
    assert again.provenance.unit_commits == {"a" * 40: n - 1, "b" * 40: 1}
    text = unit_commits(again.provenance.commit, again.provenance.unit_commits)
    assert text.startswith("this commit: 1; `aaaaaaaaaaaa`: " + str(n - 1))
    assert "--fresh" in text
    assert unit_commits("c" * 40, {"not recorded": 3}).startswith("not recorded: 3")
