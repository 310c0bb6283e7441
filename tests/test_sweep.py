"""Sweeps: grid expansion and validation, points run on Dask match serial runs, resume after
a kill, the tidy table and the report section; the built-in sweep on a 2-worker cluster."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from continuum_vs_network.cli import EXIT, main
from continuum_vs_network.scenes import load_scene
from continuum_vs_network.scenes.compute import KILL_ENV
from continuum_vs_network.scenes.grid import expand, grid_shape, parse_set, with_overrides
from continuum_vs_network.scenes.schema import SceneError, parse_scene

BASE = """
name = "tiny"
description = "tiny Stern-type task"
seed = 3
kind = "learning"
[network]
builder = "triangular"
n_nodes = 16
[task]
kind = "stern"
n_sources = 2
n_targets = 1
[learning]
rules = ["gcl"]
trials = 2
steps = 6
strain_reference = "initial"
"""
SWEEP = """
[sweep]
learning.eta = [0.01, 0.1]
"learning.alpha_gcl" = [0.3, 1.0]
threshold = 0.5
"""


def _file(tmp_path, text, name="tiny.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# -- expansion and validation ---------------------------------------------------------------
def test_grid_is_the_cartesian_product_first_key_slowest(tmp_path):
    scene = load_scene(_file(tmp_path, BASE + SWEEP))
    assert scene.sweep.threshold == 0.5
    scene = with_overrides(scene, parse_set(["seed=0..2", "learning.noise=0.0,0.1"]))
    assert grid_shape(scene.sweep) == (2, 2, 3, 2)
    points = expand(scene)
    assert len(points) == 24 and [p.index for p in points] == list(range(24))
    assert points[0].values == {
        "learning.eta": 0.01,
        "learning.alpha_gcl": 0.3,
        "seed": 0,
        "learning.noise": (0.0,),
    }
    last = points[-1]
    assert (last.scene.learning.eta, last.scene.learning.alpha_gcl) == (0.1, 1.0)
    assert (last.scene.seed, last.scene.learning.noise) == (2, (0.1,))
    assert last.scene.sweep is None and last.scene.learning.steps == 6  # the rest unchanged
    assert len({p.fingerprint for p in points}) == 24
    # a --set axis replaces the scene's own axis of the same key; zipped axes are one dimension
    zipped = with_overrides(
        scene,
        parse_set(["learning.eta=0.2,0.4,0.8", "learning.alpha_gcl=0.05,0.1,0.2"]),
        zip_groups=[["learning.eta", "learning.alpha_gcl"]],
    )
    assert grid_shape(zipped.sweep) == (3, 3, 2)
    pairs = {(p.scene.learning.eta, p.scene.learning.alpha_gcl) for p in expand(zipped)}
    assert pairs == {(0.2, 0.05), (0.4, 0.1), (0.8, 0.2)}


def test_scene_with_sweep_round_trips_through_its_dict(tmp_path):
    zipped = 'zip = [["learning.eta", "learning.alpha_gcl"]]'
    scene = load_scene(_file(tmp_path, BASE + SWEEP + zipped))
    data = {
        k: {kk: vv for kk, vv in v.items() if vv is not None} if isinstance(v, dict) else v
        for k, v in scene.to_dict().items()
    }
    again = parse_scene(data, "again")
    assert again == scene and again.sweep.zip == (("learning.eta", "learning.alpha_gcl"),)


@pytest.mark.parametrize(
    ("sweep", "words"),
    [
        ("learning.etta = [0.1, 0.2]", ["[sweep]", "learning.etta", "unknown key", "alpha_gcl"]),
        ("networkk.n_nodes = [16, 25]", ["[sweep]", "networkk.n_nodes", "unknown sweep key"]),
        ("name = ['a', 'b']", ["[sweep]", "name", "unknown sweep key"]),
        ("learning.eta = [0.1, -0.2]", ["learning.eta[1]", "must be > 0"]),
        ("learning.eta = ['x']", ["learning.eta", "must be a number"]),
        ("learning.rules = ['gcl', 'nope']", ["learning.rules[1]", "'nope' is not one of"]),
        ("learning.eta = [0.1, 0.1]", ["learning.eta", "must not repeat"]),
        ("learning.eta = []", ["learning.eta", "at least one value"]),
        ("seed = '5..2'", ["seed", "range"]),
        ("threshold = 1.5", ["threshold", "between 0 and 1"]),
        (
            "learning.eta = [0.1, 0.2]\nlearning.steps = [1, 2, 3]\n"
            "zip = [['learning.eta', 'learning.steps']]",
            ["zip", "equally many values"],
        ),
    ],
)
def test_bad_sweep_table_names_the_file_and_the_key(tmp_path, sweep, words):
    path = _file(tmp_path, BASE + "\n[sweep]\n" + sweep + "\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert str(path) in msg
    for w in words:
        assert w in msg, (w, msg)


def test_invalid_variant_names_the_point_before_anything_runs(tmp_path):
    scene = load_scene(_file(tmp_path, BASE + SWEEP))
    bad = with_overrides(scene, parse_set(["network.builder=triangular,paper"]))
    with pytest.raises(SceneError) as info:
        expand(bad)
    msg = str(info.value)
    assert "[task] kind" in msg and "sweep point 1" in msg and "network.builder = 'paper'" in msg
    with pytest.raises(SceneError, match=r"command line \(--set\).*learning\.eta.*KEY=VALUE"):
        parse_set(["learning.eta"])
    with pytest.raises(SceneError, match="nothing to sweep"):
        with_overrides(load_scene(_file(tmp_path, BASE, "plain.toml")), {})


def test_cli_sweep_errors_exit_2_and_dry_run_computes_nothing(tmp_path, capsys, monkeypatch):
    from continuum_vs_network.scenes import executor

    monkeypatch.setattr(executor, "CONNECT_TIMEOUT", "1s")
    path = str(_file(tmp_path, BASE + SWEEP))
    out = str(tmp_path / "out")
    assert main(["sweep", path, "--set", "learning.alfa=1,2", "--out", out]) == EXIT["usage"]
    assert "learning.alfa" in capsys.readouterr().err
    assert main(["sweep", path, "--set", "seed=0..4", "--dry-run", "--out", out]) == 0
    err = capsys.readouterr().err
    assert "grid 2 x 2 x 5" in err and "20 grid point(s)" in err
    assert "40 training trial(s), 240 learning steps" in err and "estimated" in err
    assert not (tmp_path / "out" / "results").exists()
    assert main(["export", path, "--out", out]) == EXIT["usage"]  # a sweep has no meshes
    assert "[sweep]" in capsys.readouterr().err
    assert main(["sweep", path, "--scheduler", "tcp://127.0.0.1:9", "--out", out]) == 2
    assert "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'" in capsys.readouterr().err


# -- running ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The tiny sweep run serially (no Dask), without interruption."""
    from continuum_vs_network.scenes.sweep import run_sweep

    tmp = tmp_path_factory.mktemp("serial")
    scene = load_scene(_file(tmp, BASE + SWEEP))
    return scene, run_sweep(scene, tmp / "sweep", workers=1, progress=False)


