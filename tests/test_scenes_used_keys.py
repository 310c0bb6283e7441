"""Scenes name only what they use: an unused key is an error, the settings list only used keys."""

from __future__ import annotations

import pytest

from continuum_vs_network.scenes import SceneError, builtin_names, load_scene, parse_scene

TRANSMISSION = {
    "name": "t",
    "description": "d",
    "kind": "transmission",
    "network": {"builder": "triangular", "sizes": [6]},
    "task": {"kind": "source", "strain": 0.1},
}
LEARNING = {
    "name": "l",
    "description": "d",
    "kind": "learning",
    "network": {"builder": "paper"},
    "task": {"kind": "paper"},
    "learning": {"rules": ["gcl"], "trials": 1, "steps": 2},
}


def _with(base, table, key, value):
    data = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    data.setdefault(table, {})[key] = value
    return data


@pytest.mark.parametrize(
    "base, table, key, value",
    [
        (LEARNING, "network", "sizes", [6]),  # the case of the issue: silently accepted before
        (LEARNING, "network", "size", 6),
        (LEARNING, "network", "n_nodes", 64),  # the paper's patch has a fixed size
        (LEARNING, "network", "fraction", 0.3),  # not a diluted network
        (LEARNING, "task", "strain", 0.2),
        (LEARNING, "task", "anchored", True),  # a rest example only for stern tasks
        (LEARNING, "learning", "sweep_points", 5),  # sweeps off
        (TRANSMISSION, "task", "n_sources", 3),
        (TRANSMISSION, "network", "stiffness_ratios", [10.0]),
        (TRANSMISSION, "solver", "max_seconds", 3.0),
        (TRANSMISSION, "report", "dpi", 80),  # used: no error (control)
    ],
)
def test_an_unused_key_is_rejected_naming_it_and_the_file(base, table, key, value):
    data = _with(base, table, key, value)
    if key == "dpi":
        assert parse_scene(data, "scene.toml").report.dpi == 80
        return
    with pytest.raises(SceneError) as err:
        parse_scene(data, "scene.toml")
    e = err.value
    assert (e.file, e.table, e.key) == ("scene.toml", table, key)
    assert f"[{table}] {key}" in str(e) and "remove it" in str(e)


def test_an_unused_table_is_rejected_the_same_way():
    with pytest.raises(SceneError, match=r"scene.toml: \[dynamics\]: .*remove it"):
        parse_scene(_with(LEARNING, "dynamics", "damping", 1.0), "scene.toml")


def test_settings_list_only_the_keys_the_scene_uses():
    d = parse_scene(TRANSMISSION, "t.toml").to_dict()
    assert set(d["task"]) == {"kind", "strain"}
    assert "stiffness_ratios" not in d["network"] and "fraction" not in d["network"]
    assert "images" in d["report"]
    assert "images" not in load_scene("stability").to_dict()["report"]


@pytest.mark.parametrize("name", builtin_names())
def test_every_builtin_scene_round_trips_through_its_settings(name):
    scene = load_scene(name)
    again = parse_scene(scene.to_dict(), f"{name}.toml")
    assert again == scene
