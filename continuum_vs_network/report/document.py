"""The report document: Markdown lines, the files written, the findings; number helpers.

A section (one module or package in :mod:`~continuum_vs_network.report.sections` per scene
kind) is a function ``section(doc, result)`` that appends headings, tables, figures and
findings to a :class:`Document`; :func:`~continuum_vs_network.report.writer.write_report`
assembles them.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import escape
from .figures import Panel, plot_panels
from .findings import Finding

__all__ = [
    "SHORT_NAMES",
    "SOLVER_NAMES",
    "Document",
    "above",
    "fmt",
    "normalised",
    "quiet",
    "stats",
    "summary_text",
]


class Document:
    """Markdown lines, the files written and the findings of one report.

    Parameters
    ----------
    folder : Path
        Where the report and its figures go.
    dpi : int
        Resolution of the matplotlib figures.
    render : bool
        Whether sections draw pyvista renders.
    render_reason : str
        Why renders are skipped when ``render`` is false (printed in the report).
    """

    def __init__(
        self, folder: Path, dpi: int, *, render: bool = False, render_reason: str = ""
    ) -> None:
        self.folder = folder
        self.dpi = dpi
        self.render = render
        self.render_reason = render_reason
        self.lines: list[str] = []
        self.files: list[Path] = []
        self.findings: list[Finding] = []
        self._shown: set[int] = set()  # indices of findings already tabulated in the text
        self.summaries: dict[str, dict[str, Any]] = {}
        self._section = ""

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def heading(self, text: str, level: int = 2) -> None:
        self.lines.extend(["", "#" * level + " " + text, ""])
        if level <= 2:
            self._section = text

    def renders_heading(self, level: int = 2) -> bool:
        """The "Renders" heading, and below it why renders are skipped when ``render`` is
        false; returns ``render``."""
        self.heading("Renders", level)
        if not self.render:
            self.add(f"Renders skipped: {self.render_reason}.")
        return self.render

    def finding(self, finding: Finding, *, shown: bool = False) -> Finding:
        """Register a finding (it goes to ``report.json`` and the index); return it.

        An empty ``finding.section`` becomes the current level-2 heading. ``shown``: the
        section states this verdict in a table of its own; every other finding not passed to
        :meth:`findings_table` is tabulated at the end of the report (:meth:`unshown`).
        """
        if not isinstance(finding, Finding):
            raise TypeError(f"finding must be a Finding, not {type(finding).__name__}")
        if not finding.section:
            from dataclasses import replace

            finding = replace(finding, section=self._section)
        if shown:
            self._shown.add(len(self.findings))
        self.findings.append(finding)
        return finding

    def unshown(self) -> list[Finding]:
        """The registered findings whose verdict the text does not state yet."""
        return [f for i, f in enumerate(self.findings) if i not in self._shown]

    def summary(
        self, key: str, title: str, headers: Sequence[str], rows: Sequence[Sequence]
    ) -> None:
        """Keep a small table in ``report.json`` (key ``"summaries"``) for the README.

        Cells are stored as text, as the report shows them. Not added to the report itself.
        """
        self.summaries[key] = {
            "title": title,
            "headers": [str(h) for h in headers],
            "rows": [[str(c) for c in row] for row in rows],
        }

    def findings_table(self, findings: Sequence[Finding]) -> None:
        """A claim / metric / measured / verdict / rule table of the given findings.

        When every finding has the same rule, it is stated once below the table.
        """
        if not findings:
            return
        keys = {(f.claim, f.verdict, f.rule) for f in findings}
        self._shown.update(
            i for i, f in enumerate(self.findings) if (f.claim, f.verdict, f.rule) in keys
        )
        rules = {f.rule for f in findings}
        one = len(rules) == 1
        headers = ["claim", "metric", "measured", "verdict"] + ([] if one else ["rule"])
        rows = [
            [f.claim, f.metric, f.measured_text(), f"**{f.verdict}**"] + ([] if one else [f.rule])
            for f in findings
        ]
        self.table(headers, rows)
        if one:
            self.add(f"Verdict rule: {rules.pop()}.", "")

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
        """A GitHub Markdown table, unpadded, its row cells escaped (:func:`escape.cell`).

        Not ``tabulate(tablefmt="github")``: it pads every cell to its column's width (the
        committed reports' tables grow 2.6x, long "rule" cells widen whole columns) and does
        not escape ``|`` in cells.
        """
        if self.lines and self.lines[-1] != "":
            self.lines.append("")
        self.lines.append("| " + " | ".join(headers) + " |")
        self.lines.append("|" + "---|" * len(headers))
        for row in rows:
            self.lines.append("| " + " | ".join(escape.cell(c) for c in row) + " |")
        self.lines.append("")

    def figure(self, name: str, panels: Sequence[Panel], caption: str, **kw: Any) -> None:
        path = plot_panels(panels, self.folder / f"fig_{name}.png", dpi=self.dpi, **kw)
        self.image(path, caption)

    def image(self, path: Path, caption: str) -> None:
        self.files.append(path)
        self.lines.extend(["", f"![{caption}]({path.name})", "", f"*{caption}*", ""])


# -- numbers ---------------------------------------------------------------------------------
def quiet(fn, *args, **kw):
    """``fn(*args, **kw)`` with RuntimeWarnings (empty slices, all-NaN) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fn(*args, **kw)


