"""The runner computes only what a scene names, resumes after a kill, and runs in parallel
with the same results as serially."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from continuum_vs_network.learning.states import Tracker
from continuum_vs_network.scenes import load_result, load_scene, run_scene
from continuum_vs_network.scenes.compute import KILL_ENV, SceneRunError

LEARN = """
name = "learn"
description = "tiny learning scene"
seed = 7
kind = "learning"

[network]
builder = "paper"

[task]
kind = "paper"

[learning]
rules = ["gcl_floor", "gpc"]
trials = 2
steps = 8
checkpoint_every = 3
sweeps = true
sweep_points = 4
compare_gradient = true
"""

GPC = """
name = "gpc"
description = "GPC without measurements"
seed = 3
kind = "learning"

[network]
builder = "paper"

[task]
kind = "paper"

[learning]
rules = ["gpc"]
trials = 2
steps = 6
measure = false

[report]
dpi = 45
"""

TRANSMISSION = """
name = "trans"
description = "tiny transmission scene"
kind = "transmission"

[network]
builder = "triangular"
sizes = [6, 16]

[task]
kind = "source"
strain = 0.05
"""

CONTINUUM = """
[continuum]
refine = 1
order = 2
"""

# wall-clock columns and work counters differ between runs (Newton sizes its reuse of a
# factorisation from measured times); every measured quantity must agree
_CLOCKS = {"seconds", "measure_seconds", "iterations", "factorisations", "solves"}


def _scene(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return load_scene(path), path


def _same(a, b, *, rtol=1e-9):
    """Two results hold the same histories (clocks aside) and the same unit arrays.

    Not bit for bit: Newton's budget for reusing a factorisation (network/newton.py) is set
    from measured solve times, so iterates can differ in the last bits between runs; every
    number agrees to far below the solver tolerance.
    """
    assert a.units.keys() == b.units.keys()
    assert a.histories.keys() == b.histories.keys()
    for g in a.histories:
        ha, hb = a.histories[g], b.histories[g]
        np.testing.assert_array_equal(ha.seeds, hb.seeds)
        np.testing.assert_array_equal(ha.completed, hb.completed)
        for name in ha.data:
            if name not in _CLOCKS:
                # the residual is solver round-off below the tolerance (1e-10 F, F ~ 1e2)
                atol = 1e-7 if name == "residual" else 0.0
                np.testing.assert_allclose(
                    ha.data[name], hb.data[name], rtol=rtol, atol=atol, err_msg=f"{g}: {name}"
                )
        for na, nb in zip(ha.final, hb.final):
            np.testing.assert_allclose(na.rest_length, nb.rest_length, rtol=rtol, atol=0)
    for key in a.units:
        ua, ub = a.units[key], b.units[key]
        assert ua.arrays.keys() == ub.arrays.keys()
        for name in ua.arrays:
            np.testing.assert_allclose(
                ua.arrays[name], ub.arrays[name], rtol=1e-8, atol=1e-9, err_msg=f"{key}: {name}"
            )


def _subprocess(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=240,
        env={**os.environ, **(env or {})},
    )


# -- only what the scene names ----------------------------------------------------------------
_PROBE = """
import json, sys
from continuum_vs_network.scenes import load_scene, run_scene
from continuum_vs_network.report import write_report
for path, out, report in {runs!r}:
    scene = load_scene(path)
    result = run_scene(scene, out, progress=False)
    if report:
        write_report(result, out + "/report")
    print(json.dumps({{m: m in sys.modules for m in
                      ("skfem", "pyvista", "vtk", "meshio", "torch", "matplotlib")}}))
