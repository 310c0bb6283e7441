"""Elastic energy, gradient and sparse Hessian of a spring network (Eq. 11).

:func:`spring_energy_change` gives ``E(x) - E(x_ref)`` without cancellation (line searches
near a minimum) and :func:`hessian_norm_bound` a Gershgorin bound on the Hessian's largest
eigenvalue (stable steps of explicit schemes).

The kernels take plain arrays so that extra springs (the paper's clamping rods) can be
added without building a new :class:`SpringNetwork`; :func:`energy`, :func:`gradient` and
:func:`hessian` are the same kernels applied to a network.

Per spring ``j`` between nodes ``a -> b`` with ``d = x_b - x_a``, ``r = |d|``, ``u = d / r``:

* energy ``k (r - L)^2 / 2``,
* force on ``b`` ``-k (r - L) u`` (Eq. 9),
* Hessian block ``K = k [u u^T + (1 - L / r)(I - u u^T)]`` at ``(a,a)`` and ``(b,b)``,
  ``-K`` at ``(a,b)`` and ``(b,a)``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .. import _validate as check
from ..linalg.memo import per_array
from .model import SpringNetwork, spring_vectors, vector_lengths
from .ordering import coordinate_order, nested_dissection

__all__ = [
    "HessianPattern",
    "energy",
    "forces",
    "gradient",
    "hessian",
    "hessian_norm_bound",
    "node_stiffness",
    "spring_bending",
    "spring_bending_on",
    "spring_energy",
    "spring_energy_change",
    "spring_gradient",
    "spring_hessian_blocks",
]

_TINY = 1e-300
_XY = np.arange(2)


def _geometry(x: NDArray, springs: NDArray) -> tuple[NDArray, NDArray]:
    d = spring_vectors(x, springs)
    r = vector_lengths(d)
    return d, r


def spring_energy(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> float:
    """Total energy ``sum k (r - L)^2 / 2`` of springs at positions ``x`` (n_nodes, 2)."""
    _, r = _geometry(x, springs)
    return float(0.5 * np.dot(k, (r - L) ** 2))


def spring_gradient(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> NDArray:
    """Gradient ``dE/dx`` as a (n_nodes, 2) array (the negative of the net force)."""
    d, r = _geometry(x, springs)
    t = (k * (r - L) / np.maximum(r, _TINY))[:, None] * d  # tension vector along a -> b
    return _scatter_nodes(t, springs, x.shape[0])


def spring_bending(x: NDArray, step: NDArray, springs: NDArray, k: NDArray) -> NDArray:
    """The force (n_nodes, 2) of the springs' second-order length change along ``step``
    (n_nodes, 2) from ``x``: ``J^T (k |dd_perp|^2 / r)``, with ``dd_perp`` the part of a
    spring's change perpendicular to it (a linear step that turns a spring lengthens it by
    ``|dd_perp|^2 / (2 r)``). The Hessian's solve of it is the step's geodesic acceleration
    (Transtrum & Sethna 2012)."""
    d, r = _geometry(x, springs)
    r = np.maximum(r, _TINY)
    u = d / r[:, None]
    dd = spring_vectors(step, springs)
    perp = dd[:, 0] * u[:, 1] - dd[:, 1] * u[:, 0]
    return _scatter_nodes((k * perp * perp / r)[:, None] * u, springs, x.shape[0])


def spring_bending_on(
    x: NDArray, coords: NDArray, step: NDArray, springs: NDArray, k: NDArray
) -> NDArray:
    """:func:`spring_bending` of a ``step`` (n,) of the flat coordinates ``coords`` (the
    others held), on those coordinates (n,)."""
    moved = np.zeros(x.size)
    moved[coords] = step
    return spring_bending(x, moved.reshape(x.shape), springs, k).ravel()[coords]


def _scatter_nodes(t: NDArray, springs: NDArray, n_nodes: int) -> NDArray:
    """Node sums of ``+t`` at each spring's second node and ``-t`` at its first."""
    ends = _flat_ends(springs)
    if ends is None:
        g = np.empty((n_nodes, 2))
        for c in range(2):
            g[:, c] = np.bincount(springs[:, 1], t[:, c], n_nodes) - np.bincount(
                springs[:, 0], t[:, c], n_nodes
            )
        return g
    # one bincount per end on the flat coordinates 2 node + c: every bin sums the same
    # terms in the same (spring) order as the bincounts per coordinate, so the same values
    w = t.ravel()
    g = np.bincount(ends[1], w, 2 * n_nodes)
    g -= np.bincount(ends[0], w, 2 * n_nodes)
    return g.reshape(n_nodes, 2)


