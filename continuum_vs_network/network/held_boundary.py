"""Boundary conditions of a dynamic run (:mod:`.dynamics`), all held from ``t = 0``:

* ``pinned``: coordinates held at their starting values;
* ``prescribed``: ``{node: (x, y)}``, nodes moved to a position at ``t = 0`` (a step) and
  held there;
* ``clamped``: ``{spring: length}``, a clamp imposed as a prescribed displacement of the
  clamped spring's two end nodes: they move apart (or together) symmetrically along the
  spring to the clamp length at ``t = 0`` and are then held. This is what a continuum
  comparison imposes (a displacement boundary condition on two small regions); unlike the
  equilibrium clamp of :func:`~.equilibrium.relax` the clamped spring cannot also rotate
  or translate. An exact length constraint would need a differential-algebraic
  integrator; rods would need a step ~ 1/sqrt(1e10) in explicit schemes.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .constraints import Pins, pin_mask
from .model import SpringNetwork

__all__ = ["held_boundary"]


def held_boundary(
    net: SpringNetwork,
    pinned: Pins,
    prescribed: Mapping[int, ArrayLike] | None,
    clamped: Mapping[int, float] | None,
    x0: ArrayLike | None,
) -> tuple[NDArray, NDArray]:
    """Starting positions with prescribed and clamped nodes moved, and the free mask."""
    n = net.n_nodes
    x = net.positions.copy() if x0 is None else np.array(x0, dtype=np.float64, copy=True)
    if x.shape != (n, 2):
        raise ValueError(f"x0 must have shape ({n}, 2), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x0 must be finite")
    fixed = np.zeros((n, 2), dtype=bool) if pinned is None else pin_mask(net, pinned)
    held = np.zeros(n, dtype=bool)  # nodes moved by prescribed/clamped
    for node, pos in (prescribed or {}).items():
        i = int(node)
        if not 0 <= i < n:
            raise ValueError(f"prescribed names node {node} outside 0..{n - 1}")
        p = np.asarray(pos, dtype=np.float64)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ValueError(f"prescribed position of node {i} must be 2 finite numbers, got {pos}")
        x[i] = p
        held[i] = True
    for spring, length in (clamped or {}).items():
        j = int(spring)
        if not 0 <= j < net.n_springs:
            raise ValueError(f"clamped names spring {spring} outside 0..{net.n_springs - 1}")
        length = float(length)
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"clamped length of spring {j} must be finite and > 0, got {length}")
        a, b = net.springs[j]
        if held[a] or held[b]:
            raise ValueError(
                f"clamped spring {j} shares node {a if held[a] else b} with "
                "another clamp or a prescribed node"
            )
        d = x[b] - x[a]
        r = float(np.hypot(*d))
        if r == 0.0:
            raise ValueError(f"clamped spring {j} has zero length at the start")
        grow = (length - r) * d / r
        stay_a, stay_b = fixed[a].all(), fixed[b].all()
        if stay_a and stay_b:
            raise ValueError(f"clamped spring {j}: both end nodes are pinned")
        if stay_a:
            x[b] += grow
        elif stay_b:
            x[a] -= grow
        else:
            x[a] -= 0.5 * grow
            x[b] += 0.5 * grow
        held[[a, b]] = True
    fixed[held] = True
    return x, ~fixed
