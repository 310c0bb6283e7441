"""Provenance: versions, CPU, threads; the run's own outputs never mark the source dirty."""

from __future__ import annotations

import subprocess

import pytest

from continuum_vs_network.scenes.provenance import (
    LIBRARIES,
    blas_threads,
    cpu_model,
    git_commit,
    library_versions,
)


def test_library_versions_are_the_installed_ones():
    import numpy
    import scipy

    v = library_versions()
    assert tuple(v) == LIBRARIES
    assert v["numpy"] == numpy.__version__ and v["scipy"] == scipy.__version__


def test_cpu_and_threads_are_described():
    import numpy  # noqa: F401  (loads the BLAS pool)

    assert "logical cores" in cpu_model()
    assert ": " in blas_threads()


def _git(cwd, *args):
    subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True)


def test_dirty_only_when_the_source_changes(tmp_path):
    try:
        _git(tmp_path, "init", "-q")
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("git not available")
    pkg = tmp_path / "continuum_vs_network"
    pkg.mkdir()
    (pkg / "a.py").write_text("x = 1\n")
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "r.md").write_text("old\n")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "c")
    clean = git_commit(tmp_path)
    assert len(clean) == 40 and "+dirty" not in clean
    (tmp_path / "reports" / "r.md").write_text("regenerated\n")  # the run's own output
    assert git_commit(tmp_path) == clean
    (pkg / "a.py").write_text("x = 2\n")  # the source
    assert git_commit(tmp_path) == clean + "+dirty"
