"""The researcher's page of ``reports/README.md``: a one-page summary, then the findings in
three tables by whose claim they judge.

Everything is read from the scenes' ``report.json`` (their findings and the summary tables
their sections keep); nothing here is a number written by hand. :func:`summary_lines` gives
the summary (what learns and against what optimum, the paper in its own setting and why,
what the continuum shows, and the tally of verdicts by source with the findings met
trivially per scene); :func:`findings_tables` the three tables (``Finding.source``: the
paper's claims, the field's claims, the package's own checks), each cell cut to
:data:`CELL` characters (the scene's report gives the whole text and the rule).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from . import escape
from .findings import SOURCES, VERDICTS, Finding

__all__ = ["CELL", "cap", "findings_tables", "summary_lines", "tally"]

#: longest text of a table cell (claim or measured values)
CELL = 110
_TITLES = {
    "paper": "The paper's claims",
    "field": "The field's claims (published work other than the paper)",
    "check": "The package's own checks (numerics, solvers, its learning studies)",
}
#: scenes whose findings say what the continuum shows
_CONTINUUM = ("transmission", "relaxation", "continuum_learning", "continuum_mechanism")


def cap(text: str, n: int = CELL) -> str:
    """``text`` cut to ``n`` characters (an ellipsis marks a cut)."""
    text = " ".join(str(text).split())
    return text if len(text) <= n else text[: n - 3].rstrip() + "..."


def _cell(text: str, n: int = CELL) -> str:
    return escape.cell(cap(text, n))


def tally(findings: Sequence[tuple[str, Finding]]) -> dict[str, Counter]:
    """Verdict counts per source: ``{source: Counter(verdict -> n)}``."""
    out = {s: Counter() for s in SOURCES}
    for _, f in findings:
        out[f.source][f.verdict] += 1
    return out


def _table(headers, rows) -> list[str]:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return [*lines, ""]


def summary_lines(entries: Sequence[dict], findings: Sequence[tuple[str, Finding]]) -> list[str]:
    """The one-page summary (module docstring), from the reports' entries and findings."""
    by_name = {e["name"]: e for e in entries}
    lines = ["## Summary", ""]
    head = by_name.get("allostery", {}).get("summaries", {}).get("headline")
    if head:
        lines += [
            f"**What learns, how fast, against what optimum.** {head['title']} "
            "([allostery](allostery/report.md)):",
            "",
        ]
        lines += _table(head["headers"], head["rows"])
    paper = [(n, f) for n, f in findings if f.source == "paper" and n == "paper"]
    if paper:
        lines += [
            "**The paper, in its own setting** (the author's notebooks' rates, nudges, steps "
            "and conventions, exact equilibria; [paper](paper/report.md)):",
            "",
        ]
        lines += _table(
            ["claim", "measured", "verdict"],
            [
                [
                    _cell(f.claim.split("): ", 1)[-1] + _run(f.claim), 90),
                    _cell(f.measured_text(), 60),
                    f"**{f.verdict}**",
                ]
                for _, f in paper
            ],
        )
    why = by_name.get("paper", {}).get("summaries", {}).get("explanations")
    if why:
        lines += ["**Why** ([paper](paper/report.md), a paragraph each there):", ""]
        lines += _table(["topic", "measured"], [[r[0], _cell(r[1], 60)] for r in why["rows"]])
    cont = [(n, f) for n, f in findings if n in _CONTINUUM]
    if cont:
        lines += ["**What the continuum shows:**", ""]
        lines += _table(
            ["scene", "claim", "verdict"],
            [[f"[{n}]({n}/report.md)", _cell(f.claim), f"**{f.verdict}**"] for n, f in cont],
        )
    counts = tally(findings)
    lines += ["**Verdicts by whose claim** (every finding of every report):", ""]
    lines += _table(
        ["claims of", *VERDICTS, "total"],
        [
            [s, *(counts[s][v] for v in VERDICTS), sum(counts[s].values())]
            for s in SOURCES
            if counts[s]
        ],
    )
    trivial = Counter(n for n, f in findings if f.basis == "met trivially")
    basis = Counter(n for n, f in findings if f.basis)
    if basis:
        lines += [
            "Learning verdicts that rest on runs which met the task by prestress alone "
            "(`basis` met trivially), per scene: "
            + ", ".join(f"{n} {trivial[n]} of {basis[n]}" for n in sorted(basis))
            + ".",
            "",
        ]
    return lines


def _run(claim: str) -> str:
    """`` (run)`` named in a paper finding's claim (``paper, Fig. 4 (gcl, paper): ...``)."""
    inside = claim.split("(", 1)[-1].split(")", 1)[0] if "(" in claim else ""
    run = inside.split(",")[0].strip()
    return f" [{run}]" if run else ""


def findings_tables(findings: Sequence[tuple[str, Finding]]) -> list[str]:
    """The findings in three tables by source (module docstring)."""
    lines = [
        "## Findings",
        "",
        "Every claim a report judges, with the verdict its rule computed from the same run; "
        "the scene's report gives the rule, the whole text and the figures. `basis`: for a "
        "learning verdict, whether it rests on runs where the sources drive the target "
        "(coupled) or on runs that met the task by prestress alone (met trivially).",
        "",
    ]
    for source in SOURCES:
        rows = [(n, f) for n, f in findings if f.source == source]
        if not rows:
            continue
        lines += [f"### {_TITLES[source]}", ""]
        lines += _table(
            ["scene", "claim", "measured", "verdict", "basis"],
            [
                [
                    f"[{n}]({n}/report.md)",
                    _cell(f.claim),
                    _cell(f.measured_text(), 70),
                    f"**{f.verdict}**",
                    f.basis or "",
                ]
                for n, f in rows
            ],
        )
    return lines
