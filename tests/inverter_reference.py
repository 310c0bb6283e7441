"""The independent textbook force inverter of ``benchmarks/bench_inverter.py``, loaded by
path so that the reference code lives in one place (the benchmark) and tests can call it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_inverter.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_inverter", _PATH)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return module


bench_inverter = _load()
textbook_inverter = bench_inverter.textbook_inverter
package_inverter = bench_inverter.package_inverter