"""


def test_scenes_import_only_what_they_use(tmp_path):
    runs = []
    for name, text in (("gpc", GPC), ("bare", TRANSMISSION), ("fem", TRANSMISSION + CONTINUUM)):
        _, path = _scene(tmp_path, text, f"{name}.toml")
        runs.append((str(path), str(tmp_path / name), name == "gpc"))
    proc = _subprocess(_PROBE.format(runs=runs))
    assert proc.returncode == 0, proc.stderr[-3000:]
    learn, bare, fem = (json.loads(line) for line in proc.stdout.strip().splitlines()[-3:])
    # no [continuum]: no scikit-fem; no images: no pyvista/vtk; no [export]: no meshio;
    # no paper relaxation: no torch. The report itself needs matplotlib.
    assert learn == {
        "skfem": False,
        "pyvista": False,
        "vtk": False,
        "meshio": False,
        "torch": False,
        "matplotlib": True,
    }
    assert bare["skfem"] is False and bare["meshio"] is False
    # the same scene with a [continuum] table does import it: the probe can tell
    assert fem["skfem"] is True


def _count_free_solves(monkeypatch, scene, tmp_path):
    calls = []
    original = Tracker.solve

    def spy(self, net, pinned, clamped, x0, **kw):
        calls.append(frozenset(clamped))
        return original(self, net, pinned, clamped, x0, **kw)

    monkeypatch.setattr(Tracker, "solve", spy)
    result = run_scene(scene, tmp_path, progress=False)
    sources = [{int(s) for s in t.sources} for t in result.histories["newton/gpc/noise0"].tasks]
    free = sum(1 for c in calls if any(c == s for s in sources))
    return free, len(calls), result


def test_prospective_configuration_solves_no_free_state_it_does_not_use(tmp_path, monkeypatch):
    scene, _ = _scene(tmp_path, GPC)
    free, total, result = _count_free_solves(monkeypatch, scene, tmp_path / "a")
    assert free == 0
    assert total == 2 * 6  # one clamped state per step and trial, nothing else
    h = result.histories["newton/gpc/noise0"]
    assert np.all(np.isnan(h.error_initial)) and np.all(np.isfinite(h.energy_clamped))
    # with measurements the free state is solved after every step (the spy sees it)
    measured = scene.learning.__class__(**{**scene.learning.__dict__, "measure": True})
    scene2 = scene.__class__(**{**scene.__dict__, "learning": measured})
    free, total, _ = _count_free_solves(monkeypatch, scene2, tmp_path / "b")
    # per trial: 6 + 1 measured free states, and the coupling measurement's sweep of the
    # trained network (5 source scales) and the initial network with the sources off and on
    assert free == 2 * (6 + 1) + 2 * (5 + 2) and total == 2 * 6 + free


def test_no_export_table_writes_no_mesh(tmp_path):
    from continuum_vs_network.cli import main

    _, path = _scene(tmp_path, TRANSMISSION + CONTINUUM)
    assert main(["run", str(path), "--out", str(tmp_path), "--quiet"]) == 0
    assert (tmp_path / "reports" / "trans" / "report.md").exists()
    assert not (tmp_path / "meshes").exists()
    # with [export] the largest lattice and its continuum are written and read back
    import meshio

    _, path = _scene(tmp_path, TRANSMISSION + CONTINUUM + "[export]\n", "export.toml")
    assert main(["run", str(path), "--out", str(tmp_path), "--quiet", "--no-report"]) == 0
    folder = tmp_path / "meshes" / "trans"
    assert sorted(p.name for p in folder.iterdir()) == ["continuum_n16.vtu", "network_n16.vtu"]
    result = load_result(load_scene(path), tmp_path / "results" / "trans")
    a = result.units["transmission/n16"].arrays
    net_mesh = meshio.read(folder / "network_n16.vtu")
    np.testing.assert_allclose(
        net_mesh.point_data["displacement"][:, :2], a["net/x"] - a["net/positions"], atol=1e-12
    )
    strain = net_mesh.cell_data["strain"][0]
    src = int(a["net/sources"][0])
    assert strain[src] == pytest.approx(0.05, abs=1e-9)  # the clamped source


# -- resume --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The LEARN scene run once, serially and without interruption."""
    tmp = tmp_path_factory.mktemp("reference")
    scene, path = _scene(tmp, LEARN)
    return scene, path, run_scene(scene, tmp / "result", progress=False)


_RUN = """
from continuum_vs_network.scenes import load_scene, run_scene
run_scene(load_scene({path!r}), {out!r}, progress=False)
"""


