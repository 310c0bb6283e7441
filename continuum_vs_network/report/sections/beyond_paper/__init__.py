"""Report section of a ``beyond_paper`` scene: directed aging, several examples, symmetry.

Computed from the scene's stored units by the rules stated in the text (it runs nothing):
directed aging against GPC, GCL and the exact gradient on anchored tasks beside the optimum
(final error, coupling, outcome, feasibility; the identity of rest-length aging and GPC at
uniform stiffness), anchored node tasks (absolute and relative node displacements), the
capacity of a network trained on several examples at once (optimum and GCL against the
number of examples and the network size), the thermal floor against temperature, a
regression task (training and held-out error: generalisation) and symmetric training.

This module reads the units as their result classes once (by
:data:`~....scenes.results.beyond_paper.CLASSES`) and orders the parts; each is its own
module: :mod:`.aging`, :mod:`.nodes`, :mod:`.examples` (capacity,
symmetric training, regression), :mod:`.thermal`.
"""

from __future__ import annotations

from ....learning.coupling import MET_AT
from ....scenes.results import read_results
from ....scenes.results.beyond_paper import CLASSES
from ...document import Document
from .aging import _compare
from .examples import _capacity, _regression, _symmetric
from .nodes import _nodes
from .thermal import _thermal

__all__ = ["section"]


def section(doc: Document, result) -> None:
    scene = result.scene
    units = read_results(result.units, CLASSES)
    L = scene.learning
    doc.add(
        "Options of the existing rules, tasks and `train` that the field uses beyond the "
        "paper, each run by the package's default rule objects (scale-free rates, nothing "
        f"tuned) for {L.steps} steps, beside the optimum of the same task (L-BFGS-B on the "
        f"exact gradient, at most {L.steps} iterations, the same ranges): every task is one "
        "that prestress cannot meet (rest-length rules train with the rest example; the "
        "examples studies learn stiffnesses of a network at rest), so a met task is learned, "
        "and a task whose optimum misses is infeasible and counted apart. Bulk learning "
        "everywhere (sources and targets frozen), strains against the initial rest lengths. "
        f"A task is *met* when C/C0 <= {MET_AT:g}; the coupling verdict (learning.coupling) "
        "says whether the sources cause the trained target strain. Every finding says what "
        "its verdict rests on (coupled runs) and every *not comparable* says why.",
        "",
    )
    _compare(doc, scene, units)
    _nodes(doc, scene, units)
    _capacity(doc, scene, units)
    _thermal(doc, scene, units)
    _regression(doc, units)
    _symmetric(doc, units)
