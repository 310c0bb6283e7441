"""reports/README.md: a summary first, then the findings in three tables by whose claim."""

from __future__ import annotations

import json
from pathlib import Path

from continuum_vs_network.report.findings import (
    CONTRADICTED,
    NOT_COMPARABLE,
    REPRODUCED,
    Finding,
)
from continuum_vs_network.report.index_summary import CELL, cap, tally
from continuum_vs_network.report.writer import write_index


def _scene(root: Path, name: str, findings, summaries=None) -> None:
    folder = root / name
    folder.mkdir(parents=True)
    (folder / "report.md").write_text("# x\n")
    meta = {
        "name": name,
        "kind": "learning",
        "description": "d",
        "default": True,
        "compute_seconds": 1.0,
        "report_seconds": 0.5,
        "findings": [f.to_dict() for f in findings],
        "summaries": summaries or {},
    }
    (folder / "report.json").write_text(json.dumps(meta))


def _f(claim, verdict, source="check", basis="", measured=None):
    return Finding(
        claim=claim,
        metric="m",
        measured=measured or {"x": 1.0},
        verdict=verdict,
        rule="r",
        source=source,
        basis=basis,
    )


def test_index_opens_with_a_summary_and_sorts_findings_by_source(tmp_path):
    long = {f"value {i}": float(i) for i in range(30)}  # a wall of numbers
    _scene(
        tmp_path,
        "paper",
        [
            _f("paper, Fig. 4 (gcl, paper): GCL lowers C", CONTRADICTED, "paper"),
            _f(
                "paper, Fig. 10 (gpc_frozen, paper): lowers C", REPRODUCED, "paper", "met trivially"
            ),
        ],
        {
            "explanations": {
                "title": "Why",
                "headers": ["topic", "number", "text"],
                "rows": [["Eq. 14 sign", "6/10", "t"]],
            }
        },
    )
    _scene(tmp_path, "stern", [_f("Stern 2022: critical ratio", NOT_COMPARABLE, "field")])
    _scene(tmp_path, "accuracy", [_f("P1 converges at order 2", REPRODUCED, measured=long)])
    text = write_index(tmp_path).read_text()
    summary, rest = text.split("## Findings", 1)
    assert "## Summary" in summary and "Eq. 14 sign" in summary
    # tally: one row per source with its counts, computed from the findings
    assert "| paper | 1 | 0 | 1 | 0 | 2 |" in summary
    assert "| field | 0 | 0 | 0 | 1 | 1 |" in summary
    assert "| check | 1 | 0 | 0 | 0 | 1 |" in summary
    assert "paper 1 of 1" in summary  # findings met trivially per scene
    heads = [line for line in rest.splitlines() if line.startswith("### ")]
    assert heads == [
        "### The paper's claims",
        "### The field's claims (published work other than the paper)",
        "### The package's own checks (numerics, solvers, its learning studies)",
    ]
    paper_part = rest.split("### The field")[0]
    assert "GCL lowers C" in paper_part and "P1 converges" not in paper_part
    # cells are capped: the 30 measured values are cut
    row = next(line for line in rest.splitlines() if "P1 converges" in line)
    cells = row.split(" | ")
    assert all(len(c) <= CELL + 10 for c in cells) and "..." in row


def test_cap_and_tally():
    assert cap("a  b\nc") == "a b c"
    assert cap("x" * 200, 20) == "x" * 17 + "..."
    t = tally([("s", _f("c", REPRODUCED, "paper")), ("s", _f("d", REPRODUCED, "paper"))])
    assert t["paper"][REPRODUCED] == 2 and not t["field"] and not t["check"]