def _flat_ends(springs: NDArray) -> tuple[NDArray, NDArray] | None:
    """The flat coordinates ``2 a + (0, 1)`` and ``2 b + (0, 1)`` of every spring, (2 s,)
    each, for a network's read-only springs array that owns its data (kept while it lives);
    None for others (rods appended, writeable arrays, views) and above
    :data:`SCATTER_MAX_SPRINGS`."""
    if (
        springs.flags.writeable
        or not springs.flags.owndata  # a read-only view of an array that may still change
        or len(springs) > SCATTER_MAX_SPRINGS
        or springs.ndim != 2
    ):
        return None
    store = per_array(springs, "flat_ends")
    if "ends" not in store:
        store["ends"] = tuple((2 * springs[:, e, None] + _XY).ravel() for e in (0, 1))
    return store["ends"]


def spring_hessian_blocks(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> NDArray:
    """Per-spring 2x2 blocks ``k [u u^T + (1 - L/r)(I - u u^T)]``, shape (n_springs, 2, 2)."""
    d, r = _geometry(x, springs)
    r_safe = np.maximum(r, _TINY)
    u = d / r_safe[:, None]
    uu = u[:, :, None] * u[:, None, :]
    tangential = (k * (1.0 - L / r_safe))[:, None, None]
    return k[:, None, None] * uu + tangential * (np.eye(2) - uu)


SCATTER_MAX_SPRINGS = 300_000  # HessianPattern keeps a +-1 matrix (~57 MB) up to this


class HessianPattern:
    """Sparsity pattern of the Hessian for one topology, built once and reused.

    Parameters
    ----------
    springs : (n_springs, 2) int array
    n_nodes : int
    free : (n_nodes, 2) bool array, optional
        Coordinates kept in the assembled matrix (default all). Pinned coordinates are
        dropped, so the matrix is the Hessian restricted to free coordinates, in the order
        of ``np.flatnonzero(free.ravel())``.
    coords : (n_free,) int array, optional
        Flat coordinate index (into ``x.ravel()``) of each matrix row, to assemble in a
        chosen elimination order; overrides ``free``. ``self.coords`` holds the order used.
    ordered : bool
        The rows are in a fill-reducing order, which factorisations keep
        (:func:`~..linalg.kkt.factor_spd`'s ``ordered``).
    band_positions : (n_nodes, 2) float array, optional
        The positions a narrow-band row order was computed from: :meth:`nested_rows`
        orders the rows by nested dissection of them (None: the rows are not in band order).

    ``assemble(blocks)`` scatters per-spring 2x2 blocks into a CSR matrix in O(nnz) with one
    sparse product.
    """

    def __init__(
        self,
        springs: NDArray,
        n_nodes: int,
        free: NDArray | None = None,
        coords: NDArray | None = None,
        *,
        ordered: bool = False,
        band_positions: NDArray | None = None,
    ) -> None:
        springs = np.asarray(springs, dtype=np.int64)
        if coords is None:
            free = np.ones((n_nodes, 2), dtype=bool) if free is None else np.asarray(free, bool)
            coords = np.flatnonzero(free.ravel())
        self.springs = springs
        self.n_nodes = n_nodes
        self.coords = np.asarray(coords, dtype=np.int64)
        index = np.full(2 * n_nodes, -1, dtype=np.int64)
        index[self.coords] = np.arange(self.coords.size)
        self.size = int(self.coords.size)

        a, b = springs[:, 0], springs[:, 1]
        # coordinates of the four node pairs (aa, bb, ab, ba), each with 2x2 entries
        rows_nodes = np.stack([a, b, a, b], axis=1)  # (s, 4)
        cols_nodes = np.stack([a, b, b, a], axis=1)
        ci = np.arange(2)
        rows = 2 * rows_nodes[:, :, None, None] + ci[None, None, :, None]
        cols = 2 * cols_nodes[:, :, None, None] + ci[None, None, None, :]
        rows = np.broadcast_to(rows, (len(springs), 4, 2, 2)).ravel()
        cols = np.broadcast_to(cols, (len(springs), 4, 2, 2)).ravel()
        r_idx, c_idx = index[rows], index[cols]
        keep = (r_idx >= 0) & (c_idx >= 0)
        self._keep = keep
        key = r_idx[keep] * self.size + c_idx[keep]
        uniq, slot = np.unique(key, return_inverse=True)
        self._flat = uniq  # position of each stored entry in the dense (size, size) matrix
        self._slot = slot.ravel()
        self._nnz = int(uniq.size)
        self._indices = (uniq % self.size).astype(np.int32)
        row_of = uniq // self.size
        self._indptr = np.searchsorted(row_of, np.arange(self.size + 1)).astype(np.int32)
        self.free_index = index
        self.ordered = ordered
        self.band_positions = band_positions
        self._nested_rows: NDArray | None = None
        self._scatter: sp.csr_matrix | None = None

    def nested_rows(self) -> NDArray | None:
        """The rows (n_free,) in nested-dissection order where they are in band order
        (``band_positions`` given), else None; made on first use and kept.

        SuperLU's directions of negative curvature depend on the order, and the shift
        newton estimates from them steers its iterations: they are read in this order
        whatever factorisation is used. Made on first use, not with every pattern: most
        solves read no such direction (``docs/solver-notes.md#energy``).
        """
        if self.band_positions is None:
            return None
        if self._nested_rows is None:
            free = (self.free_index >= 0).reshape(-1, 2)
            order = nested_dissection(self.band_positions, self.springs)
            self._nested_rows = self.free_index[coordinate_order(order, free)]
        return self._nested_rows

    def _data(self, blocks: NDArray) -> NDArray:
        """The stored entries (nnz,) from per-spring blocks (n_springs, 2, 2): one product
        with a (nnz, 4 n_springs) matrix of +-1 built on first use (faster than
        scattering the signed blocks with ``np.bincount``); above
        ``SCATTER_MAX_SPRINGS`` springs, where that matrix's memory would count, the
        scatter."""
        s = self.springs.shape[0]
        if s > SCATTER_MAX_SPRINGS:  # the product's matrix would cost 190 bytes a spring
            signed = np.stack([blocks, blocks, -blocks, -blocks], axis=1).ravel()[self._keep]
            return np.bincount(self._slot, weights=signed, minlength=self._nnz)
        if self._scatter is None:
            # entry (spring i, pair j, a, b) of the signed stack is sign_j * blocks[i, a, b]
            source = np.broadcast_to(np.arange(4 * s).reshape(s, 1, 2, 2), (s, 4, 2, 2))
            sign = np.broadcast_to(np.array([1.0, 1.0, -1.0, -1.0])[:, None, None], (s, 4, 2, 2))
            self._scatter = sp.csr_matrix(
                (sign.ravel()[self._keep], (self._slot, source.ravel()[self._keep])),
                shape=(self._nnz, 4 * s),
            )
            self._scatter.sum_duplicates()
        return self._scatter @ np.asarray(blocks, dtype=np.float64).reshape(-1)

    def assemble_dense(self, blocks: NDArray) -> NDArray:
        """Dense (size, size) array from per-spring blocks: for small problems, where
        scipy.sparse's per-call overhead costs more than the arithmetic."""
        dense = np.zeros(self.size * self.size)
        dense[self._flat] = self._data(blocks)
        return dense.reshape(self.size, self.size)

    def assemble(self, blocks: NDArray, shift: float = 0.0) -> sp.csr_matrix:
        """CSR matrix from per-spring blocks (n_springs, 2, 2), plus ``shift * I``."""
        data = self._data(blocks)
        mat = sp.csr_matrix((data, self._indices, self._indptr), shape=(self.size, self.size))
        if shift:
            mat = mat + shift * sp.identity(self.size, format="csr")
        return mat


def _state(x: NDArray, net: SpringNetwork) -> NDArray:
    """``x`` checked against ``net`` (the public functions' arguments)."""
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    return check.float_array("x", x, (net.n_nodes, 2))


def energy(x: NDArray, net: SpringNetwork) -> float:
    """Elastic energy of ``net`` at positions ``x`` (n_nodes, 2) (Eq. 11)."""
    return spring_energy(_state(x, net), net.springs, net.stiffness, net.rest_length)


def gradient(x: NDArray, net: SpringNetwork) -> NDArray:
    """``dE/dx`` of ``net`` at ``x``: (n_nodes, 2) float array."""
    return spring_gradient(_state(x, net), net.springs, net.stiffness, net.rest_length)


def forces(x: NDArray, net: SpringNetwork) -> NDArray:
    """Net spring force on every node, ``-dE/dx``: (n_nodes, 2) float array."""
    return -gradient(x, net)


def hessian(x: NDArray, net: SpringNetwork, pattern: HessianPattern | None = None) -> sp.csr_matrix:
    """Sparse Hessian ``d^2E/dx^2`` (2 n_nodes, 2 n_nodes), coordinates ordered x0, y0, x1, ...

    Pass a ``pattern`` built once for the topology to skip the symbolic work.
    """
    x = _state(x, net)
    pattern = pattern or HessianPattern(net.springs, net.n_nodes)
    blocks = spring_hessian_blocks(x, net.springs, net.stiffness, net.rest_length)
    return pattern.assemble(blocks)


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
    d, r = _geometry(x, springs)
    d0, r0 = _geometry(x_ref, springs)
    u = x - x_ref
    du = np.take(u, springs[:, 1], axis=0) - np.take(u, springs[:, 0], axis=0)
    dr = np.einsum("ij,ij->i", du, d + d0) / np.maximum(r + r0, 1e-300)
    return float(0.5 * np.dot(k, dr * (r + r0 - 2.0 * L)))


def node_stiffness(x: NDArray, springs: NDArray, k: NDArray, L: NDArray) -> NDArray:
    """Per node, the sum over incident springs of the norm of their 2x2 Hessian block.

    A spring's block ``k [u u^T + (1 - L/r)(I - u u^T)]`` has eigenvalues ``k`` and
    ``k (1 - L/r)``, so its norm is ``k max(1, |1 - L/r|)`` (``k`` unless the spring is
    compressed below half its rest length). Returns a (n_nodes,) float array.
    """
    d = spring_vectors(x, springs)
    r = np.maximum(vector_lengths(d), 1e-300)
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
