"""What the ``continuum_learning`` section (:mod:`.continuum_learning`) measures on the
stored units: steps to ``C / C0 <= TOLERANCE``, the learned field's change under
refinement, its correlation with the network's and its localisation, and the thresholds.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["LOCALISED", "SETTLED", "SHRINK", "TOLERANCE", "field_summary", "steps_to"]

TOLERANCE = 1e-3  # C / C0 a run must reach to count as having learned the task
SHRINK = 1.5  # a field converges when successive refinements change it less by this factor
SETTLED = 0.1  # ... and the last refinement changes it by at most this (relative L2)
LOCALISED = 0.1  # localisation threshold: a fraction of the largest change


def steps_to(error: NDArray, tol: float = TOLERANCE) -> float:
    """First step with ``error <= tol * error[0]`` (NaN when never reached)."""
    e = np.asarray(error, dtype=float)
    hit = np.flatnonzero(e <= tol * e[0])
    return float(hit[0]) if hit.size else math.nan


def _magnitude(eps: NDArray) -> NDArray:
    from ...continuum.learned_fields import field_magnitude

    return field_magnitude(eps)


def field_summary(units: dict[str, Any], rule: str, refine: int) -> dict[str, list[float]]:
    """Per refinement ``r``: relative L2 change of the field on the lattice triangles from
    ``r - 1`` (area-weighted), correlation with the network's field, and the area fraction
    whose change exceeds ``LOCALISED`` of the largest (native mesh)."""
    net = units[f"continuum_learning/network/{rule}"].arrays
    out: dict[str, list[float]] = {"change": [], "correlation": [], "localised": []}
    prev = None
    area0 = None
    for r in range(refine + 1):
        a = units[f"continuum_learning/refine{r}/{rule}"].arrays
        coarse = np.asarray(a["coarse"])
        if area0 is None:
            area0 = np.asarray(a["area"])
        w = np.sqrt(area0)[:, None]
        norm = float(np.linalg.norm(coarse * w))
        if prev is None or norm == 0:
            out["change"].append(math.nan)
        else:
            out["change"].append(float(np.linalg.norm((coarse - prev) * w)) / norm)
        prev = coarse
        c = np.corrcoef(coarse.ravel(), np.asarray(net["coarse"]).ravel())[0, 1]
        out["correlation"].append(float(c))
        mag = _magnitude(np.asarray(a["field"]))
        area = np.asarray(a["area"])
        top = float(mag.max())
        out["localised"].append(
            float(np.sum(area[mag > LOCALISED * top]) / np.sum(area)) if top > 0 else math.nan
        )
    return out
