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
    for r in range(3):  # h, h/2 and h/4 in the default scene, each with its optimum
        assert f"continuum_mechanism/learn/refine{r}/gcl/scaled" in keys
        assert f"continuum_mechanism/optimum/refine{r}" in keys
    assert "continuum_mechanism/simp_solid" in keys
    assert "continuum_mechanism/lattice/refine2" in keys
    assert len([u for u in plan(full) if "/optimum/" in u.key]) == 3


def test_refinement_change_is_zero_for_equal_fields():
    from continuum_vs_network.report.sections.continuum_mechanism import change

    a = np.array([1.0, 1.0, 2.0])
    assert change(np.full(3, 10.0), np.full(3, 10.0), a) == 0
    assert change(np.full(3, 100.0), np.full(3, 10.0), a) == pytest.approx(1.0)


@pytest.mark.slow
def test_tiny_scene_runs(tmp_path):
    import dataclasses

    from continuum_vs_network.scenes.results import from_stored
    from continuum_vs_network.scenes.results.mechanism import InverterResult, LearnResult
    from continuum_vs_network.scenes.runner import run_scene

    scene = load_scene("continuum_mechanism")
    m = dataclasses.replace(
        scene.mechanism, refine=1, steps=20, simp_iterations=5, inverter_iterations=5,
        inverter_h=0.2, rates=("adaptive",),
    )  # fmt: skip
    res = run_scene(dataclasses.replace(scene, mechanism=m), tmp_path)
    inverter = from_stored(res.units["continuum_mechanism/inverter"], InverterResult)
    assert inverter.solves == 6
    learned = from_stored(res.units["continuum_mechanism/learn/refine1/gcl/adaptive"], LearnResult)
    assert learned.coarse.shape == (256,)


def test_lattice_beside_the_continuum_learns_the_same_task():
    import dataclasses

    from continuum_vs_network.scenes.units_mechanism import lattice, lattice_unit

    scene = load_scene("continuum_mechanism")
    net, task, _ = lattice(scene, 0)
    mid = net.positions[net.springs].mean(axis=1)
    assert np.hypot(*(mid[task.sources[0]] - (0.4, 0.5))) <= 0.125
    assert np.hypot(*(mid[task.targets[0]] - (1.6, 0.5))) <= 0.125
    assert task.target_strain[0] == pytest.approx(-0.2 * task.source_strain[0])
    m = dataclasses.replace(scene.mechanism, steps=60)
    run = lattice_unit(dataclasses.replace(scene, mechanism=m), {"refine": 0}, None)
    assert run.ratio <= 1e-3 and run.coupling == "coupled"