def stats(a: NDArray) -> dict[str, NDArray]:
    """Per-column median, quartiles, mean, std over rows (trials), NaN-aware."""
    a = np.asarray(a, dtype=float)
    return {
        "median": quiet(np.nanmedian, a, axis=0),
        "q25": quiet(np.nanpercentile, a, 25, axis=0),
        "q75": quiet(np.nanpercentile, a, 75, axis=0),
        "mean": quiet(np.nanmean, a, axis=0),
        "std": quiet(np.nanstd, a, axis=0),
    }


def normalised(values: NDArray) -> NDArray:
    """Rows divided by their first column: (trials, steps) -> same."""
    v = np.asarray(values, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return v / v[:, :1]


def fmt(x: float, digits: int = 3) -> str:
    """``x`` to ``digits`` significant digits; "-" for None and non-finite values."""
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


def coupling_text(run) -> str:
    """A learning run's coupling as the report writes it: "source share (verdict)", from a
    result's ``source_share`` and ``coupling``."""
    return f"{fmt(run.source_share, 2)} ({run.coupling})"


def mesh_name(refine: int) -> str:
    """The element size of a mesh refined ``refine`` times from h: "h", "h/2", "h/4", ..."""
    return "h" if refine == 0 else f"h/{2**refine}"


def summary_text(values: NDArray, completed: NDArray | None = None) -> str:
    """Final normalised value: "median [q25, q75]" over trials (missing ones counted)."""
    from ..learning.metrics import summary

    s = summary(values, completed)
    if not s.get("n"):
        return "no finite value"
    text = f"{fmt(s['median'])} [{fmt(s['q25'])}, {fmt(s['q75'])}]"
    if s.get("missing"):
        text += f" ({s['missing']} missing)"
    return text


#: Short solver names for panel titles.
SHORT_NAMES = {
    "newton": "Newton equilibria",
    "paper": "paper's Adagrad",
    "fire": "FIRE",
    "lbfgs": "L-BFGS",
}
#: Solver names for sentences.
SOLVER_NAMES = {
    "newton": "exact equilibria (Newton)",
    "paper": "the paper's relaxation (Adagrad, rods)",
    "fire": "FIRE",
    "lbfgs": "L-BFGS",
}


def above(values: NDArray, floor: float) -> NDArray:
    """``values`` with those at or below ``floor`` replaced by NaN (not drawn)."""
    return np.where(values > floor, values, np.nan)
