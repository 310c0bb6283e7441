"""Numerical safeguards shared by the first-order minimisers and the dynamics.

* :func:`spring_energy_change`: ``E(x) - E(x_ref)`` computed without cancellation, so line
  searches can compare energies near a minimum, where differences are ~ residual^2 / k and
  drown in ``eps * E`` when the two energies are subtracted.
* :func:`hessian_norm_bound`: a Gershgorin bound on the largest eigenvalue of the Hessian,
  which sets the stable step of explicit schemes (FIRE, explicit dynamics).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["hessian_norm_bound", "node_stiffness", "spring_energy_change"]


def spring_energy_change(
    x: NDArray, x_ref: NDArray, springs: NDArray, k: NDArray, L: NDArray
) -> float:
    """``E(x) - E(x_ref)`` for ``E = sum k (r - L)^2 / 2``, free of cancellation.

    With ``d = x_b - x_a``, the length change is ``r - r0 = (d - d0).(d + d0) / (r + r0)``
    with ``d - d0`` taken from the displacements ``x - x_ref``, and
    ``(r - L)^2 - (r0 - L)^2 = (r - r0)(r + r0 - 2 L)``: the round-off is relative to the
    change, not to ``E``.

    Parameters
    ----------
    x, x_ref : (n_nodes, 2) float arrays
    springs : (n_springs, 2) int array
    k, L : (n_springs,) float arrays

    Returns
    -------
    float, energy units.
    """
    u = x - x_ref
    a, b = springs[:, 0], springs[:, 1]
    d = x[b] - x[a]
    d0 = x_ref[b] - x_ref[a]
    r = np.hypot(d[:, 0], d[:, 1])
    r0 = np.hypot(d0[:, 0], d0[:, 1])
    dr = np.einsum("ij,ij->i", u[b] - u[a], d + d0) / np.maximum(r + r0, 1e-300)
    return float(0.5 * np.dot(k, dr * (r + r0 - 2.0 * L)))


def node_stiffness(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> NDArray:
    """Per node, the sum over incident springs of the norm of their 2x2 Hessian block.

    A spring's block ``k [u u^T + (1 - L/r)(I - u u^T)]`` has eigenvalues ``k`` and
    ``k (1 - L/r)``, so its norm is ``k max(1, |1 - L/r|)`` (``k`` unless the spring is
    compressed below half its rest length). Returns a (n_nodes,) float array.
    """
    d = x[springs[:, 1]] - x[springs[:, 0]]
    r = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)
    w = k * np.maximum(1.0, np.abs(1.0 - L / r))
    n = x.shape[0]
    return np.bincount(springs[:, 0], w, n) + np.bincount(springs[:, 1], w, n)


def hessian_norm_bound(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> float:
    """Upper bound on the largest eigenvalue of the Hessian at ``x`` (force per length).

    Block Gershgorin: every eigenvalue lies within ``sum ||off-diagonal blocks||`` of an
    eigenvalue of a diagonal block, so ``lambda_max <= 2 max_nodes node_stiffness``
    (``2 max_nodes sum_incident k`` near rest lengths). Pinning coordinates only removes
    rows, so the bound also holds for the Hessian restricted to free coordinates.
    """
    if x.shape[0] == 0 or springs.shape[0] == 0:
        return 0.0
    return float(2.0 * np.max(node_stiffness(x, springs, k, L)))
