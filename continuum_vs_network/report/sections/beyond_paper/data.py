"""The ``beyond_paper`` units read as their result classes
(:mod:`~continuum_vs_network.scenes.results.beyond_paper`), once, where the section loads
them: every part indexes the typed results by unit key."""

from __future__ import annotations

from typing import Any

from ....scenes.results import from_stored
from ....scenes.results.beyond_paper import (
    CapacityResult,
    CompareResult,
    NodeResult,
    OptimumResult,
    RegressionResult,
    SymmetricResult,
    ThermalResult,
)

#: the result class of a unit, by the start of its key
CLASSES = {
    "beyond/compare/": CompareResult,
    "beyond/optimum/": OptimumResult,
    "beyond/node/": NodeResult,
    "beyond/thermal/": ThermalResult,
    "beyond/capacity/": CapacityResult,
    "beyond/regression": RegressionResult,
    "beyond/symmetric": SymmetricResult,
}


def results(units) -> dict[str, Any]:
    """``units`` (key -> stored unit) as key -> result, for every key of :data:`CLASSES`."""
    out = {}
    for key, unit in units.items():
        cls = next((c for start, c in CLASSES.items() if key.startswith(start)), None)
        if cls is not None:
            out[key] = from_stored(unit, cls)
    return out
