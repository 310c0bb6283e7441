"""The physical range of the learning degrees of freedom, relative to their initial values.

A learned stiffness stays within ``STIFFNESS_RANGE`` times its value when training started,
in every rule (``stiffness_range``) and in the optimum (:mod:`.optimum`), so a task that needs
more contrast than a material has is reported as infeasible, not met by a 1e5-fold stiffness
contrast. The default allows a stiffness contrast of 1e4 (soft rubber to stiff plastic).

Rest lengths: a rule's ``rest_length_range`` is None by default (the paper's rules move rest
lengths far, and its floor ``min_rest_length`` keeps them positive); the optimum, whose
search needs a box, keeps them within ``REST_LENGTH_RANGE`` (half to twice the initial).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check

__all__ = ["REST_LENGTH_RANGE", "STIFFNESS_RANGE", "check_range", "clip_to_range"]

#: (low, high) factors of the initial stiffness a learned stiffness stays within
STIFFNESS_RANGE = (1e-2, 1e2)
#: (low, high) factors of the initial rest length a learned rest length stays within
REST_LENGTH_RANGE = (0.5, 2.0)


def check_range(name: str, value: object) -> tuple[float, float] | None:
    """``None`` or a pair ``(low, high)`` with ``0 < low <= 1 <= high < inf``."""
    if value is None:
        return None
    what = "None or a pair (low, high) of factors with 0 < low <= 1 <= high < inf"
    try:
        low, high = (float(v) for v in value)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise check.ArgumentError(name, value, what) from None
    if not (np.isfinite(low) and np.isfinite(high) and 0.0 < low <= 1.0 <= high):
        raise check.ArgumentError(name, value, what)
    return (low, high)


def clip_to_range(
    old: NDArray, delta: NDArray, initial: NDArray, factors: tuple[float, float] | None
) -> NDArray:
    """``delta`` limited so that ``old + delta`` stays in ``factors * initial``.

    A value already outside the range (set by hand) is not pulled back: the bound stops a
    move further out, it never moves a value by itself.
    """
    if factors is None:
        return delta
    low = np.minimum(old, factors[0] * initial)
    high = np.maximum(old, factors[1] * initial)
    return np.clip(old + delta, low, high) - old
