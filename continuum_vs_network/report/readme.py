"""README blocks generated from the reports' JSON, so the README's numbers cannot drift.

A README holds generated blocks between markers::

    <!-- cvn:findings -->
    ... written by update_readme ...
    <!-- /cvn:findings -->

:func:`render_block` builds a block's text from every ``<reports>/<scene>/report.json``
(``headline``: the allostery scene's summary of what learns, how fast, against the task's
optimum; ``paper``: the paper scene's verdicts on the paper's claims, one line each, and its
explanations' numbers; ``findings``: one line per claim and verdict, scene by scene
(``reports/README.md`` has them in tables by source); ``benchmarks``: the
summary tables the sections keep, e.g. seconds to tolerance of every equilibrium method and
the convergence orders and costs of the finite elements and time integrators).
:func:`update_readme` rewrites the blocks a README has (``cvn report`` and ``cvn run`` call
it for ``<out>/README.md``); :func:`stale_blocks` names those that differ from what the
reports give (the repository's test of its README).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..io.atomic import write_text_atomic
from ..io.strict_json import loads_record
from . import escape
from .findings import Finding

__all__ = ["BLOCKS", "render_block", "stale_blocks", "update_readme"]

#: Blocks a README may hold, and the summary tables (scene, key) of the benchmarks block.
BLOCKS = ("headline", "findings", "benchmarks", "paper")
_HEADLINE = (("allostery", "headline"),)
_BENCHMARKS = (
    ("solvers", "time_to_tolerance"),
    ("accuracy", "finite_elements"),
    ("accuracy", "time_integrators"),
)
_MARK = re.compile(r"(<!-- cvn:(\w+) -->\n)(.*?)(<!-- /cvn:\2 -->)", re.S)


def _entries(reports: Path) -> list[dict]:
    out = []
    for meta in sorted(Path(reports).glob("*/report.json")):
        if (meta.parent / "report.md").exists():
            out.append(loads_record(meta.read_text()))
    return out


def _link(reports: Path, readme_dir: Path, name: str) -> str:
    try:
        rel = os.path.relpath(Path(reports) / name / "report.md", readme_dir)
    except ValueError:  # pragma: no cover - another drive
        rel = str(Path(reports) / name / "report.md")
    return Path(rel).as_posix()


def render_block(
    name: str, reports: str | os.PathLike[str], readme_dir: str | os.PathLike[str]
) -> str:
    """The Markdown of block ``name`` from the reports under ``reports``.

    Links are relative to ``readme_dir`` (the README's folder).
    """
    reports, readme_dir = Path(reports), Path(readme_dir)
    entries = _entries(reports)
    lines: list[str] = []
    if name == "findings":
        for e in entries:
            found = [Finding.from_dict(f) for f in e.get("findings", ())]
            if not found:
                continue
            link = _link(reports, readme_dir, e["name"])
            lines.append(f"**[{e['name']}]({link})**")
            lines.append("")
            lines += [f"- *{f.verdict}*: {f.claim} ({f.measured_text()})" for f in found]
            lines.append("")
        if not lines:
            lines = ["No report with findings yet: run `cvn report`.", ""]
    elif name == "paper":
        from .index_summary import cap

        entry = next((e for e in entries if e["name"] == "paper"), None)
        found = [Finding.from_dict(f) for f in (entry or {}).get("findings", ())]
        found = [f for f in found if f.source == "paper"]
        if found:
            link = _link(reports, readme_dir, "paper")
            lines += [f"Verdicts on the paper's claims ([paper]({link})):", ""]
            lines += ["| claim | measured | verdict |", "|---|---|---|"]
            for f in found:
                claim = f.claim.split("): ", 1)[-1]
                run = f.claim.split("(", 1)[-1].split(",")[0] if "(" in f.claim else ""
                lines.append(
                    f"| {escape.cell(cap(claim, 80))} ({run}) | "
                    f"{escape.cell(cap(f.measured_text().split(', ')[0], 30))} | **{f.verdict}** |"
                )
            lines.append("")
        why = (entry or {}).get("summaries", {}).get("explanations")
        if why:
            lines.append(
                "Why: "
                + "; ".join(escape.text(f"{r[0]}: {r[1]}") for r in why["rows"])
                + " (the report "
                "gives a paragraph each)."
            )
            lines.append("")
        if not lines:
            lines = ["No paper report yet: run `cvn report`.", ""]
    elif name in ("benchmarks", "headline"):
        by_name = {e["name"]: e for e in entries}
        for scene, key in _BENCHMARKS if name == "benchmarks" else _HEADLINE:
            table = by_name.get(scene, {}).get("summaries", {}).get(key)
            if table is None:
                continue
            link = _link(reports, readme_dir, scene)
            lines += [f"{table['title']} ([{scene}]({link})):", ""]
            lines.append("| " + " | ".join(table["headers"]) + " |")
            lines.append("|" + "---|" * len(table["headers"]))
            lines += ["| " + " | ".join(row) + " |" for row in table["rows"]]
            lines.append("")
        if not lines:
            lines = [f"No {name} summary in the reports yet: run `cvn report`.", ""]
    else:
        raise ValueError(f"name must be one of {', '.join(map(repr, BLOCKS))}, got {name!r}")
    return "\n".join(lines).rstrip() + "\n"


def _rewrite(text: str, reports: Path, readme_dir: Path) -> tuple[str, list[str]]:
    changed: list[str] = []

    def sub(m: re.Match) -> str:
        block = m.group(2)
        if block not in BLOCKS:
            return m.group(0)
        new = render_block(block, reports, readme_dir)
        if new != m.group(3):
            changed.append(block)
        return m.group(1) + new + m.group(4)

    return _MARK.sub(sub, text), changed


def stale_blocks(readme: str | os.PathLike[str], reports: str | os.PathLike[str]) -> list[str]:
    """Names of the README's generated blocks that differ from what ``reports`` give."""
    readme = Path(readme)
    return _rewrite(readme.read_text(), Path(reports), readme.parent)[1]


def update_readme(readme: str | os.PathLike[str], reports: str | os.PathLike[str]) -> list[str]:
    """Rewrite the generated blocks of ``readme`` (if it exists); return those changed."""
    readme = Path(readme)
    if not readme.is_file():
        return []
    text, changed = _rewrite(readme.read_text(), Path(reports), readme.parent)
    if changed:
        write_text_atomic(readme, text)
    return changed
