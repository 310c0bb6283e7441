"""The continuum_mechanism scene: schema, plan, refinement measure, a tiny run."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.scenes import load_scene


def test_builtin_scenes_load_and_plan():
    from continuum_vs_network.scenes.runner import plan

    short = load_scene("continuum_mechanism")
    full = load_scene("continuum_mechanism_full")
    assert short.report.default and not full.report.default
    keys = [u.key for u in plan(short)]
    assert "continuum_mechanism/inverter" in keys and "continuum_mechanism/simp" in keys
    for r in range(3):  # h, h/2 and h/4 in the default scene
        assert f"continuum_mechanism/learn/refine{r}/gcl/adaptive" in keys
    assert len([u for u in plan(full) if "/optimum/" in u.key]) == 3


def test_refinement_change_is_zero_for_equal_fields():
    from continuum_vs_network.report.sections.continuum_mechanism import change

    a = np.array([1.0, 1.0, 2.0])
    assert change(np.full(3, 10.0), np.full(3, 10.0), a) == 0
    assert change(np.full(3, 100.0), np.full(3, 10.0), a) == pytest.approx(1.0)


@pytest.mark.slow
def test_tiny_scene_runs(tmp_path):
    import dataclasses

    from continuum_vs_network.scenes.runner import run_scene

    scene = load_scene("continuum_mechanism")
    m = dataclasses.replace(
        scene.mechanism, refine=1, steps=20, simp_iterations=5, inverter_iterations=5,
        inverter_h=0.2, rates=("adaptive",),
    )  # fmt: skip
    res = run_scene(dataclasses.replace(scene, mechanism=m), tmp_path)
    assert res.units["continuum_mechanism/inverter"].meta["solves"] == 6
    assert res.units["continuum_mechanism/learn/refine1/gcl/adaptive"].arrays["coarse"].shape == (
        256,
    )
