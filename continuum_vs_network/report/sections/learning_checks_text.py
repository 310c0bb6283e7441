"""How the learning checks (:mod:`.learning_checks`) word things: the strain conventions,
the task error's label, and captions computed from a curve.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..document import fmt

__all__ = ["CONVENTION_TEXT", "curve_caption", "direction", "error_label"]

#: how a report names each strain convention
CONVENTION_TEXT = {
    "initial": "`initial` (strains against the initial rest lengths: fixed target geometries)",
    "current": "`current` (the paper's literal convention: strains against the learning "
    "rest lengths)",
}


def error_label(strain_reference: str) -> str:
    """``C`` with the rest length its strains are measured against."""
    return "C (Eq. 26, strains vs the " + (
        "initial L)" if strain_reference == "initial" else "learning L)"
    )


def direction(first: float, last: float, *, rel: float = 0.01) -> str:
    """``"rises"``, ``"falls"`` or ``"stays level"`` (within ``rel``) from ``first`` to
    ``last``; ``"is not measured"`` when either is missing."""
    if not (np.isfinite(first) and np.isfinite(last)):
        return "is not measured"
    if abs(last - first) <= rel * max(abs(first), abs(last)):
        return "stays level"
    return "rises" if last > first else "falls"


def _last_finite(row: NDArray) -> float:
    ok = np.flatnonzero(np.isfinite(row))
    return float(row[ok[-1]]) if ok.size else float("nan")


def curve_caption(what: str, row: NDArray) -> str:
    """``"<what> rises from a to b"`` computed from a curve (first and last finite value)."""
    first = float(row[0]) if np.isfinite(row[0]) else float("nan")
    last = _last_finite(row)
    return f"{what} {direction(first, last)} from {fmt(first)} to {fmt(last)}"
