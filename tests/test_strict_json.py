"""Stored records are strict JSON: non-finite values are null, named, and restored on load."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from continuum_vs_network.io.strict_json import NON_FINITE_KEY, dumps_record, loads_record
from continuum_vs_network.report import write_report
from continuum_vs_network.scenes import load_result, load_scene, run_scene


def _strict(text: str, where: str = "") -> dict:
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"{where}: bare {c} in JSON"))


def test_non_finite_values_become_null_and_come_back():
    record = {
        "seconds": math.nan,
        "meta": {"error": np.float64("nan"), "critical_high": math.inf, "eta": None},
        "series": np.array([1.0, -np.inf, np.nan]),
        "a/b~c": [0.5, (math.inf,)],
        "count": np.int64(3),
    }
    text = dumps_record(record, sort_keys=True)
    stored = _strict(text)
    assert stored["seconds"] is None and stored["meta"]["error"] is None
    assert stored["meta"]["critical_high"] is None and stored["series"] == [1.0, None, None]
    assert stored[NON_FINITE_KEY] == {
        "/seconds": "nan",
        "/meta/error": "nan",
        "/meta/critical_high": "inf",
        "/series/1": "-inf",
        "/series/2": "nan",
        "/a~1b~0c/1/0": "inf",
    }
    back = loads_record(text)
    assert NON_FINITE_KEY not in back
    assert math.isnan(back["seconds"]) and math.isnan(back["meta"]["error"])
    assert back["meta"]["critical_high"] == math.inf and back["meta"]["eta"] is None
    assert back["series"][:2] == [1.0, -math.inf] and math.isnan(back["series"][2])
    assert back["a/b~c"] == [0.5, [math.inf]] and back["count"] == 3


def test_finite_record_is_written_as_plain_json():
    record = {"x": 1.5, "y": None, "z": [1, 2]}
    assert dumps_record(record) == json.dumps(record)
    assert loads_record(dumps_record(record)) == record


def test_a_non_finite_value_that_escapes_the_conversion_fails_loudly():
    class Odd:
        pass

    with pytest.raises(ValueError, match="Out of range float"):
        dumps_record({"x": Odd()}, default=lambda _: math.nan)
    with pytest.raises(ValueError, match="reserved"):
        dumps_record({NON_FINITE_KEY: 1})


def test_old_records_with_bare_nan_tokens_still_load():
    back = loads_record('{"error": NaN, "high": Infinity, "low": -Infinity, "eta": null}')
    assert math.isnan(back["error"]) and back["high"] == math.inf and back["low"] == -math.inf
    assert back["eta"] is None


# -- end to end: the cheapest scene with a not-applicable value ---------------------------------
SCENE = """
name = "acc"
description = "tiny accuracy scene: the coarse explicit step is refused (not applicable)"
kind = "accuracy"
[accuracy]
elements = ["P1"]
mesh_sizes = [0.4]
schemes = ["explicit"]
problems = ["overdamped"]
steps = [8, 32]
size = 4
"""
REFUSED = "accuracy/network/overdamped/explicit/n8"


def _table_row(report: str, steps: str) -> list[str]:
    rows = [
        r
        for r in report.splitlines()
        if r.startswith(f"| network | overdamped | explicit | {steps} |")
    ]
    assert len(rows) == 1
    return [c.strip() for c in rows[0].strip("|").split("|")]


def _timing_free(report: str) -> list[str]:
    return [line for line in report.splitlines() if "started" not in line and "seconds" not in line]


def test_scene_results_are_strict_json_and_render_as_before(tmp_path):
    (tmp_path / "acc.toml").write_text(SCENE)
    scene = load_scene(tmp_path / "acc.toml")
    result = run_scene(scene, tmp_path / "results", progress=False)
    write_report(result, tmp_path / "report", render=False)
    files = sorted(tmp_path.rglob("*.json"))
    assert len(files) >= 6  # scene.json, run.json, 3 unit records, report.json
    for path in files:
        _strict(path.read_text(), str(path))
    record_path = tmp_path / "results" / "units" / (REFUSED.replace("/", "__") + ".json")
    stored = _strict(record_path.read_text())
    assert stored["meta"]["refused"].startswith("ValueError")
    assert stored["meta"]["error"] is None and stored["meta"]["seconds"] is None
    assert stored[NON_FINITE_KEY] == {"/meta/error": "nan", "/meta/seconds": "nan"}

    # in memory the not-applicable values are NaN again, and the report shows "-"
    loaded = load_result(scene, tmp_path / "results")
    meta = loaded.units[REFUSED].meta
    assert math.isnan(meta["error"]) and math.isnan(meta["seconds"])
    report = (tmp_path / "report" / "report.md").read_text()
    row = _table_row(report, "8")
    assert row[-3:-1] == ["-", "-"] and row[-1].startswith("ValueError")
    assert "-" not in _table_row(report, "32")[-3:-1]

    # a record written before strict JSON (bare NaN tokens) loads and renders the same report
    old = json.loads(record_path.read_text())
    old["meta"].update(error=math.nan, seconds=math.nan)
    del old[NON_FINITE_KEY]
    record_path.write_text(json.dumps(old, sort_keys=True))
    assert "NaN" in record_path.read_text()
    write_report(load_result(scene, tmp_path / "results"), tmp_path / "old", render=False)
    again = (tmp_path / "old" / "report.md").read_text()
    assert _timing_free(again) == _timing_free(report)
