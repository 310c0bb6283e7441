"""Stiff springs put back to the lengths a linear step predicted (Gauss-Newton projection).

A linear step that rotates a spring lengthens it by ``|rotation|^2 r / 2``; for a spring
much stiffer than the rest that second-order error alone would veto the step. Both Newton
methods (:mod:`.trust`, :mod:`.newton`) therefore also try each trial step after moving it
the least onto the lengths the linear model predicted for the stiff springs and the exact
clamps.

The projection is called for most rejected trial steps, so it works on arrays alone: the Jacobian
``J`` (one row per stiff spring, ``-u`` and ``u`` on its end nodes' free coordinates) is
applied by gathers and scatters, and the pattern of ``J J^T`` (pairs of stiff springs on a
common free coordinate) is found once, so each factorisation only fills its values
(``scipy.sparse`` products would dominate the dense trust region's time:
``docs/solver-notes.md#stiff-springs-arrays``).
"""

from __future__ import annotations

import threading

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .constraints import Problem
from .length_jacobian import end_columns
from .model import unit_vectors

__all__ = ["StiffSprings", "median"]

_REGULARISATION = 1e-12  # added to J J^T's diagonal: over-determined stiff sets are singular


def median(a: NDArray) -> float:
    """``np.median`` of a non-empty 1-d array (the same value), without its overhead."""
    s = np.sort(a)
    return float((s[(s.size - 1) // 2] + s[s.size // 2]) / 2)


class StiffSprings:
    """Springs much stiffer than the network's median (and exact clamps), and a projection
    onto their lengths.

    ``springs`` (s, 2) node pairs; ``index`` (2 n_nodes,) the row of each flat coordinate
    in a move vector, -1 where the coordinate is pinned; ``n`` the move vector's length.

    ``restore(y, x, dx)`` moves ``y = x + dx`` the least (Gauss-Newton, minimum norm) so
    that every such spring has the length the linear model predicted,
    ``r(x) + u(x) . (dx_b - dx_a)``; None when that does not converge (:meth:`nearest`:
    the iterate nearest those lengths instead, and whether they were met).
    """

    CONTRAST = 10.0

    def __init__(self, springs: NDArray, index: NDArray, n: int) -> None:
        self.springs = springs
        self.n = n
        # the free flat coordinates and their rows, for scattering a move
        self.coords = np.flatnonzero(index >= 0)
        self.order = index[self.coords]
        rows = end_columns(springs, index)
        # J's column of each entry (s, 4); pinned entries point at a padding row n
        self._cols = np.where(rows >= 0, rows, n)
        self._gram = _GramPattern(self._cols, n)

    @classmethod
    def find(
        cls, problem: Problem, coords: NDArray, *, contrast: float | None = None
    ) -> StiffSprings | None:
        """Springs ``contrast`` (default :attr:`CONTRAST`) times stiffer than the median;
        ``coords`` the free flat coordinates in the order of a move vector."""
        contrast = cls.CONTRAST if contrast is None else contrast
        springs, k, _ = problem.all_springs()
        positive = k[k > 0]
        if not positive.size:
            return None
        stiff = np.flatnonzero(k > contrast * median(positive))
        if not stiff.size:
            return None
        if problem.exact:  # clamps are infinitely stiff springs: restored the same way
            stiff = np.union1d(stiff, problem.clamp_springs)
        index = np.full(2 * problem.net.n_nodes, -1, dtype=np.int64)
        index[coords] = np.arange(coords.size)
        return cls(springs[stiff], index, coords.size)

    def geometry(self, x: NDArray) -> tuple[NDArray, NDArray]:
        """Unit vectors ``u`` (s, 2) from each stiff spring's first node to its second, and
        lengths ``r`` (s,), at positions ``x`` (n_nodes, 2): ``J``'s rows are ``(-u, u)``."""
        return unit_vectors(x, self.springs)

    def lengthening(self, u: NDArray, move: NDArray) -> NDArray:
        """``J move`` (s,): each stiff spring's length change along ``move`` (n,), to first
        order."""
        padded = np.append(move, 0.0)[self._cols]
        return np.einsum("ij,ij->i", u, padded[:, 2:] - padded[:, :2])

    def spread(self, u: NDArray, w: NDArray) -> NDArray:
        """``J^T w`` (n,): the node forces of spring tensions ``w`` (s,) on the move rows
        (a Gauss-Newton correction is ``-J^T (J J^T)^-1`` of the length errors)."""
        values = np.concatenate([-u, u], axis=1) * w[:, None]
        return np.bincount(self._cols.ravel(), values.ravel(), self.n + 1)[: self.n]

    def restore(self, y: NDArray, x: NDArray, dx: NDArray) -> NDArray | None:
        """``y`` (n_nodes, 2) moved onto the predicted lengths, or None (:meth:`nearest`
        gave up)."""
        z, met = self.nearest(y, x, dx)
        return z if met else None

    def nearest(self, y: NDArray, x: NDArray, dx: NDArray) -> tuple[NDArray | None, bool]:
        """``(z, met)``: ``y`` (n_nodes, 2) moved onto the predicted lengths (``met``), or,
        where that gives up, the iterate nearest them (None when that is ``y`` itself).

        ``dx`` (n,) is the linear step in the row order of ``index``. A chord iteration:
        ``J J^T`` is factorised at the first iterate and reused while each correction cuts
        the length error at least 10-fold (refactorised otherwise: a factorisation per
        Gauss-Newton iteration would dominate the cost). Gives up
        when a correction with a fresh factorisation does not cut it 10-fold either: near
        reachable lengths Gauss-Newton converges quadratically, so that mostly means they
        are not reachable (rarely, reachable lengths of a large step are given up; the
        caller then keeps the unprojected point). Also gives up after 12 corrections.

        The nearest iterate serves the trust region: where the projection gives up, the
        partly projected point is usually far better than the plain one (the linear lengths
        of a long step are not worth meeting at any cost, so no 2-fold rule pushes on).
        Measurements: ``docs/solver-notes.md#stiff-springs-chord``.

        Not for threads sharing one network: the cached ``J J^T`` matrix is refilled in
        place (processes, as the package's own parallel runs use, are safe)."""
        u0, r0 = self.geometry(x)
        target = r0 + self.lengthening(u0, dx)
        tol = 1e-14 * max(float(np.max(r0)), 1e-300)
        z = y.copy()
        lu = None
        last = np.inf
        fresh = False  # the factorisation was made at the last iterate
        nearest, nearest_error = None, np.inf  # the best iterate after y
        for _ in range(12):
            u, r = self.geometry(z)
            c = r - target
            error = float(np.max(np.abs(c)))
            if error <= tol:
                return z, True
            if error < nearest_error:
                nearest, nearest_error = (z if nearest_error < np.inf else None), error
            if error > 0.1 * last:
                if fresh:  # Gauss-Newton itself is slow: the lengths are not reachable
                    return nearest, False
                lu = None
            fresh = lu is None
            if lu is None:
                try:
                    lu = spla.splu(self._gram.matrix(u))
                except RuntimeError:
                    return nearest, False
            last = error
            move = -self.spread(u, lu.solve(c))
            z = z.copy()
            z.ravel()[self.coords] += move[self.order]
            if not np.all(np.isfinite(z)):
                return nearest, False
        return nearest, False  # no convergence


class _GramPattern:
    """The sparsity of ``J J^T`` (s, s) for a Jacobian with four entries a row in columns
    ``cols`` (s, 4) (``n``: a pinned entry), found once; :meth:`matrix` fills the values.

    ``(J J^T)_st`` sums ``J_sc J_tc`` over the free coordinates ``c`` springs ``s`` and
    ``t`` share, so every pair of entries in one column adds one product to one stored
    value (``_slot``); the diagonal is stored even for a spring with no free coordinate.
    """

    def __init__(self, cols: NDArray, n: int) -> None:
        s = cols.shape[0]
        flat = cols.ravel()
        entries = np.flatnonzero(flat < n)
        by_column = entries[np.argsort(flat[entries], kind="stable")]
        column = flat[by_column]
        starts = np.flatnonzero(np.r_[True, column[1:] != column[:-1]])
        sizes = np.diff(np.r_[starts, column.size])
        group = np.repeat(np.arange(starts.size), sizes)  # each sorted entry's column group
        width = sizes[group]  # the size of that group, per entry
        first = np.repeat(by_column, width)
        within = np.arange(int(width.sum())) - np.repeat(np.cumsum(width) - width, width)
        second = by_column[np.repeat(starts[group], width) + within]
        key = np.concatenate([(second // 4) * s + first // 4, np.arange(s) * (s + 1)])
        stored, slot = np.unique(key, return_inverse=True)  # column-major: CSC order
        # kept for the network's lifetime: int32 where it fits (half the memory)
        small = np.int32 if key.size < 2**31 and 4 * s < 2**31 else np.int64
        self._first, self._second = first.astype(small), second.astype(small)  # pairs
        self._slot = slot[: first.size].astype(small)
        self._diagonal = slot[first.size :]
        indices = (stored % s).astype(np.int32)
        indptr = np.r_[0, np.cumsum(np.bincount(stored // s, minlength=s))].astype(np.int32)
        # one matrix per thread whose values are overwritten: building a new one each time
        # cost more than the values (SuperLU copies what it factorises); per thread, since
        # the pattern is kept with the network and threads may relax one network at once
        self._gram = sp.csc_matrix((np.zeros(indices.size), indices, indptr), shape=(s, s))
        self._local = threading.local()

    def matrix(self, u: NDArray) -> sp.csc_matrix:
        """``J J^T + 1e-12 I`` for unit vectors ``u`` (s, 2), ``J``'s rows ``(-u, u)``: the
        same matrix object at each call from one thread, its values overwritten (factorise
        it before the next call)."""
        values = np.concatenate([-u, u], axis=1).ravel()
        gram = getattr(self._local, "gram", None)
        if gram is None:
            gram = self._local.gram = self._gram.copy()
        data = gram.data
        data[:] = np.bincount(self._slot, values[self._first] * values[self._second], data.size)
        data[self._diagonal] += _REGULARISATION
        return gram
