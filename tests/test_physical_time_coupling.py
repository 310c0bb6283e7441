"""Coupling of the states learned in physical time: each run unit measures its final
learned state by the rule of :mod:`continuum_vs_network.learning.coupling` at the free
states the run reads (a network: sources held by their end nodes; a body: the
continuum_learning scene's measurement), and the learning-speed findings are judged only
when no size or draw is decoupled."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
from physical_time_scenes import tiny_physical_time

from continuum_vs_network import triangular_lattice
from continuum_vs_network.learning import stern_task
from continuum_vs_network.learning.coupling import (
    coupling_verdict,
    measure_coupling,
    source_share,
)
from continuum_vs_network.learning.tasks import AllosteryTask
from continuum_vs_network.learning.time_media import held_free_state
from continuum_vs_network.report.document import Document
from continuum_vs_network.report.findings import NOT_COMPARABLE
from continuum_vs_network.report.sections.physical_time.findings import _findings
from continuum_vs_network.report.sections.physical_time.runs import _by_rule
from continuum_vs_network.scenes.results import from_stored
from continuum_vs_network.scenes.results.physical_time import TimeRunResult, TimeTaskResult
from continuum_vs_network.scenes.runner import run_scene
from continuum_vs_network.scenes.units_physics import lattice
from continuum_vs_network.scenes.units_time_coupling import final_coupling


def _run(tmp_path, media):
    scene = tiny_physical_time(
        "ptc", rules=["gpc", "gcl"], media=media, ratios=[0.3, 3.0], bisections=1,
        relaxation_times=1.0, learning_times=3.0,
    )  # fmt: skip
    result = run_scene(scene, tmp_path / "results")
    units = result.select("physical_time/")
    t = from_stored(units["physical_time/n5/d0/task"], TimeTaskResult)
    net = lattice(scene, 5)
    task = AllosteryTask.create(
        net, t.sources, t.source_strain, t.targets, t.target_strain, pinned=t.pinned
    )
    runs = [from_stored(u, TimeRunResult) for k, u in units.items() if not k.endswith("/task")]
    return scene, result, net, task, runs


@pytest.fixture(scope="module")
def network_scene(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("ptn"), ["network"])


def _held_strains(net, task):
    x = held_free_state(net, task, reference="initial")
    return task.target_strains(net, net.lengths(x)[task.targets], "initial")


def test_final_share_tells_a_trivial_network_from_an_untrained_one():
    """A target whose rest length is its goal, made stiff, sits at its goal whatever the
    sources do (share ~0, decoupled); an untrained network's targets move by the sources
    only (share 1)."""
    net = triangular_lattice(6, 6)
    task = stern_task(net, 2, 1, np.random.default_rng(1), source_std=0.1, target_std=0.1)
    run = SimpleNamespace(rest_length=[net.rest_length], stiffness=[net.stiffness])
    assert final_coupling(net, task, run, "network") == {"source_share": 1.0, "coupling": "coupled"}
    j = task.targets
    rest, stiff = net.rest_length.copy(), net.stiffness.copy()
    rest[j] *= 1.0 + task.target_strain
    stiff[j] = 1e4
    trivial = final_coupling(
        net, task, SimpleNamespace(rest_length=[rest], stiffness=[stiff]), "network"
    )
    assert trivial["source_share"] < 0.01 and trivial["coupling"] == "decoupled"
    assert final_coupling(net, task, None, "network") == {"source_share": None, "coupling": None}


def test_network_unit_carries_the_coupling_of_its_final_learned_network(network_scene):
    _, _, net, task, runs = network_scene
    off = task.with_source_strain(np.zeros(task.n_sources))
    assert {u.rule for u in runs} == {"gpc", "gcl"}
    for m in runs:
        every = m.runs + m.bisection
        assert not any(r["diverged"] for r in every)
        for i, row in enumerate(m.runs):
            rest, stiff = m.fields[f"r{i}/rest_length"], m.fields[f"r{i}/stiffness"]
            assert np.max(np.abs(rest - net.rest_length)) > 1e-6  # it learned something
            trained = net.with_rest_length(rest).with_stiffness(stiff)
            on, base_on = _held_strains(trained, task), _held_strains(net, task)
            share = source_share(on, _held_strains(trained, off), _held_strains(net, off), base_on)
            assert row["source_share"] == pytest.approx(share, rel=1e-9, abs=1e-12)
            assert row["coupling"] == coupling_verdict(share)
            # the measured states are the run's: Eq. 26 at them is the run's first and last
            # recorded error
            desired = task.target_strain
            assert m.error0 == pytest.approx(0.5 * np.sum((base_on - desired) ** 2), rel=1e-8)
            final = m.error0 * m.fields[f"r{i}/error"][-1]
            assert 0.5 * np.sum((on - desired) ** 2) == pytest.approx(final, rel=1e-5)
            # length clamps (measure_coupling, another boundary condition) agree on the verdict
            assert measure_coupling(net, trained, task).verdict == row["coupling"]
        share = min(r["source_share"] for r in every)
        assert m.source_share == share and m.coupling == coupling_verdict(share)


def test_learning_speed_findings_are_judged_only_without_decoupled_units(network_scene, tmp_path):
    scene, result, *_ = network_scene
    rules = _by_rule(result)
    ratios = np.asarray(scene.physical_time.ratios, float)

    def verdicts(units_by_rule):
        doc = Document(tmp_path, 50)
        _findings(doc, units_by_rule, ratios)
        return [f for f in doc.findings if not f.claim.startswith("package")]

    # as measured: the verdict of every unit decides, with the measured reason
    measured = verdicts(rules)
    for name, units in rules.items():
        claims = [f for f in measured if name.upper() in f.claim]
        decoupled = sum(u.coupling == "decoupled" for u in units)
        for f in claims:
            assert (f.verdict == NOT_COMPARABLE) == (decoupled > 0)
            if decoupled:
                assert f"{decoupled} of {len(units)} sizes x draws decoupled" in f.rule
            assert "source share" in " ".join(f.measured)
    # the same units relabelled: decoupled -> not comparable, coupled -> judged
    for label, comparable in (("decoupled", False), ("coupled", True)):
        relabelled = {
            k: [dataclasses.replace(u, coupling=label) for u in v] for k, v in rules.items()
        }
        for f in verdicts(relabelled):
            assert (f.verdict != NOT_COMPARABLE) == comparable, (label, f.claim)
            assert ("decoupled (source share" in f.rule) == (not comparable)


def test_continuum_unit_carries_the_source_share_of_its_final_learned_body(tmp_path):
    from continuum_vs_network.learning.coupling import body_source_share
    from continuum_vs_network.scenes.units_time import _body

    _, _, net, task, runs = _run(tmp_path, ["continuum"])
    body, mtask = _body(net, task)
    assert body_source_share(body, body, mtask) == pytest.approx(1.0)  # untrained
    for m in runs:
        assert m.medium == "continuum"
        for i, row in enumerate(m.runs):
            field = m.fields[f"r{i}/rest_length"]
            assert field.shape == body.eigenstrain.shape and np.any(field != 0)
            trained = body.with_eigenstrain(field).with_modulus(m.fields[f"r{i}/stiffness"])
            share = body_source_share(body, trained, mtask)
            assert row["source_share"] == pytest.approx(share, abs=1e-12)
            final = mtask.error(trained.free_state(mtask).target_strain)
            assert final == pytest.approx(m.error0 * m.fields[f"r{i}/error"][-1], rel=1e-6)
        every = m.runs + m.bisection
        share = min(r["source_share"] for r in every if r["source_share"] is not None)
        assert m.coupling == coupling_verdict(share)


def test_the_report_opens_with_the_measured_coupling_of_every_unit():
    from continuum_vs_network.report.sections.physical_time import _coupling_summary

    def unit(verdict, share):
        return SimpleNamespace(coupling=verdict, source_share=share)

    text = _coupling_summary({"gcl": [unit("decoupled", 0.0), unit("decoupled", 2e-4)]})
    assert "2 of 2 decoupled, shares 0 to 0.0002" in text and "not comparable" in text
    text = _coupling_summary({"gcl": [unit("coupled", 0.9)], "gpc": [unit("coupled", 0.6)]})
    assert "0 of 2 decoupled" in text and "not comparable" not in text
    text = _coupling_summary({"gcl": [unit("coupled", 0.9), unit(None, None)]})
    assert text.startswith("Coupling (learning.coupling) is not measured for every run")