def _same_table(a, b):
    """Every column but the wall-clock one, exactly."""
    import pandas as pd

    cols = [c for c in a.columns if c != "wall_seconds"]
    pd.testing.assert_frame_equal(a[cols], b[cols], check_exact=True)


def test_table_rows_match_an_independent_training_call(serial, tmp_path):
    from continuum_vs_network.learning.train import train
    from continuum_vs_network.scenes.units_learning import build_rules, builders

    _, result = serial
    df = result.frame()
    assert len(df) == 4 * 2  # four points, two trials each
    assert list(df.columns[:2]) == ["learning.eta", "learning.alpha_gcl"]
    assert df.groupby("point").size().tolist() == [2, 2, 2, 2]
    # point 3 (eta 0.1, alpha 1) trained directly, outside the runner
    point = result.points[3]
    rule = build_rules(point.scene)["gcl"]
    net, task = builders(point.scene)
    h = train(net, task, rule, 6, seeds=(3, 4), progress=False)
    rows = df[df.point == 3]
    assert rows["learning.eta"].tolist() == [0.1, 0.1] and rows["seed"].tolist() == [3, 4]
    error = h.task_error("initial")
    assert (rows["strain_reference"] == "initial").all()
    np.testing.assert_array_equal(rows["final_error"], error[:, 6])
    np.testing.assert_array_equal(rows["initial_error"], error[:, 0])
    np.testing.assert_array_equal(rows["solves"], h.solves[:, 6])
    import pandas as pd

    for k in range(2):
        below = np.flatnonzero(error[k] <= 0.5 * error[k, 0])
        got = rows["steps_to_threshold"].iloc[k]
        assert pd.isna(got) if not below.size else got == below[0]
    assert df["steps_to_threshold"].notna().any()  # the threshold is reached somewhere
    # the coupling verdict is the learning package's measurement of the trained network
    from continuum_vs_network.learning.coupling import measure_coupling, outcome
    from continuum_vs_network.scenes.replication import exact_solver

    for k in range(2):
        c = measure_coupling(
            h.initial[k], h.final[k], h.tasks[k], strain_reference="initial", solver=exact_solver()
        )
        assert rows["coupling"].iloc[k] == c.verdict
        assert rows["source_share"].iloc[k] == c.share
        assert rows["outcome"].iloc[k] == outcome(rows["relative_error"].iloc[k], c.verdict)
    # files: Parquet and CSV hold the same table

    _same_table(pd.read_parquet(result.directory / "table.parquet"), df)
    csv = pd.read_csv(result.directory / "table.csv", keep_default_na=False, na_values=[""])
    np.testing.assert_allclose(csv["final_error"], df["final_error"], rtol=1e-15)