@pytest.mark.parametrize("kill", ["steps:12", "units:5"])
def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, kill, reference):
    scene, path, fresh = reference
    out = tmp_path / "killed"
    proc = _subprocess(_RUN.format(path=str(path), out=str(out)), env={KILL_ENV: kill})
    assert proc.returncode == -9, proc.stderr[-2000:]  # SIGKILL: nothing could clean up
    assert not (out / "run.json").exists()
    done = list((out / "units").glob("*.json"))
    assert 0 < len(done) < 8  # partial: some of the 8 units, not all
    if kill.startswith("steps"):
        # killed at step 4 of trial 1 of the first run, after its checkpoint at step 3
        assert list((out / "checkpoints").glob("train__newton__gcl_floor__noise0__trial1-*"))
    resumed = run_scene(scene, out, progress=False)
    assert resumed.provenance.reused == len(done)
    _same(resumed, fresh)
    assert not (out / "checkpoints").exists()


def test_changed_settings_recompute_only_what_they_affect(tmp_path, reference):
    import shutil

    scene, _, first = reference
    assert first.provenance.reused == 0
    shutil.copytree(first.directory, tmp_path / "r")
    again = run_scene(scene, tmp_path / "r", progress=False)
    assert again.provenance.reused == again.provenance.units
    # the sweep resolution does not affect training: only the sweeps are recomputed
    scene2, _ = _scene(tmp_path, LEARN.replace("sweep_points = 4", "sweep_points = 5"), "b.toml")
    third = run_scene(scene2, tmp_path / "r", progress=False)
    assert third.provenance.reused == third.provenance.units - 2
    assert third.units["sweeps/newton/gpc"].arrays["source_strain"].shape == (2, 5)


# -- parallel ------------------------------------------------------------------------------------
def test_two_workers_give_the_serial_result(tmp_path, reference):
    scene, _, serial = reference
    parallel = run_scene(scene, tmp_path / "parallel", workers=2, progress=False)
    assert parallel.provenance.workers == 2
    _same(serial, parallel)


def test_failing_unit_raises_scene_run_error_and_keeps_the_rest(tmp_path):
    text = """
name = "explode"
description = "an explicit step far above the stability limit"
kind = "relaxation"
[network]
builder = "triangular"
sizes = [4, 5]
[dynamics]
scheme = "explicit"
steps_per_tau = 2
"""
    scene, _ = _scene(tmp_path, text)
    with pytest.raises(SceneRunError, match="relaxation/n4") as info:
        run_scene(scene, tmp_path / "r", progress=False)
    assert isinstance(info.value.cause, ValueError)
    assert "dt" in str(info.value.cause)


def test_transmission_and_relaxation_compare_network_and_continuum(tmp_path):
    # physics the report rests on: the continuum of the lattice's shape carries strain like
    # the lattice, and relaxes at the rate of the lattice with its drag smeared per area
    scene, _ = _scene(tmp_path, TRANSMISSION + CONTINUUM)
    result = run_scene(scene, tmp_path / "t", progress=False)
    meta = result.units["transmission/n16"].meta
    assert meta["correlation"] > 0.97
    assert 1.7 < meta["network_exponent"] < 2.5 and 1.7 < meta["continuum_exponent"] < 2.5
    text = """
name = "relax"
description = "relaxation of small lattices"
kind = "relaxation"
[network]
builder = "triangular"
sizes = [6, 8]
[dynamics]
damping = 2.0
[continuum]
refine = 1
order = 2
material = "lattice"
"""
    scene, _ = _scene(tmp_path, text, "relax.toml")
    result = run_scene(scene, tmp_path / "r", progress=False)
    for n in (6, 8):
        m = result.units[f"relaxation/n{n}"].meta
        assert m["continuum_tau_mode"] == pytest.approx(m["network_tau_mode"], rel=0.08)
        assert m["continuum_tau"] == pytest.approx(m["network_tau"], rel=0.15)
    small, big = (result.units[f"relaxation/n{n}"].meta for n in (6, 8))
    assert big["network_tau_mode"] > 1.5 * small["network_tau_mode"]  # ~ n^2 (diffusive)
