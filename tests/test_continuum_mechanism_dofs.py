"""Eigenstrain and both (modulus + eigenstrain) beside the modulus field on the mechanism task."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from continuum_vs_network.continuum.filtered_fields import MaterialExamples, filtered_fields
from continuum_vs_network.continuum.mechanism import rest_example
from continuum_vs_network.learning.rules import CoupledLearning
from continuum_vs_network.scenes.schema import load_scene
from continuum_vs_network.scenes.units_mechanism import build, dof_unit, eigenstrain_unit


@pytest.fixture(scope="module")
def scene():
    sc = load_scene("continuum_mechanism")
    return dataclasses.replace(sc, mechanism=dataclasses.replace(sc.mechanism, steps=300))


def test_eigenstrain_without_rest_is_met_trivially(scene):
    run = dof_unit(scene, {"refine": 0, "dof": "eigenstrain", "rest": False}, None)
    assert run.ratio < 1e-6
    assert run.coupling == "decoupled"
    assert run.outcome == "met trivially (decoupled)"


def test_eigenstrain_with_rest_cannot_meet_both_examples(scene):
    run = dof_unit(scene, {"refine": 0, "dof": "eigenstrain", "rest": True}, None)
    assert run.ratio > 0.4  # prestress: a compromise between the two examples
    assert run.coupling == "decoupled"


def test_both_learns_coupled_with_rest(scene):
    run = dof_unit(scene, {"refine": 0, "dof": "both", "rest": True}, None)
    assert run.ratio < 1e-2
    assert run.coupling == "coupled"
    assert run.rest_error < 1e-6


def test_both_step_has_modulus_and_eigenstrain_columns(scene):
    _, task, fm = build(scene, 0)
    med = filtered_fields(fm, 1e-3)
    ex = MaterialExamples((task, rest_example(task)))
    step = CoupledLearning(1.0, dof="both").update(med, ex)
    assert step.raw.shape == (med.n_elements, 4)
    frozen = ~med.learning_mask(task, learn_sources=False, learn_targets=False)
    assert np.all(step.raw[frozen] == 0)
    assert np.isclose(
        ex.error(med.free_state(ex).target_strain), task.error(fm.free_state(task).target_strain)
    )


def test_scale_free_rate_refused_for_eigenstrain(scene):
    _, task, fm = build(scene, 0)
    med = filtered_fields(fm, 1e-3)
    with pytest.raises(ValueError, match="raw rate"):
        CoupledLearning(dof="eigenstrain").update(med, MaterialExamples((task,)))


def _fields(scene, refine=0):
    _, task, filtered = build(scene, refine)
    medium = filtered_fields(filtered, eigenstrain_unit(scene))
    return medium, MaterialExamples((task, rest_example(task)))


def test_optimum_gradient_per_column_matches_finite_differences(scene):
    # the adjoint gradient field_optimum uses (task_gradient * area), every column of "both"
    medium, ex = _fields(scene)
    rng = np.random.default_rng(0)
    n = medium.n_elements
    p = np.column_stack([np.exp(rng.uniform(-1, 1, n)), rng.normal(0, 20, (n, 3))])
    med = medium.with_parameters("both", p)
    g = med.task_gradient(ex, med.free_state(ex), "both") * med.area[:, None]
    mask = med.learning_mask(ex, learn_sources=False, learn_targets=False)
    # elements near the target carry the largest signal; check a few there and elsewhere
    big = np.argsort(-np.abs(g[mask, 1]))[:3]
    elements = np.flatnonzero(mask)[np.r_[big, [0, n // 3]]]
    for i in elements:
        for col in range(4):
            step = 1e-6 * max(1.0, abs(p[i, col]))
            hi, lo = p.copy(), p.copy()
            hi[i, col] += step
            lo[i, col] -= step
            c_hi = ex.error(medium.with_parameters("both", hi).free_state(ex).target_strain)
            c_lo = ex.error(medium.with_parameters("both", lo).free_state(ex).target_strain)
            fd = (c_hi - c_lo) / (2 * step)
            assert fd == pytest.approx(g[i, col], rel=1e-4, abs=1e-9 * np.abs(g).max())


def test_eigenstrain_optimum_is_the_prestress_compromise_and_both_meets_the_task(scene):
    from continuum_vs_network.learning.field_optimum import field_optimum

    medium, ex = _fields(scene)
    eig = field_optimum(medium, ex, dof="eigenstrain")
    # C is quadratic in the eigenstrain, one target: min (d + z)^2 + z^2 = d^2 / 2
    assert eig.ratio == pytest.approx(0.5, abs=1e-6)
    both = field_optimum(medium, ex, dof="both")
    assert both.ratio <= 1e-6
    s = both.medium.modulus
    assert s.min() >= 1e-2 - 1e-12 and s.max() <= 1e2 + 1e-9
    bounded = field_optimum(medium, ex, dof="eigenstrain", eigenstrain_range=(-1.0, 1.0))
    assert np.abs(bounded.medium.strain_design).max() <= 1.0 + 1e-12
    with pytest.raises(ValueError, match="dof"):
        field_optimum(medium, ex, dof="rest")


def test_dof_optimum_unit_flags_eigenstrain_infeasible(scene):
    from continuum_vs_network.report.sections.continuum_mechanism import dof_verdict
    from continuum_vs_network.scenes.units_mechanism import dof_optimum_unit

    eig = dof_optimum_unit(scene, {"refine": 0, "dof": "eigenstrain"}, None)
    both = dof_optimum_unit(scene, {"refine": 0, "dof": "both"}, None)
    assert not eig.feasible and both.feasible
    assert both.rest_error < 1e-6 and both.solves == 2 * both.evaluations
    # dof_verdict reads a dof run's outcome only
    assert dof_verdict(SimpleNamespace(outcome="not learned"), eig) == (
        "infeasible (optimum C/C0 = 0.5)"
    )
    assert dof_verdict(SimpleNamespace(outcome="learned (coupled)"), both) == "learned (coupled)"


def test_balanced_eigenstrain_unit_moves_both_designs_equally(scene):
    """The balanced unit (scene key 0) makes the first GCL step on both fields move the
    eigenstrain design by the modulus design's norm: the eigenstrain signal scales with the
    unit (eps0 = unit * H e, e = 0 at the start); a set unit is taken as it is."""
    assert scene.mechanism.eigenstrain_unit == 0
    unit = eigenstrain_unit(scene)
    medium, ex = _fields(scene)
    raw = CoupledLearning(1.0, dof="both").update(medium, ex).raw
    assert np.linalg.norm(raw[:, 1:]) == pytest.approx(np.linalg.norm(raw[:, 0]), rel=1e-9)
    other = filtered_fields(medium.filtered, 10 * unit)
    raw10 = CoupledLearning(1.0, dof="both").update(other, ex).raw
    assert np.linalg.norm(raw10[:, 1:]) == pytest.approx(10 * np.linalg.norm(raw[:, 0]), rel=1e-9)
    fixed = dataclasses.replace(
        scene, mechanism=dataclasses.replace(scene.mechanism, eigenstrain_unit=1e-3)
    )
    assert eigenstrain_unit(fixed) == 1e-3