def test_points_on_a_separately_started_scheduler_match_the_serial_run(serial, tmp_path):
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    from continuum_vs_network.scenes.sweep import run_sweep

    scene, reference = serial
    with LocalCluster(
        n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        result = run_sweep(
            scene, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False
        )
    assert result.info["executor"].startswith("Dask at tcp://127.0.0.1")
    assert result.info["workers"] == 2 and result.info["reused"] == 0
    _same_table(result.frame(), reference.frame())


_KILLED = """
from continuum_vs_network.cli import main
main(["sweep", {path!r}, "--workers", "1", "--out", {out!r}, "--quiet"])
"""


def test_killed_sweep_resumes_on_two_workers_to_the_serial_result(serial, tmp_path):
    pytest.importorskip("distributed")
    scene, reference = serial
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-c", _KILLED.format(path=scene.source, out=str(out))],
        capture_output=True,
        text=True,
        timeout=240,
        env={**os.environ, KILL_ENV: "points:2"},
    )
    assert proc.returncode == -9, proc.stderr[-2000:]  # SIGKILL after two points
    folder = out / "results" / "tiny"
    assert len(list((folder / "points").glob("*.json"))) == 2
    assert not (folder / "table.parquet").exists()
    code = main(["sweep", scene.source, "--workers", "2", "--out", str(out), "--quiet"])
    assert code == 0
    info = json.loads((folder / "sweep.json").read_text())
    assert info["reused"] == 2 and info["executor"].startswith("local Dask")
    import pandas as pd

    _same_table(pd.read_parquet(folder / "table.parquet"), reference.frame())
    assert (out / "reports" / "tiny" / "report.md").exists()


def test_builtin_sweep_on_a_two_worker_local_cluster(tmp_path, capsys):
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    small = ["--set", "allostery.n_nodes=[48]", "--set", "allostery.draws=2"]
    small += ["--set", "allostery.steps=3", "--set", "allostery.alpha=1e5,1e6,1e7"]
    code = main(["sweep", "eta_alpha", "--workers", "2", "--out", str(out), *small])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "grid 2 x 3" in err and "6 grid point(s)" in err
    import pandas as pd

    df = pd.read_parquet(out / "results" / "eta_alpha" / "table.parquet")
    assert len(df) == 6 * 2  # one row per point and draw
    assert sorted(set(df["allostery.alpha"])) == [1e5, 1e6, 1e7]
    assert set(df["rule"]) == {"gcl_eta0.01", "gcl_eta1"} and df["final_error"].notna().all()
    report = (out / "reports" / "eta_alpha" / "report.md").read_text()
    assert "fig_phase.png" in report
    assert "The best rate and the nudge" in report
    assert "eta_alpha" in (out / "reports" / "README.md").read_text()


def test_sweep_of_a_plain_scene_keeps_out_of_the_scene_folders(tmp_path, capsys):
    path = str(_file(tmp_path, BASE, "plain.toml"))
    out = tmp_path / "out"
    args = ["sweep", path, "--set", "learning.eta=0.1,0.2", "--set", "learning.steps=2"]
    assert main([*args, "--workers", "1", "--out", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in (out / "results").iterdir()) == ["tiny_sweep"]
    assert (out / "reports" / "tiny_sweep" / "report.md").exists()
    assert not (out / "reports" / "tiny").exists()
    report = (out / "reports" / "tiny_sweep" / "report.md").read_text()
    assert f"cvn sweep {path} --set learning.eta=0.1,0.2 --set learning.steps=2" in report
