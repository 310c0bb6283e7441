"""Eigenstrain and both (modulus + eigenstrain) beside the modulus field on the mechanism task."""

import dataclasses

import numpy as np
import pytest

from continuum_vs_network.continuum.filtered_fields import MaterialExamples, filtered_fields
from continuum_vs_network.continuum.mechanism import rest_example
from continuum_vs_network.learning.rules import CoupledLearning
from continuum_vs_network.scenes.schema import load_scene
from continuum_vs_network.scenes.units_mechanism import build, dof_unit


@pytest.fixture(scope="module")
def scene():
    sc = load_scene("continuum_mechanism")
    return dataclasses.replace(sc, mechanism=dataclasses.replace(sc.mechanism, steps=300))


def test_eigenstrain_without_rest_is_met_trivially(scene):
    _, meta = dof_unit(scene, {"refine": 0, "dof": "eigenstrain", "rest": False}, None)
    assert meta["ratio"] < 1e-6
    assert meta["coupling"] == "decoupled"
    assert meta["outcome"] == "met trivially (decoupled)"


def test_eigenstrain_with_rest_cannot_meet_both_examples(scene):
    _, meta = dof_unit(scene, {"refine": 0, "dof": "eigenstrain", "rest": True}, None)
    assert meta["ratio"] > 0.4  # prestress: a compromise between the two examples
    assert meta["coupling"] == "decoupled"


def test_both_learns_coupled_with_rest(scene):
    _, meta = dof_unit(scene, {"refine": 0, "dof": "both", "rest": True}, None)
    assert meta["ratio"] < 1e-2
    assert meta["coupling"] == "coupled"
    assert meta["rest_error"] < 1e-6


def test_both_step_has_modulus_and_eigenstrain_columns(scene):
    _, task, fm = build(scene, 0)
    med = filtered_fields(fm, 1e-3)
    ex = MaterialExamples((task, rest_example(task)))
    step = CoupledLearning(1.0, dof="both").update(med, ex)
    assert step.raw.shape == (med.n_elements, 4)
    frozen = ~med.learning_mask(task, learn_sources=False, learn_targets=False)
    assert np.all(step.raw[frozen] == 0)
    assert np.isclose(ex.error(med.free_state(ex).target_strain), task.error(
        fm.free_state(task).target_strain))


def test_scale_free_rate_refused_for_eigenstrain(scene):
    _, task, fm = build(scene, 0)
    med = filtered_fields(fm, 1e-3)
    with pytest.raises(ValueError, match="raw rate"):
        CoupledLearning(dof="eigenstrain").update(med, MaterialExamples((task,)))
