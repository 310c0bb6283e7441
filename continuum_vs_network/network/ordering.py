"""Fill-reducing elimination orders for 2D networks: geometric nested dissection, and a
narrow-band order (reverse Cuthill-McKee, or a sweep across the network by rows) for the
banded Cholesky of mid-sized networks."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .model import spring_vectors, vector_lengths

__all__ = ["band_order", "coordinate_order", "nested_dissection"]


def nested_dissection(positions: NDArray, springs: NDArray, *, leaf: int = 64) -> NDArray[np.int64]:
    """Node elimination order by recursive coordinate bisection with vertex separators.

    The node set is split at the median of its longer extent; the nodes of one half that
    touch the other form the separator and are eliminated last. On 2D lattices this gives
    less fill than SuperLU's minimum degree and faster factorisations
    (``docs/solver-notes.md#ordering-nested-dissection``).

    Parameters
    ----------
    positions : (n_nodes, 2) float array
    springs : (n_springs, 2) int array
    leaf : int
        Sets of at most this many nodes are not split further.

    Returns
    -------
    (n_nodes,) int array, a permutation of the nodes.
    """
    n = positions.shape[0]
    adj = _adjacency(springs, n)
    on_right = np.zeros(n, dtype=bool)
    pieces: list[NDArray] = []
    stack: list[tuple[NDArray, bool]] = [(np.arange(n), False)]
    # iterative post-order: (set, expanded) — a separator is emitted after both halves
    while stack:
        idx, expanded = stack.pop()
        if expanded:
            pieces.append(idx)
            continue
        p = positions[idx]
        if idx.size <= leaf or np.ptp(p, axis=0).max() == 0.0:
            pieces.append(idx)
            continue
        axis = int(np.argmax(np.ptp(p, axis=0)))
        cut = np.median(p[:, axis])
        right_mask = p[:, axis] >= cut
        if right_mask.all() or not right_mask.any():
            pieces.append(idx)
            continue
        left, right = idx[~right_mask], idx[right_mask]
        on_right[right] = True
        rows = adj[left]
        row_of = np.repeat(np.arange(left.size), np.diff(rows.indptr))
        touches = np.bincount(row_of, weights=on_right[rows.indices], minlength=left.size)
        on_right[right] = False
        separator, left = left[touches > 0], left[touches == 0]
        stack.append((separator, True))
        stack.append((right, False))
        stack.append((left, False))
    return np.concatenate(pieces).astype(np.int64)


def coordinate_order(node_order: NDArray, free: NDArray) -> NDArray[np.int64]:
    """Flat free-coordinate indices (into ``x.ravel()``) in node elimination order.

    ``free`` is the (n_nodes, 2) mask of coordinates that move.
    """
    coords = np.stack([2 * node_order, 2 * node_order + 1], axis=1).ravel()
    return coords[free.ravel()[coords]]


def band_order(
    springs: NDArray, n_nodes: int, free: NDArray, positions: NDArray
) -> tuple[NDArray[np.int64], int]:
    """Free coordinates in a narrow-band order of the nodes, and the lower bandwidth of the
    Hessian assembled in that order.

    The narrowest of reverse Cuthill-McKee and a sweep across the network along each axis
    (:func:`_sweep`). Cuthill-McKee from one peripheral node (a corner) sweeps a lattice
    by its diagonals, up to 1.45x longer than its rows, so on a lattice the row sweep's
    band is usually the narrower (``docs/solver-notes.md#ordering-band``).

    Parameters
    ----------
    springs : (n_springs, 2) int array
    n_nodes : int
    free : (n_nodes, 2) bool array
    positions : (n_nodes, 2) float array

    Returns
    -------
    coords : (n_free,) int array, as :func:`coordinate_order`.
    bandwidth : int, the largest ``|row - column|`` of a coupled pair of free coordinates.
    """
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    adj = _adjacency(springs, n_nodes)
    lengths = vector_lengths(spring_vectors(positions, springs))
    reach = 0.5 * float(np.median(lengths)) if lengths.size else 0.0
    candidates = [reverse_cuthill_mckee(adj, symmetric_mode=True)]
    candidates += [_sweep(adj, positions, axis, reach) for axis in (0, 1)]
    best = None
    for nodes in candidates:
        coords = coordinate_order(nodes, free)
        width = _bandwidth(coords, springs, n_nodes)
        if best is None or width < best[1]:
            best = coords, width
    return best


def _adjacency(springs: NDArray, n_nodes: int) -> sp.csr_matrix:
    """The nodes' adjacency (n_nodes, n_nodes), one entry each way per spring."""
    return sp.coo_matrix(
        (np.ones(2 * len(springs)), (springs.ravel(), springs[:, ::-1].ravel())),
        shape=(n_nodes, n_nodes),
    ).tocsr()


def _sweep(adj: sp.csr_matrix, positions: NDArray, axis: int, reach: float) -> NDArray:
    """Nodes (n_nodes,) by their graph distance from the side where ``positions[:, axis]``
    is least (the nodes within ``reach`` of it: half the median spring length), each level
    along the other axis: a lattice's rows, one after the other, when they run across
    ``axis``."""
    from scipy.sparse.csgraph import dijkstra

    along = positions[:, axis]
    side = np.flatnonzero(along <= along.min(initial=0.0) + reach)
    level = dijkstra(adj, directed=False, indices=side, unweighted=True, min_only=True)
    return np.lexsort((positions[:, 1 - axis], level))


def _bandwidth(coords: NDArray, springs: NDArray, n_nodes: int) -> int:
    """The lower bandwidth of the Hessian of ``springs`` with free coordinates ``coords``
    (flat indices) as its rows, in that order."""
    row = np.full(2 * n_nodes, -1, dtype=np.int64)
    row[coords] = np.arange(coords.size)
    # rows of each spring's free coordinates (-1 where pinned): the band spans a spring's
    # extreme rows, and a node's own two coordinates are adjacent
    rows = row[np.stack([2 * springs[:, 0], 2 * springs[:, 0] + 1, 2 * springs[:, 1],
                         2 * springs[:, 1] + 1], axis=1)]  # fmt: skip
    top = rows.max(axis=1, initial=-1)
    low = np.where(rows >= 0, rows, top[:, None]).min(axis=1, initial=2 * n_nodes)
    return int(np.max(top - low, initial=1 if coords.size > 1 else 0))
