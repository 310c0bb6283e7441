"""The report: matplotlib figures and the Markdown writer.

:func:`~.writer.write_report` turns a scene result into ``reports/<scene>/report.md`` with
its figures; :func:`~.writer.write_index` writes ``reports/README.md``. matplotlib and
pyvista are imported only while drawing.
"""

from __future__ import annotations

from .writer import write_index, write_report

__all__ = ["write_index", "write_report"]
