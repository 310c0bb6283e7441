"""One executor for every parallel run: serial, a local Dask cluster, a running scheduler."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from continuum_vs_network.scenes import load_scene, run_scene
from continuum_vs_network.scenes import runner as runner_module
from continuum_vs_network.scenes.executor import (
    DaskExecutor,
    SerialExecutor,
    TaskError,
    open_executor,
)

pytest.importorskip("distributed")


def _square(x: int) -> int:
    return x * x


def _fail_on(x: int, bad: int) -> int:
    if x == bad:
        raise ValueError(f"bad value {x}")
    return x


def _blas_threads() -> int:
    from threadpoolctl import threadpool_info

    return max([p["num_threads"] for p in threadpool_info()] or [1])


@pytest.fixture(scope="module")
def scheduler():
    """A 2-worker cluster started separately from the code under test; its address.

    Its workers are started with two BLAS threads (not Dask's default of one), so that the
    executor's own pinning is what the BLAS test sees.
    """
    import cloudpickle
    import dask
    from distributed import LocalCluster

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers cannot import tests/
    two = {"OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2", "MKL_NUM_THREADS": "2"}
    with (
        dask.config.set({"distributed.nanny.pre-spawn-environ": {}}),
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=50,
            env=two,
        ) as cluster,
    ):
        yield cluster.scheduler_address


def test_serial_executor_runs_in_order_and_names_the_failing_task():
    got = []
    with open_executor(workers=1) as ex:
        assert isinstance(ex, SerialExecutor)
        ex.run(_square, [(i,) for i in range(5)], on_result=lambda i, v: got.append((i, v)))
        assert got == [(i, i * i) for i in range(5)]
        with pytest.raises(TaskError) as info:
            ex.run(_fail_on, [(i, 2) for i in range(5)])
    assert info.value.index == 2 and isinstance(info.value.cause, ValueError)


@pytest.mark.parametrize("workers", [0, -1, 1.5, True])
def test_bad_worker_counts_are_refused(workers):
    with pytest.raises(ValueError, match="workers"):
        open_executor(workers=workers)


def test_dask_executor_on_a_running_scheduler(scheduler):
    got = {}
    with open_executor(scheduler=scheduler) as ex:
        assert isinstance(ex, DaskExecutor) and ex.workers == 2
        ex.run(_square, [(i,) for i in range(8)], on_result=got.__setitem__)
        assert got == {i: i * i for i in range(8)}
        # BLAS is pinned to one thread inside every task; outside the executor the same
        # workers run two
        threads = {}
        ex.run(_blas_threads, [()] * 4, on_result=threads.__setitem__)
        assert set(threads.values()) == {1}
        assert ex.client.submit(_blas_threads, pure=False).result() == 2
        with pytest.raises(TaskError) as info:
            ex.run(_fail_on, [(i, 3) for i in range(6)])
    assert info.value.index == 3 and "bad value 3" in str(info.value.cause)


LEARN = """
name = "learn"
description = "tiny learning scene"
seed = 4
kind = "learning"
[network]
builder = "triangular"
n_nodes = 16
[task]
kind = "stern"
n_sources = 2
n_targets = 1
[learning]
rules = ["gcl", "gpc"]
trials = 2
steps = 4
strain_reference = "initial"
"""


def test_scene_workers_run_through_the_executor(tmp_path, monkeypatch, scheduler):
    path = tmp_path / "learn.toml"
    path.write_text(LEARN)
    scene = load_scene(path)
    opened = []
    real = runner_module.open_executor

    def spy(**kw):
        ex = real(**kw)
        opened.append((kw, type(ex).__name__))
        return ex

    monkeypatch.setattr(runner_module, "open_executor", spy)
    serial = run_scene(scene, tmp_path / "serial", progress=False)
    assert opened == []  # one worker: no executor, no Dask
    remote = run_scene(scene, tmp_path / "remote", scheduler=scheduler, progress=False)
    assert opened == [
        (
            {"workers": 1, "scheduler": scheduler, "serial_fallback": False, "log": None},
            "DaskExecutor",
        )
    ]
    assert remote.provenance.workers == 2
    for key, h in serial.histories.items():
        np.testing.assert_array_equal(h.error_initial, remote.histories[key].error_initial)
        np.testing.assert_array_equal(h.iterations, remote.histories[key].iterations)


_IMPORTS = """
import json, sys
import continuum_vs_network
from continuum_vs_network.scenes import load_scene, run_scene
from continuum_vs_network.scenes.grid import expand, parse_set, with_overrides
scene = with_overrides(load_scene({path!r}), parse_set(["learning.eta=0.1,0.2"]))
points = expand(scene)
run_scene(points[0].scene, {out!r}, progress=False)
print(json.dumps({{m: m in sys.modules for m in ("dask", "distributed", "pandas", "pyarrow")}}))
"""


def test_serial_runs_and_sweep_expansion_import_no_dask_or_pandas(tmp_path):
    path = tmp_path / "learn.toml"
    path.write_text(LEARN)
    proc = subprocess.run(
        [sys.executable, "-c", _IMPORTS.format(path=str(path), out=str(tmp_path / "r"))],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == {
        "dask": False,
        "distributed": False,
        "pandas": False,
        "pyarrow": False,
    }


def test_units_modules_do_not_import_the_runner():
    """No import circle: the units_* modules take their types from scenes/units.py."""
    import ast
    from pathlib import Path

    import continuum_vs_network.scenes as scenes

    folder = Path(scenes.__file__).parent
    modules = sorted(folder.glob("units_*.py"))
    assert len(modules) >= 4
    for path in [*modules, folder / "units.py"]:
        tree = ast.parse(path.read_text())
        imported = {
            node.module
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and node.module is not None
        }
        assert "runner" not in imported, f"{path.name} imports the runner"


def test_report_defaults_to_one_worker_per_core_when_dask_is_there(monkeypatch):
    import importlib.util

    from continuum_vs_network.cli_parser import build_parser
    from continuum_vs_network.scenes import executor

    assert build_parser().parse_args(["report"]).workers is None  # resolved when run
    assert build_parser().parse_args(["run", "x.toml"]).workers == 1
    real = importlib.util.find_spec
    monkeypatch.setattr(executor, "machine_workers", lambda: 12)
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda n, *a: None if n == "distributed" else real(n, *a)
    )
    assert executor.default_workers() == 1  # no Dask: serial
    monkeypatch.setattr(importlib.util, "find_spec", real)
    assert executor.default_workers() == executor.DEFAULT_WORKERS_MAX == 8


def test_a_local_cluster_that_does_not_start_falls_back_to_serial_only_when_allowed(
    tmp_path, monkeypatch
):
    path = tmp_path / "learn.toml"
    path.write_text(LEARN)
    scene = load_scene(path)

    import distributed

    def broken(**kw):
        raise OSError("no sockets here")

    monkeypatch.setattr(distributed, "LocalCluster", broken)
    messages = []
    fallback = run_scene(
        scene, tmp_path / "f", workers=2, serial_fallback=True, progress=False, log=messages.append
    )
    assert fallback.provenance.workers == 1
    assert any("did not start (no sockets here); serial" in m for m in messages)
    serial = run_scene(scene, tmp_path / "s", progress=False)
    for key, h in serial.histories.items():
        np.testing.assert_array_equal(h.error_initial, fallback.histories[key].error_initial)
    with pytest.raises(OSError, match="no sockets"):
        run_scene(scene, tmp_path / "x", workers=2, progress=False)


@pytest.mark.filterwarnings("ignore:Port 8787 is already in use")  # the fixture's cluster
def test_local_workers_have_no_memory_cap_that_would_restart_a_large_unit():
    """Dask's default splits the machine's memory evenly between the workers and restarts
    one past its share; a unit that runs serially must not be killed for running beside
    others."""
    with open_executor(workers=2) as ex:
        got = {}
        ex.run(_square, [(i,) for i in range(4)], on_result=got.__setitem__)
        limits = [w.get("memory_limit") for w in ex.client.scheduler_info()["workers"].values()]
    assert got == {i: i * i for i in range(4)}
    assert limits == [0, 0]
