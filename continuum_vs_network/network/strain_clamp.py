"""A clamp that fixes only a spring's length (strain), held in time by a stiff rod.

:func:`~.dynamics.simulate`'s ``clamped`` holds a clamp as a prescribed displacement of
the clamped spring's two end nodes (they cannot rotate or translate). The continuum holds
its source strains as constraints ``G u = S`` and leaves the material points free
otherwise. :func:`rod_clamped` gives the network the continuum's clamp by a penalty: each
clamped spring becomes a rod of stiffness ``factor * mean(k)`` and rest length the clamp
length, with no node held. Its strain error is ``f / (k_rod L)`` for a rod tension ``f``
(:func:`rod_strain_error`), ``~ 1 / factor`` of the clamp's strain change. Backward Euler
(``scheme="implicit"``) is L-stable, so the rod's stiff mode (rate ``k_rod / c``) is damped
in one step whatever ``dt``; the other modes keep their rates up to ``O(1 / factor)``.

:func:`simulate_strain_clamped` runs :func:`~.dynamics.simulate` on the rod network with
the implicit solver's force tolerance set against the *original* network's force scale
(the rods would otherwise raise ``mean(k)``, the unit of the relative tolerance, by
``factor * n_clamps / n_springs``), floored above the rods' rounding noise. Linearised
about the rod network's *initial* state, the rods are compressed by the clamp step and its
Hessian is indefinite; the run's modes are those about its end state, where each rod's
tension is the constraint force.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from .model import SpringNetwork

__all__ = ["ROD_FACTOR", "rod_clamped", "rod_strain_error", "simulate_strain_clamped"]

#: rod stiffness over the network's mean stiffness
ROD_FACTOR = 1e6


def rod_clamped(
    net: SpringNetwork, clamped: Mapping[int, float], *, factor: float = ROD_FACTOR
) -> SpringNetwork:
    """``net`` with every clamped spring a rod: stiffness ``factor * mean(k)``, rest length
    the clamp length (``clamped``: ``{spring: length}``, lengths finite and > 0)."""
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"factor must be finite and > 0, got {factor}")
    k = np.array(net.stiffness, dtype=float)
    L = np.array(net.rest_length, dtype=float)
    k_rod = factor * float(np.mean(net.stiffness))
    for spring, length in clamped.items():
        j = int(spring)
        if not 0 <= j < net.n_springs:
            raise ValueError(f"clamped names spring {j} outside 0..{net.n_springs - 1}")
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"clamped length of spring {j} must be finite and > 0, got {length}")
        k[j], L[j] = k_rod, float(length)
    return net.with_stiffness(k).with_rest_length(L)


def rod_strain_error(net: SpringNetwork, clamped: Mapping[int, float], x) -> NDArray:
    """Strain of each clamped spring at positions ``x`` relative to its clamp length,
    ``r / length - 1`` (in the order of ``clamped``)."""
    springs = np.array([int(s) for s in clamped], dtype=int)
    lengths = np.array([float(v) for v in clamped.values()])
    return net.lengths(np.asarray(x, dtype=float), springs) / lengths - 1.0


def simulate_strain_clamped(
    net: SpringNetwork,
    *,
    clamped: Mapping[int, float],
    factor: float = ROD_FACTOR,
    tol: float = 1e-10,
    **kwargs,
):
    """:func:`~.dynamics.simulate` with ``clamped`` held as rods (:func:`rod_clamped`), no
    node held by a clamp; the other keywords go to ``simulate`` (``clamped`` is not
    passed on). ``tol`` is relative to ``net``'s force scale, not the rod network's, but
    not below ``100 eps factor`` (a hundred times the rods' rounding noise; a step whose
    starting force is below that does not move, so the run stalls at a distance ``~ 100 eps
    factor F / lambda_min`` from its end state; a tighter floor lets the noise fail the line
    search). Returns the :class:`~.dynamics.Trajectory` of the rod network (all nodes)."""
    from .dynamics import simulate

    rods = rod_clamped(net, clamped, factor=factor)
    tol = max(float(tol), 100.0 * np.finfo(float).eps * float(factor))
    return simulate(rods, tol=tol * net.force_scale / rods.force_scale, **kwargs)
