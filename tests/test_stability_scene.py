"""Stability scene: every case converged or raised, judged by an independent local imbalance."""

from __future__ import annotations

import json

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.continuum.body import LOCKING_RATIO
from continuum_vs_network.report import write_report
from continuum_vs_network.scenes import load_scene, run_scene
from continuum_vs_network.scenes.units_accuracy import lame_error
from continuum_vs_network.scenes.units_stability import local_imbalance

SCENE = """
name = "stabq"
description = "every kind of stability case, tiny"
kind = "stability"
[network]
builder = "triangular"
size = 5
stiffness_ratios = [1e6]
[task]
kind = "source"
strain = 0.2
strains = [-0.999]
[solver]
methods = ["newton"]
rod_stiffnesses = [1e10]
max_seconds = 2.0
[stability]
collinear_heights = [1e-6]
float32 = true
floppy = true
explicit_dt = [0.9, 1.1]
implicit_dt = [100.0]
poisson = [0.3, 0.49]
locking_h = 0.2
learning_stiffness_ratios = [1e3]
learning_steps = 2
"""


@pytest.fixture(scope="module")
def stability(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("stab")
    (tmp / "s.toml").write_text(SCENE)
    result = run_scene(load_scene(tmp / "s.toml"), tmp / "results", progress=False)
    folder = tmp / "reports" / "stabq"
    write_report(result, folder, render=False)
    return result, folder


def test_local_imbalance_is_zero_at_equilibrium_and_sees_a_soft_region():
    net = cvn.triangular_lattice(5, 5, noise=0.1, rng=np.random.default_rng(0))
    pins = cvn.default_pins(net, avoid=[10])
    eq = cvn.relax(net, pinned=pins, clamped={10: 1.2 * float(net.rest_length[10])}, tol=1e-12)
    assert local_imbalance(net, eq.positions, ~pins, [10]) < 1e-10
    # without removing the clamp's force the clamped nodes are far from balance
    assert local_imbalance(net, eq.positions, ~pins) > 1e-3
    # stiff springs elsewhere do not hide a soft node's imbalance: scale is per node
    stiff = net.with_stiffness(np.where(np.arange(net.n_springs) < 20, 1e9, 1.0))
    x = net.positions.copy()
    soft_node = int(np.setdiff1d(np.arange(net.n_nodes), stiff.springs[:20].ravel())[-1])
    x[soft_node] += 0.01
    assert local_imbalance(stiff, x, ~pins) > 1e-3


def test_p1_warning_threshold_follows_the_measured_locking():
    base = lame_error("P1", 0.2, 0.3)["error"]
    locked = lame_error("P1", 0.2, 0.49)
    assert locked["error"] > 2 * base and locked["warned"]
    mild = lame_error("P1", 0.2, 0.4)
    assert mild["error"] < 1.5 * base and not mild["warned"]
    assert 2 * 0.4 / (1 - 2 * 0.4) < LOCKING_RATIO < 2 * 0.49 / (1 - 2 * 0.49)


def test_every_case_is_converged_or_raised(stability):
    result, _ = stability
    rows = {k: u.meta for k, u in result.units.items() if k.count("/") == 2}
    assert rows["stability/floppy/newton"]["error"].startswith("ValueError")
    for key in ("stiff_1e+06", "rod_1e+10", "strain_-0.999", "collinear_1e-06", "float32"):
        m = rows[f"stability/{key}/newton"]
        assert m["converged"] and m["imbalance"] <= 1e-9, key
    assert rows["stability/collinear_1e-06/newton"]["check"] < 1e-9
    assert rows["stability/float32/newton"]["check"] < 1e-9
    d = {k.rsplit("/", 1)[1]: u.meta for k, u in result.units.items() if "/dynamics/" in k}
    assert d["explicit_1.1"]["error"].startswith("ValueError")
    assert not d["explicit_0.9"]["error"]
    assert d["explicit_0.9"]["energy_end"] < d["explicit_0.9"]["energy_start"]
    assert not d["implicit_100"]["error"]  # backward Euler: L-stable at 100x the limit


def test_findings_are_computed_and_stored(stability):
    _, folder = stability
    meta = json.loads((folder / "report.json").read_text())
    verdicts = {f["claim"]: f["verdict"] for f in meta["findings"]}
    assert verdicts["P1 warns where locking inflates its error, and not elsewhere"] == "reproduced"
    assert verdicts["README: floppy networks raise a ValueError that counts their zero modes"] == (
        "reproduced"
    )
    assert all(v in ("reproduced", "not reproduced", "contradicted") for v in verdicts.values())


def test_newmark_far_above_the_explicit_limit_on_the_stiff_lattice_completes():
    """The stability scene's hardest implicit case (Newmark at 1e5 x the explicit limit, a
    fifth of the springs 1e6 x stiffer): every step's Newton converges once a correction
    that cuts the force less than 4-fold switches the step to full Newton (without that
    switch, chord and Newton steps alternated past 200 iterations at t = 283)."""
    from continuum_vs_network.scenes.schema import load_scene
    from continuum_vs_network.scenes.units_stability import dynamics_unit

    run = dynamics_unit(load_scene("stability"), {"scheme": "newmark", "f": 1e5}, None)
    assert run.error == ""
    assert np.isfinite(run.energy_end)
