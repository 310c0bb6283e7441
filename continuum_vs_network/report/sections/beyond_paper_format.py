"""Number formatting shared by the parts of the ``beyond_paper`` section
(:mod:`.beyond_paper`)."""

from __future__ import annotations

import numpy as np


def _g(x, digits: int = 3) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"
