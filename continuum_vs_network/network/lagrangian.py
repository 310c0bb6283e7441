"""The Lagrangian of a clamped equilibrium: its Hessian and the row order.

One implementation serves every solver of the package: :func:`~.newton.newton` (through
:func:`lagrangian_blocks`), the learning tracker's chord iteration, sensitivities (exact
gradients) and source sweeps.

* :class:`Frame`: the order of the free coordinates in assembled matrices for one topology
  and pin mask (fill-reducing above :data:`~..linalg.kkt.DENSE_MAX` rows), shared so that
  factorisations made anywhere match.
* :func:`lagrangian_blocks` / :func:`lagrangian_hessian`: ``W = H_E + sum_c mu_c d^2 r_c +
  rho A^T A`` per spring block and assembled.

The trust region that follows negative curvature is :mod:`.trust`'s (``relax`` and the
learning tracker's recovery use it).
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..linalg.kkt import DENSE_MAX, banded_pays, factor_spd, sparse_backend
from ..linalg.memo import per_array
from .constraints import Problem
from .energy import HessianPattern
from .length_jacobian import dense_jacobian_pays, length_jacobian
from .model import SpringNetwork, spring_vectors, vector_lengths
from .ordering import band_order, coordinate_order, nested_dissection

__all__ = ["Frame", "lagrangian_blocks", "lagrangian_hessian", "pattern_for"]


def pattern_for(
    springs: NDArray,
    n_nodes: int,
    free: NDArray,
    positions: NDArray,
    *,
    sparse_solver: str = "auto",
) -> HessianPattern:
    """The Hessian pattern of a topology and pin mask, cached while the springs array lives.

    Above ``DENSE_MAX`` free coordinates the rows follow a narrow-band order
    (:func:`~.ordering.band_order`) where its band is narrow enough for the banded
    Cholesky (:func:`~..linalg.kkt.banded_pays`, up to ~1e4 nodes on a lattice), else a
    nested-dissection elimination order; both are computed from ``positions`` (n_nodes,
    2); ``pattern.ordered`` says so, and a band-ordered pattern keeps ``positions`` for
    its nested-dissection rows (:meth:`~.energy.HessianPattern.nested_rows`). Not with
    PARDISO (``sparse_solver``, :func:`~..linalg.kkt.sparse_backend`; "auto": PARDISO when
    ``pypardiso`` imports), which orders by METIS itself (the nested dissection would cost
    seconds at 1e5 nodes for nothing). Networks
    made with ``with_*`` share their read-only springs array, so a learning loop builds the
    pattern once.
    """
    # shared by networks of equal small springs arrays (memo.per_array): the order depends
    # on positions only above DENSE_MAX free coordinates, which 256 springs cannot hold rigid
    per_topology = per_array(springs, "hessian_pattern")
    order = sparse_backend(sparse_solver) != "pardiso"
    key = (n_nodes, free.tobytes(), order)
    if key not in per_topology:
        coords = None
        banded = False
        if _reordered(free, sparse_solver):
            coords, width = band_order(springs, n_nodes, free, positions)
            banded = banded_pays(coords.size, width)
            if not banded:
                coords = coordinate_order(nested_dissection(positions, springs), free)
        pattern = HessianPattern(
            springs, n_nodes, free, coords, ordered=coords is not None,
            band_positions=positions if banded else None,
        )  # fmt: skip
        per_topology[key] = pattern
    return per_topology[key]


def _reordered(free: NDArray, sparse_solver: str = "auto") -> bool:
    """True when :func:`pattern_for` puts the rows of pin mask ``free`` in a fill-reducing
    order; otherwise they are the free coordinates in natural order."""
    if int(np.count_nonzero(free)) <= DENSE_MAX:
        return False
    return sparse_backend(sparse_solver) != "pardiso"


def lagrangian_blocks(problem: Problem, x: NDArray, lam: NDArray, rho: float) -> NDArray:
    """Per-spring 2x2 blocks of the augmented Lagrangian's Hessian, (n_springs, 2, 2).

    Axial ``k (+ rho)`` along ``u u^T`` and tangential ``k (1 - L/r) (+ lam / r)`` along
    ``I - u u^T``; rods add theirs on their spring's node pair.
    """
    net = problem.net
    springs, clamps = net.springs, problem.clamp_springs
    d = spring_vectors(x, springs)
    r = np.maximum(vector_lengths(d), 1e-300)
    axial = net.stiffness.copy()
    tangential = net.stiffness * (1.0 - net.rest_length / r)
    if problem.clamp == "rod" and problem.n_clamps:
        k_rod = problem.rod_stiffness
        axial[clamps] += k_rod
        tangential[clamps] += k_rod * (1.0 - problem.clamp_lengths / r[clamps])
    elif lam.size:
        axial[clamps] += rho
        tangential[clamps] += lam / r[clamps]
    # t I + (a - t) u u^T entry by entry (faster than forming u u^T blocks)
    ux, uy = d[:, 0] / r, d[:, 1] / r
    excess = axial - tangential
    out = np.empty((r.size, 2, 2))
    out[:, 0, 0] = tangential + excess * ux * ux
    out[:, 1, 1] = tangential + excess * uy * uy
    out[:, 0, 1] = out[:, 1, 0] = excess * ux * uy
    return out


class Frame:
    """The order of the free coordinates in assembled matrices, for one topology and pins.

    The core's :func:`~.newton.pattern_for` may order rows for
    fill reduction (``pattern.coords``); every vector and matrix this module builds uses
    the same order, so factorisations match the ones ``relax`` makes.

    Attributes
    ----------
    pattern : HessianPattern
    coords : (n,) int array
        Flat coordinate (index into ``x.ravel()``) of each row.
    index : (2 n_nodes,) int array
        Row of each flat coordinate, -1 for pinned ones.
    ordered : bool
        Rows are already in a fill-reducing order.
    sparse_solver : str
        The sparse factorisation of :meth:`factor` and the order it suits
        (:func:`pattern_for`).
    """

    def __init__(self, net: SpringNetwork, free: NDArray, *, sparse_solver: str = "auto") -> None:
        free = np.asarray(free, dtype=bool)
        self._pattern_args = (net.springs, net.n_nodes, free, net.positions)
        self.sparse_solver = sparse_solver
        if _reordered(free, sparse_solver):
            self.coords = np.asarray(self.pattern.coords)
            self.ordered = bool(self.pattern.ordered)
        else:  # natural order: the pattern is built only when a matrix is assembled
            self.coords = np.flatnonzero(free.ravel())
            self.ordered = False
        self.n_nodes = net.n_nodes
        self.n = int(self.coords.size)
        self.index = np.full(2 * net.n_nodes, -1, dtype=np.int64)
        self.index[self.coords] = np.arange(self.n)
        self._incidence: tuple[sp.csr_matrix, sp.csr_matrix] | None = None

    @functools.cached_property
    def pattern(self) -> HessianPattern:
        """The Hessian pattern of the topology and pins (:func:`pattern_for`), in row order."""
        return pattern_for(*self._pattern_args, sparse_solver=self.sparse_solver)

    def take(self, full: NDArray) -> NDArray:
        """Free entries of a (n_nodes, 2) array, in row order, (n,)."""
        return np.asarray(full).reshape(-1)[self.coords]

    def put(self, vec: NDArray) -> NDArray:
        """A (n_nodes, 2) array that is ``vec`` on free coordinates and 0 elsewhere."""
        out = np.zeros(2 * self.n_nodes)
        out[self.coords] = vec
        return out.reshape(self.n_nodes, 2)

    def rows(
        self, net: SpringNetwork, x: NDArray, springs: NDArray, *, dense: bool | None = None
    ) -> sp.csr_matrix | NDArray:
        """Length gradients ``dr_j/dx`` of ``springs`` (len(springs), n): a dense ndarray
        or a sparse CSR matrix (``dense=None``: whichever
        :func:`~.length_jacobian.dense_jacobian_pays` picks)."""
        springs = np.atleast_1d(np.asarray(springs, dtype=np.int64))
        if dense is None:
            dense = dense_jacobian_pays(springs.size, self.n)
        return length_jacobian(x, net.springs[springs], self.index, self.n, dense=dense)

    def gradient(self, net: SpringNetwork, x: NDArray) -> NDArray:
        """``dE/dx`` on free coordinates in row order, (n,), by two sparse products.

        Same values as :func:`~continuum_vs_network.network.energy.spring_gradient`
        (round-off aside); the incidence matrices are built once per frame.
        """
        return self.gradient_and_lengths(net, x)[0]

    def gradient_and_lengths(self, net: SpringNetwork, x: NDArray) -> tuple[NDArray, NDArray]:
        """:meth:`gradient` and the spring lengths ``r`` (n_springs,) it used."""
        if self._incidence is None:
            s = net.n_springs
            rows = np.concatenate([np.arange(s), np.arange(s)])
            cols = np.concatenate([net.springs[:, 0], net.springs[:, 1]])
            vals = np.concatenate([-np.ones(s), np.ones(s)])
            D = sp.csr_matrix((vals, (rows, cols)), shape=(s, net.n_nodes))
            self._incidence = (D, D.T.tocsr())
        D, Dt = self._incidence
        d = D @ x
        r = np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2)
        t = (net.stiffness * (r - net.rest_length) / np.maximum(r, 1e-300))[:, None] * d
        return (Dt @ t).reshape(-1)[self.coords], r

    def factor(self, W: sp.csr_matrix, *, rough: bool = False):
        """Positive-definite factorisation of ``W`` (None when it is not); ``rough``: an
        approximate one may serve (:func:`~..linalg.spd.factor_spd`)."""
        return factor_spd(W, ordered=self.ordered, rough=rough, sparse_solver=self.sparse_solver)


def lagrangian_hessian(
    problem: Problem,
    x: NDArray,
    multipliers: NDArray,
    *,
    rho: float | None = None,
    frame: Frame | None = None,
) -> sp.csr_matrix:
    """Hessian of the (augmented) Lagrangian on free coordinates, (n, n) CSR.

    ``W = H_E(x) + sum_c mu_c d^2 r_c / dx^2 + rho sum_c a_c a_c^T`` with ``a_c = dr_c/dx``
    the clamp directions and ``mu`` the multipliers of ``grad E + A^T mu = 0`` (minus
    ``Equilibrium.clamp_force``). ``rho`` (default ``max(k)`` when there are clamps) adds
    a multiple of ``A^T A`` that leaves every KKT solution unchanged but makes ``W``
    positive definite at a stable constrained minimum. Rows in ``frame`` order (default:
    the frame of ``problem``). Exact clamps only.
    """
    frame = frame or Frame(problem.net, problem.free, sparse_solver=problem.sparse_solver)
    if rho is None:
        rho = float(np.max(problem.net.stiffness)) if problem.n_clamps else 0.0
    blocks = lagrangian_blocks(problem, x, np.asarray(multipliers, float), float(rho))
    return frame.pattern.assemble(blocks)
