"""The report: matplotlib figures, one section per scene kind, the writer, findings.

:func:`~.writer.write_report` turns a scene result into ``reports/<scene>/report.md`` with
its figures by handing a :class:`~.document.Document` to its kind's ``section`` (one module
or package per kind in :mod:`.sections`), then the settings and provenance
(:mod:`.provenance`); sections register :class:`~.findings.Finding` objects (claim,
metric, measured values, verdict, rule), which land in ``report.json``; the verdicts on
the paper's learning claims are judged in :mod:`.verdicts`;
:func:`~.writer.write_index` writes ``reports/README.md``, opening with every scene's
findings. matplotlib and pyvista are imported only while drawing.
"""

from __future__ import annotations

from .findings import Finding
from .writer import write_index, write_report

__all__ = ["Finding", "write_index", "write_report"]
