"""Clamp sets that no configuration meets, refused before a solve.

A clamped spring fixes the distance between its end nodes, and a fully pinned node its
position, so two pinned nodes are a fixed distance apart. Every such distance is at most
the sum along any other chain of clamped springs and pinned pairs between the same two
nodes (the triangle inequality, in any dimension). :func:`refuse_unreachable_clamps`
checks that with shortest paths over the clamps' end nodes, and raises one ``ValueError``
naming the chain where it fails: a clamped spring between two pinned nodes at another
distance, three clamped springs of a triangle whose longest side exceeds the other two,
clamps in a line between pins too short to span them. Unrefused, such a set costs a
whole solve (up to the iteration budget on the sparse path) and ends in "Hessian could
not be made positive definite" or a non-converging projection.

The check is necessary, not sufficient (a 2D embedding needs more), and it refuses only
clear violations (by more than ``1e-9`` relative): clamp lengths that add up exactly are
degenerate, not impossible, and the solvers name them so. Rods (``clamp="rod"``) stretch,
so for them only the single spring between two pins is refused: a rod there carries only
the pins' force, which no free coordinate measures. The chain check runs only where a chain
can exist (a node shared by two clamps, or two pinned clamp ends) and up
to ``_CHAIN_NODES_MAX`` clamp end nodes (its pinned pairs grow as their square).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import shortest_path

from .constraints import Problem

__all__ = ["refuse_unreachable_clamps"]

_SLACK = 1e-9  # relative: a distance longer than a chain by less is not refused
_CHAIN_NODES_MAX = 500  # clamp end nodes above which the chain check is skipped (O(k^2))


def refuse_unreachable_clamps(problem: Problem, x: NDArray) -> None:
    """Raise ``ValueError`` when the clamps of ``problem`` cannot all be met with the pins
    at their places in ``x`` (n_nodes, 2); see the module."""
    if not problem.n_clamps:
        return
    ends = problem.net.springs[problem.clamp_springs]  # (m, 2)
    held = ~problem.free[ends].any(axis=2)  # (m, 2): end node fully pinned
    _refuse_pinned_spring(problem, x, ends, held.all(axis=1))
    flat = ends.ravel().tolist()
    shared = len(set(flat)) < len(flat)
    if problem.clamp == "exact" and (shared or len(set(ends[held].tolist())) > 1):
        _refuse_short_chain(problem, x, ends)  # a chain exists: a shared node or two pins


def _refuse_pinned_spring(problem: Problem, x: NDArray, ends: NDArray, held: NDArray) -> None:
    """A clamped spring between two pinned nodes ``held`` (m,) at another distance."""
    if not held.any():
        return
    r = np.linalg.norm(x[ends[:, 1]] - x[ends[:, 0]], axis=1)
    wrong = held & (np.abs(r - problem.clamp_lengths) > 1e-12 * problem.clamp_lengths)
    if wrong.any():
        c = int(np.argmax(wrong))
        raise ValueError(
            f"clamped: spring {int(problem.clamp_springs[c])} has both end nodes pinned, "
            f"{r[c]:.6g} apart, so its clamp length {problem.clamp_lengths[c]:.6g} cannot "
            "be met; clamp it to that distance, or leave an end free"
        )


def _refuse_short_chain(problem: Problem, x: NDArray, ends: NDArray) -> None:
    """The shortest-path form of the triangle inequality over the clamps' end nodes."""
    nodes, local = np.unique(ends, return_inverse=True)
    if nodes.size > _CHAIN_NODES_MAX:
        return
    pinned = np.flatnonzero(~problem.free[nodes].any(axis=1))  # local indices
    local = local.reshape(ends.shape)
    # edges: (a, b, length, label) with label the clamped spring, or -1 for a pinned pair
    a = [local[:, 0]]
    b = [local[:, 1]]
    length = [np.asarray(problem.clamp_lengths, dtype=np.float64)]
    label = [np.asarray(problem.clamp_springs, dtype=np.int64)]
    if pinned.size > 1:
        i, j = np.triu_indices(pinned.size, 1)
        a.append(pinned[i])
        b.append(pinned[j])
        length.append(np.linalg.norm(x[nodes[pinned[j]]] - x[nodes[pinned[i]]], axis=1))
        label.append(np.full(i.size, -1))
    a, b, length, label = (np.concatenate(v) for v in (a, b, length, label))
    # the graph keeps the shorter of parallel edges (a pinned pair that is also clamped)
    shortest = _shortest_edges(a, b, length, label)
    pairs = np.array(list(shortest), dtype=np.int64).reshape(-1, 2)
    weights = np.array([w for w, _ in shortest.values()])
    graph = sp.coo_matrix((weights, (pairs[:, 0], pairs[:, 1])), shape=(nodes.size,) * 2)
    dist, previous = shortest_path(graph.tocsr(), directed=False, return_predecessors=True)
    excess = length / np.maximum(dist[a, b], 1e-300)
    worst = int(np.argmax(excess))
    if excess[worst] <= 1.0 + _SLACK:
        return
    p, q = int(a[worst]), int(b[worst])
    chain = _path(previous, p, q)
    steps = [shortest[(min(u, v), max(u, v))][1] for u, v in pairwise(chain)]
    springs = [s for s in steps if s >= 0]
    pinned_pairs = [
        (int(nodes[u]), int(nodes[v]))
        for (u, v), s in zip(pairwise(chain), steps, strict=True)
        if s < 0
    ]
    through = " and ".join(
        part
        for part in (
            f"clamped springs {springs}" if springs else "",
            f"pinned node pairs {pinned_pairs}" if pinned_pairs else "",
        )
        if part
    )
    what = (
        f"spring {int(label[worst])} is clamped to {length[worst]:.6g}"
        if label[worst] >= 0
        else f"nodes {int(nodes[p])} and {int(nodes[q])} are pinned {length[worst]:.6g} apart"
    )
    raise ValueError(
        f"clamped: {what}, more than the chain through {through} between nodes "
        f"{int(nodes[p])} and {int(nodes[q])} can span ({dist[p, q]:.6g}): no configuration "
        "meets these clamps (a distance cannot exceed the length of a chain between its "
        "ends); change the clamp lengths, or unpin a node"
    )


def _shortest_edges(a, b, length, label) -> dict[tuple[int, int], tuple[float, int]]:
    """``{(lo, hi): (length, label)}``: the shortest edge between each node pair."""
    best: dict[tuple[int, int], tuple[float, int]] = {}
    for p, q, w, s in zip(a.tolist(), b.tolist(), length.tolist(), label.tolist()):
        key = (min(p, q), max(p, q))
        if key not in best or w < best[key][0]:
            best[key] = (w, s)
    return best


def _path(previous: NDArray, start: int, end: int) -> list[int]:
    """The nodes of the shortest path from ``start`` to ``end`` (local indices)."""
    path = [end]
    while path[-1] != start:
        path.append(int(previous[start, path[-1]]))
    return path[::-1]
