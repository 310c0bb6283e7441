"""Number and mesh-size formatting shared by the parts of the ``continuum_learning``
section (:mod:`.continuum_learning`).
"""

from __future__ import annotations

import numpy as np


def _h(r: int) -> str:
    return "continuum h" if r == 0 else f"continuum h/{2**r}"


def _g(x: float, digits: int = 3) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"
