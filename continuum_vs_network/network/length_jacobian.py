"""Length Jacobians of springs: ``dr/dx`` rows ``[-u_j, +u_j]`` on each spring's end
coordinates, dense or sparse, and the linear chord-strain rows built from them."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.spd import DENSE_MAX
from .model import unit_vectors

__all__ = ["dense_jacobian_pays", "end_columns", "length_jacobian", "strain_jacobian"]

DENSE_JACOBIAN = 100_000  # entries: a length Jacobian this small is kept dense (0.8 MB)


def dense_jacobian_pays(m: int, n: int) -> bool:
    """True when an (m, n) length Jacobian is cheaper dense: ``n <= DENSE_MAX`` or at most
    ``DENSE_JACOBIAN`` entries. Below that scipy.sparse's construction and products cost
    more than the dense arithmetic (``docs/solver-notes.md#constraints``)."""
    return n <= DENSE_MAX or m * n <= DENSE_JACOBIAN


def end_columns(pairs: NDArray, column: NDArray) -> NDArray:
    """``column`` (2 n_nodes,) at the four end coordinates of each spring of ``pairs`` (m,
    2): (m, 4), first node x, y then second node x, y (-1 stays -1: pinned)."""
    a, b = pairs[:, 0], pairs[:, 1]
    return column[np.stack([2 * a, 2 * a + 1, 2 * b, 2 * b + 1], axis=1)]


def length_jacobian(
    x: NDArray, pairs: NDArray, column: NDArray, n: int, *, dense: bool
) -> sp.csr_matrix | NDArray:
    """``dr/dx`` (m, n) of the springs with node pairs ``pairs`` (m, 2) at ``x`` (n_nodes,
    2): row ``j`` is ``-u_j`` on its first node's and ``+u_j`` on its second node's
    coordinates, in columns ``column`` (2 n_nodes,) (-1: a pinned coordinate, left out);
    a dense ndarray or a sparse CSR matrix."""
    m = len(pairs)
    u, _ = unit_vectors(x, pairs)
    cols = end_columns(pairs, column)
    vals = np.concatenate([-u, u], axis=1)
    if dense:
        out = np.zeros((m, n + 1))  # column n collects the pinned entries
        out[np.arange(m)[:, None], np.where(cols >= 0, cols, n)] = vals
        return out[:, :n]
    keep = cols >= 0
    rows = np.broadcast_to(np.arange(m)[:, None], cols.shape)
    return sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(m, n))


def strain_jacobian(x: NDArray, pairs: NDArray) -> sp.csr_matrix:
    """``d(r/r_x)/dx`` (m, 2 n_nodes) at ``x`` (n_nodes, 2): the linear chord-strain rows
    ``u_j . (dx_b - dx_a) / r_j`` of the springs with node pairs ``pairs`` (m, 2), ``r_j``
    their lengths at ``x``; sparse CSR over every coordinate."""
    n = 2 * len(x)
    _, r = unit_vectors(x, pairs)
    J = length_jacobian(x, pairs, np.arange(n), n, dense=False)
    return sp.diags(1.0 / r) @ J
