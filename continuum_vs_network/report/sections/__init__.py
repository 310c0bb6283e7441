"""One report section per scene kind: ``SECTIONS[kind](doc, result)``.

A section is a function ``section(doc, result) -> None`` that appends to a
:class:`~continuum_vs_network.report.document.Document` (headings, tables, figures, renders
and :class:`~continuum_vs_network.report.findings.Finding` objects) from a
:class:`~continuum_vs_network.scenes.runner.SceneResult`. A new scene kind adds a module here
and one entry to :data:`SECTIONS`.
"""

from __future__ import annotations

from collections.abc import Callable

from . import (
    accuracy,
    allostery,
    beyond_paper,
    continuum_learning,
    continuum_mechanism,
    learning,
    physical_time,
    relaxation,
    solvers,
    stability,
    transmission,
)

__all__ = ["SECTIONS"]

#: The section writer of each scene kind.
SECTIONS: dict[str, Callable[..., None]] = {
    "learning": learning.section,
    "transmission": transmission.section,
    "relaxation": relaxation.section,
    "stability": stability.section,
    "solvers": solvers.section,
    "accuracy": accuracy.section,
    "physical_time": physical_time.section,
    "continuum_learning": continuum_learning.section,
    "beyond_paper": beyond_paper.section,
    "allostery": allostery.section,
    "continuum_mechanism": continuum_mechanism.section,
}
