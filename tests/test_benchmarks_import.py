"""Every benchmark script imports: its names still exist in the package (a moved function
left ``bench_builders.py`` importing a name that was gone, found only when run)."""

from __future__ import annotations

import importlib.util
import pathlib

import pytest

BENCHMARKS = sorted((pathlib.Path(__file__).parents[1] / "benchmarks").glob("bench_*.py"))


@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.stem)
def test_a_benchmark_script_imports(path):
    spec = importlib.util.spec_from_file_location(f"_bench_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # definitions and imports only: main() is guarded
    assert callable(module.main)


def test_there_are_benchmarks():
    assert len(BENCHMARKS) >= 10
