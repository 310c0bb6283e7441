"""The README's findings and benchmark numbers are generated from the committed report's JSON."""

from __future__ import annotations

import json
from pathlib import Path

from continuum_vs_network.report.findings import CONTRADICTED, REPRODUCED, Finding
from continuum_vs_network.report.readme import render_block, stale_blocks, update_readme

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_matches_the_committed_report():
    stale = stale_blocks(ROOT / "README.md", ROOT / "reports")
    assert not stale, f"README blocks {stale} differ from reports/*/report.json: run cvn report"


def test_the_readme_names_the_paper_and_needs_no_shared_folder():
    text = (ROOT / "README.md").read_text()
    assert "../shared" not in text
    assert "Computation in Physical Media" in text
    assert "<!-- cvn:paper -->" in text and "<!-- cvn:benchmarks -->" in text
    assert "<!-- cvn:headline -->" in text
    # the findings live in reports/README.md (three tables by source), not copied here
    assert "<!-- cvn:findings -->" not in text and "reports/README.md" in text
    assert len(text.splitlines()) < 360


def _report(root: Path, name: str, verdict: str, seconds: str) -> None:
    folder = root / "reports" / name
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "report.md").write_text("# x\n")
    f = Finding(
        claim=f"{name} claim",
        metric="m",
        measured={"x": 0.5},
        verdict=verdict,
        rule="r",
    )
    summaries = {
        "time_to_tolerance": {
            "title": "Seconds",
            "headers": ["N", "newton"],
            "rows": [["64", seconds]],
        }
    }
    meta = {"name": name, "findings": [f.to_dict()], "summaries": summaries}
    (folder / "report.json").write_text(json.dumps(meta))


def test_blocks_follow_the_reports_and_drift_is_detected(tmp_path):
    _report(tmp_path, "solvers", REPRODUCED, "0.01")
    _report(tmp_path, "stability", CONTRADICTED, "0.01")
    readme = tmp_path / "README.md"
    readme.write_text(
        "intro\n<!-- cvn:findings -->\nold\n<!-- /cvn:findings -->\nmiddle\n"
        "<!-- cvn:benchmarks -->\n<!-- /cvn:benchmarks -->\nend\n"
    )
    assert stale_blocks(readme, tmp_path / "reports") == ["findings", "benchmarks"]
    assert update_readme(readme, tmp_path / "reports") == ["findings", "benchmarks"]
    text = readme.read_text()
    assert text.startswith("intro\n") and "\nmiddle\n" in text and text.endswith("end\n")
    assert "- *contradicted*: stability claim (x = 0.5)" in text
    assert "[solvers](reports/solvers/report.md)" in text and "| 64 | 0.01 |" in text
    assert stale_blocks(readme, tmp_path / "reports") == []
    # a number in the report changes: the README is stale until regenerated
    _report(tmp_path, "solvers", REPRODUCED, "0.02")
    assert stale_blocks(readme, tmp_path / "reports") == ["benchmarks"]


def test_a_readme_without_markers_is_left_alone(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("plain\n")
    assert update_readme(readme, tmp_path / "reports") == []
    assert readme.read_text() == "plain\n"
    assert update_readme(tmp_path / "missing.md", tmp_path) == []
    assert "No report with findings yet" in render_block("findings", tmp_path, tmp_path)


def _paper_report(root: Path, verdict: str) -> None:
    folder = root / "reports" / "paper"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "report.md").write_text("# x\n")
    mine = Finding(
        claim="paper, Fig. 4 (gcl, paper): GCL lowers C by orders of magnitude",
        metric="m",
        measured={"value": 1.09},
        verdict=verdict,
        rule="r",
        source="paper",
    )
    check = Finding(
        claim="package check", metric="m", measured={"x": 1}, verdict=REPRODUCED, rule="r"
    )
    why = {
        "title": "Why",
        "headers": ["topic", "number", "text"],
        "rows": [["Eq. 23 sign", "3/3", "t"]],
    }
    meta = {
        "name": "paper",
        "findings": [mine.to_dict(), check.to_dict()],
        "summaries": {"explanations": why},
    }
    (folder / "report.json").write_text(json.dumps(meta))


def test_the_paper_block_lists_the_paper_claims_only_with_their_verdicts(tmp_path):
    _paper_report(tmp_path, CONTRADICTED)
    text = render_block("paper", tmp_path / "reports", tmp_path)
    assert "| GCL lowers C by orders of magnitude (gcl) | value = 1.09 | **contradicted** |" in text
    assert "package check" not in text  # a check is not a claim of the paper
    assert "Eq. 23 sign: 3/3" in text
