"""Findings: validated, registered by a section, written to report.json and the index."""

from __future__ import annotations

import json
import math

import pytest

from continuum_vs_network.report import write_index
from continuum_vs_network.report.document import Document
from continuum_vs_network.report.findings import (
    CONTRADICTED,
    REPRODUCED,
    VERDICTS,
    Finding,
)


def _finding(**kw):
    base = dict(
        claim="GCL lowers the task error",
        metric="final C/C0",
        measured={"C/C0": 3e-4},
        verdict=REPRODUCED,
        rule="reproduced when C/C0 < 1e-2",
    )
    base.update(kw)
    return Finding(**base)


def test_verdicts_are_the_four_named_ones():
    assert VERDICTS == ("reproduced", "not reproduced", "contradicted", "not comparable")


@pytest.mark.parametrize(
    "kw, word",
    [
        (dict(verdict="ok"), "verdict"),
        (dict(claim=" "), "claim"),
        (dict(rule=""), "rule"),
        (dict(measured={}), "measured"),
        (dict(measured={"x": "big"}), "measured['x']"),
    ],
)
def test_bad_findings_are_refused_naming_the_field(kw, word):
    with pytest.raises(ValueError, match=word.replace("[", r"\[").replace("]", r"\]")):
        _finding(**kw)


def test_round_trip_through_json_keeps_nan_as_missing():
    f = _finding(measured={"a": 1.5, "b": math.nan})
    d = json.loads(json.dumps(f.to_dict()))
    assert d["measured"] == {"a": 1.5, "b": None}
    g = Finding.from_dict(d)
    assert g.measured["a"] == 1.5 and math.isnan(g.measured["b"])
    assert g.measured_text() == "a = 1.5, b = -"


def test_round_trip_through_strict_json_keeps_an_infinity():
    f = _finding(measured={"a": math.inf, "b": -math.inf, "c": math.nan})
    text = json.dumps(f.to_dict(), allow_nan=False)
    d = json.loads(text)
    assert d["measured"] == {"a": None, "b": None, "c": None}
    g = Finding.from_dict(d).measured
    assert g["a"] == math.inf and g["b"] == -math.inf and math.isnan(g["c"])


def test_document_files_findings_under_the_current_heading(tmp_path):
    doc = Document(tmp_path, 50)
    doc.heading("Claims")
    f = doc.finding(_finding())
    doc.heading("detail", level=3)
    g = doc.finding(_finding(verdict=CONTRADICTED, section="Elsewhere"))
    assert (f.section, g.section) == ("Claims", "Elsewhere")
    assert doc.findings == [f, g]
    doc.findings_table(doc.findings)
    assert "| **contradicted** |" in "\n".join(doc.lines)
    with pytest.raises(TypeError, match="Finding"):
        doc.finding({"claim": "x"})


def test_index_opens_with_every_scenes_findings(tmp_path):
    for name, verdict in (("a", REPRODUCED), ("b", CONTRADICTED)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "report.md").write_text("# x\n")
        meta = {
            "name": name,
            "kind": "learning",
            "description": "d",
            "default": True,
            "compute_seconds": 1.0,
            "report_seconds": 0.1,
            "findings": [_finding(verdict=verdict, claim=f"claim {name}").to_dict()],
        }
        (folder / "report.json").write_text(json.dumps(meta))
    text = write_index(tmp_path).read_text()
    assert text.index("## Findings") < text.index("## Reports")
    assert "| [a](a/report.md) | claim a | C/C0 = 0.0003 | **reproduced** |" in text
    assert "| [b](b/report.md) | claim b | C/C0 = 0.0003 | **contradicted** |" in text
