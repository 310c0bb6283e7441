"""Boundary conditions of an equilibrium problem: pins (Dirichlet) and clamps (fixed lengths).

A pin fixes single coordinates at their starting values. A clamp fixes the length of a
spring (Eq. 25), either exactly (an equality constraint ``r_c - l_c = 0`` whose Lagrange
multiplier is the clamp force) or, as in the paper, with a stiff ``rod``: an extra spring of
stiffness ``rod_stiffness`` and rest length ``l_c`` on the same node pair.

:class:`Problem` bundles a network with its boundary conditions and gives every solver the
same energy, gradient, constraint Jacobian and residual.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .._validate import choice, index_array, real
from ..linalg.memo import per_network
from ..linalg.spd import SPARSE_SOLVERS
from .arguments import clamp_arrays, pin_mask_or_indices
from .energy import spring_energy, spring_gradient
from .length_jacobian import dense_jacobian_pays, length_jacobian
from .model import SpringNetwork, spring_vectors, vector_lengths
from .stopping import StopRule, coordinate_scale

__all__ = ["Problem", "Residual", "clamp_tensions", "default_pins", "pin_mask"]

ClampMode = Literal["exact", "rod"]
Pins = Sequence[int] | NDArray | None


def default_pins(net: SpringNetwork, avoid: ArrayLike = ()) -> NDArray[np.bool_]:
    """Pins that remove rigid-body motion: one node fully, one coordinate of a far node.

    The first node is the one farthest from the springs in ``avoid`` (sources and targets;
    the network's centre when empty); the second is the node farthest from the first, pinned
    in the coordinate that a rotation about the first node would move most. Adjacent pins
    leave a very soft rotation mode in large lattices; far pins do not.

    Returns a (n_nodes, 2) bool mask.
    """
    avoid = index_array("avoid", np.ravel(avoid), net.n_springs, what="spring indices")
    return _far_pins(net, avoid)


def _far_pins(net: SpringNetwork, avoid: NDArray[np.int64]) -> NDArray[np.bool_]:
    """:func:`default_pins` for checked spring indices ``avoid`` (distances compared
    squared: the same nodes, without the norms' overhead)."""
    x = net.positions
    if avoid.size:
        avoid_nodes = np.unique(net.springs[avoid].ravel())
        diff = x[:, None, :] - x[None, avoid_nodes, :]
        dist = np.min(np.einsum("ijk,ijk->ij", diff, diff), axis=1)
        dist[avoid_nodes] = -np.inf
        first = int(np.argmax(dist))
    else:
        avoid_nodes = None
        c = x - np.add.reduce(x, 0) / x.shape[0]
        first = int(np.argmin(np.add.reduce(c * c, 1)))
    d = x - x[first]
    far = np.add.reduce(d * d, 1)
    if avoid_nodes is not None:
        far[avoid_nodes] = -np.inf
    far[first] = -np.inf
    second = int(np.argmax(far))
    mask = np.zeros((net.n_nodes, 2), dtype=bool)
    mask[first] = True
    if net.n_nodes > 1:
        dx, dy = d[second].tolist()
        mask[second, 1 if abs(dx) >= abs(dy) else 0] = True
    return mask


def _known(net: SpringNetwork, key: object, make: Callable[[SpringNetwork], NDArray]) -> NDArray:
    """``make(net)`` (read-only), computed once per network and ``key`` (:mod:`..linalg.memo`):
    repeated solves of one network (sweeps over clamps or starts) build their problem fast."""
    per = per_network(net, "problem")
    value = per.get(key)
    if value is None:
        value = make(net)
        value.setflags(write=False)
        per[key] = value
    return value


def _scale(net: SpringNetwork) -> NDArray[np.float64]:
    return coordinate_scale(net.springs, net.stiffness, net.rest_length, net.n_nodes)


def pin_mask(net: SpringNetwork, pinned: Pins, avoid: ArrayLike = ()) -> NDArray[np.bool_]:
    """Normalise ``pinned`` (None, node indices, or a (n_nodes, 2) bool mask) to a mask."""
    if pinned is None:
        return default_pins(net, avoid)
    arr = pin_mask_or_indices(net, pinned)
    if arr.dtype == bool:
        return arr
    mask = np.zeros((net.n_nodes, 2), dtype=bool)
    mask[arr] = True
    return mask


def clamp_tensions(A: sp.spmatrix | NDArray, g: NDArray, scale: NDArray) -> NDArray:
    """Clamp tensions ``mu`` (m,) minimising ``sum_k ((g + A^T mu)_k / scale_k)^2``.

    ``A`` (m, n) clamp Jacobian, ``g`` (n,) gradient, ``scale`` (n,) local force scale of
    each coordinate. Weighting by the local scale keeps the round-off of the forces at a
    stiff end of a clamp (``eps k r``) out of the balance judged at its soft end.
    """
    w2 = 1.0 / np.asarray(scale, dtype=np.float64) ** 2
    if sp.issparse(A):
        Aw = A.multiply(w2[None, :]).tocsr()
        G = (Aw @ A.T).toarray()
    else:
        Aw = A * w2[None, :]
        G = Aw @ A.T
    # normalise so that the Gram matrix has a unit diagonal where possible
    d = np.sqrt(np.maximum(np.abs(np.diag(G)), 1e-300))
    try:
        inverse = np.linalg.inv(G / d[:, None] / d[None, :]) / d[:, None] / d[None, :]
    except np.linalg.LinAlgError:
        inverse = np.linalg.pinv(G)
    # the normal equations square the condition of the clamp directions: nearly parallel
    # ones (two clamped springs folded onto each other) lose digits, which one step of
    # refinement on the unformed residual recovers
    mu = -inverse @ (Aw @ g)
    return mu - inverse @ (Aw @ (g + A.T @ mu))


class Residual(NamedTuple):
    """How far a state is from equilibrium (see :mod:`.stopping` for the definitions).

    Attributes
    ----------
    imbalance : float
        Largest relative imbalance ``max |F_ic| / f_i`` over free coordinates.
    force : float
        Largest absolute net force ``max |F_ic|`` (force units).
    clamp : float
        Largest relative clamp error ``max |b_c| / L_c`` (0 without clamps), with ``b_c``
        from :meth:`Problem.clamp_balance` and ``L_c`` the clamped spring's rest length.
    multipliers : (m,) float array
        Least-squares clamp tensions ``mu`` of ``grad E + A^T mu``.
    """

    imbalance: float
    force: float
    clamp: float
    multipliers: NDArray


@dataclass(frozen=True, eq=False)
class Problem:
    """A network with pins and clamps: what every equilibrium method minimises.

    Attributes
    ----------
    net : SpringNetwork
    free : (n_nodes, 2) bool array
        Coordinates that move.
    clamp_springs : (m,) int array
    clamp_lengths : (m,) float array
    clamp : "exact" or "rod"
    rod_stiffness : float
        Stiffness of the paper's rods, used when ``clamp == "rod"``.
    sparse_solver : {"auto", "pardiso", "superlu"}
        The sparse factorisation every solve of this problem uses
        (:func:`~continuum_vs_network.linalg.spd.sparse_backend`).
    """

    net: SpringNetwork
    free: NDArray[np.bool_]
    clamp_springs: NDArray[np.int64]
    clamp_lengths: NDArray[np.float64]
    clamp: ClampMode = "exact"
    rod_stiffness: float = 1e10
    sparse_solver: str = "auto"
    free_flat: NDArray[np.int64] = field(init=False)
    scale: NDArray[np.float64] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "free_flat", np.flatnonzero(self.free.ravel()))
        object.__setattr__(self, "scale", _known(self.net, "scale", _scale))

    def with_clamp_lengths(self, lengths: NDArray) -> Problem:
        """The same problem with other clamp lengths (strain continuation)."""
        return self._sibling(self.free, lengths)

    def with_free(self, free: NDArray) -> Problem:
        """The same problem with another pin mask."""
        return self._sibling(np.asarray(free, dtype=bool), self.clamp_lengths)

    def as_exact(self) -> Problem:
        """The same problem with its clamps exact instead of rods."""
        return self._sibling(self.free, self.clamp_lengths, clamp="exact")

    def _sibling(self, free: NDArray, lengths: NDArray, clamp: ClampMode | None = None) -> Problem:
        """A copy with ``free``, clamp ``lengths`` (and the ``clamp`` mode) replaced that
        reuses the coordinate scale (it depends on the network only): no
        ``__post_init__`` again."""
        new = object.__new__(Problem)
        free_flat = self.free_flat if free is self.free else np.flatnonzero(free.ravel())
        clamp = self.clamp if clamp is None else clamp
        fields = {
            "net": self.net, "free": free, "clamp_springs": self.clamp_springs,
            "clamp_lengths": lengths, "clamp": clamp, "rod_stiffness": self.rod_stiffness,
            "sparse_solver": self.sparse_solver, "free_flat": free_flat, "scale": self.scale,
        }  # fmt: skip
        for name, value in fields.items():
            object.__setattr__(new, name, value)
        return new

    def stop_rule(self, tol: float, *, max_iter: int, max_seconds: float) -> StopRule:
        """The local stop rule of this problem at relative tolerance ``tol``."""
        return StopRule(
            tol=float(tol),
            scale=self.scale,
            clamp_scale=self.net.rest_length[self.clamp_springs],
            max_iter=int(max_iter),
            max_seconds=float(max_seconds),
        )

    @classmethod
    def build(
        cls,
        net: SpringNetwork,
        *,
        pinned: Pins = None,
        clamped: Mapping[int, float] | None = None,
        clamp: ClampMode = "exact",
        rod_stiffness: float = 1e10,
        sparse_solver: str = "auto",
    ) -> Problem:
        choice("clamp", clamp, ("exact", "rod"))
        choice("sparse_solver", sparse_solver, SPARSE_SOLVERS)
        rod_stiffness = real("rod_stiffness", rod_stiffness, low=0, low_open=True)
        idx, length = clamp_arrays(net, clamped)
        if pinned is None:
            free = _known(net, ("free", idx.tobytes()), lambda net: ~_far_pins(net, idx))
        else:
            free = ~pin_mask(net, pinned)
        return cls(net, free, idx, length, clamp, float(rod_stiffness), sparse_solver)

    # -- the energy that is minimised -----------------------------------------------
    @property
    def mean_rest_length(self) -> float:
        """The network's mean rest length (the length unit of nudges and move bounds)."""
        net = self.net
        return float(np.add.reduce(net.rest_length)) / net.n_springs

    @property
    def n_clamps(self) -> int:
        return int(self.clamp_springs.size)

    @property
    def exact(self) -> bool:
        """True when clamps are equality constraints (not rods)."""
        return self.clamp == "exact" and self.n_clamps > 0

    def all_springs(self) -> tuple[NDArray, NDArray, NDArray]:
        """Springs, stiffness and rest lengths including rods in ``rod`` mode."""
        net = self.net
        if self.clamp == "rod" and self.n_clamps:
            springs = np.concatenate([net.springs, net.springs[self.clamp_springs]])
            k = np.concatenate([net.stiffness, np.full(self.n_clamps, self.rod_stiffness)])
            L = np.concatenate([net.rest_length, self.clamp_lengths])
            return springs, k, L
        return net.springs, net.stiffness, net.rest_length

    def energy(self, x: NDArray) -> float:
        """Energy minimised at fixed clamps: network springs, plus rods in ``rod`` mode."""
        return spring_energy(x, *self.all_springs())

    def gradient(self, x: NDArray) -> NDArray:
        """Full (n_nodes, 2) gradient of :meth:`energy`."""
        return spring_gradient(x, *self.all_springs())

    # -- clamp constraints ------------------------------------------------------------
    def clamp_violation(self, x: NDArray) -> NDArray:
        """``r_c - l_c`` for every clamp, (m,) float array."""
        if not self.n_clamps:
            return np.empty(0)
        s = self.net.springs[self.clamp_springs]
        d = spring_vectors(x, s)
        return vector_lengths(d) - self.clamp_lengths

    def clamp_jacobian(
        self, x: NDArray, coords: NDArray | None = None, *, dense: bool = False
    ) -> sp.csr_matrix | NDArray:
        """``d(r_c)/d(x_free)`` as a sparse (m, n_free) matrix: rows ``[-u_c, +u_c]``.

        Columns follow ``coords`` (flat coordinate indices; default ``free_flat``); with
        ``dense`` a (m, n_free) ndarray (cheaper for small problems).
        """
        coords = self.free_flat if coords is None else coords
        column = np.full(2 * self.net.n_nodes, -1, dtype=np.int64)
        column[coords] = np.arange(coords.size)
        pairs = self.net.springs[self.clamp_springs]
        return length_jacobian(x, pairs, column, coords.size, dense=dense)

    # -- the one residual used by every method ----------------------------------------
    def residual(self, x: NDArray, *, force: tuple[NDArray, NDArray] | None = None) -> Residual:
        """Net force on free coordinates after removing clamp-normal forces, judged locally.

        The multipliers ``mu`` (the clamp tensions) minimise
        ``sum_k ((grad E + A^T mu)_k / f_k)^2`` over the free coordinates ``k``, ``f_k``
        their local force scale (:func:`clamp_tensions`): the least squares of the very
        quantities the imbalance judges, not of the absolute forces (which the stiff
        coordinates would dominate); pin reactions are removed by looking at free
        coordinates only.
        The same definition holds for exact clamps and rods (whose axial force is a
        clamp-normal component). ``force``: ``unbalanced_force(x, free_flat)`` when the
        caller has it. Returns a :class:`Residual`.
        """
        r, mu = self.unbalanced_force(x, self.free_flat) if force is None else force
        if r.size:
            imbalance = float(np.max(np.abs(r) / self.scale[self.free_flat]))
            force = float(np.max(np.abs(r)))
        else:
            imbalance = force = 0.0
        clamp = 0.0
        if self.n_clamps:
            lc = self.net.rest_length[self.clamp_springs]
            clamp = float(np.max(np.abs(self.clamp_balance(x, mu)) / lc))
        return Residual(imbalance, force, clamp, mu)

    def clamp_balance(self, x: NDArray, multipliers: NDArray) -> NDArray:
        """What the clamp length test measures, (m,) float array (length units).

        Exact clamps: ``r_c - l_c``. Rods: ``r_c - l_c - mu_c / k_rod``, the rod's length
        minus the length at which its own force balances the clamp tension ``mu_c``
        (a rod yields by tension / stiffness, and no more).
        """
        viol = self.clamp_violation(x)
        if self.clamp == "rod":
            viol = viol - np.asarray(multipliers) / self.rod_stiffness
        return viol

    def unbalanced_force(
        self, x: NDArray, coords: NDArray, *, grad: NDArray | None = None
    ) -> tuple[NDArray, NDArray]:
        """``grad E + A^T mu`` at flat coordinates ``coords``, with least-squares ``mu``.

        Uses the network's springs only: a rod's force lies along its clamp normal and is
        projected out anyway, so ``mu`` holds the clamp forces in both clamp modes. The
        least squares are weighted by the local force scale (:func:`clamp_tensions`).
        ``grad``: the springs' flat (2 n_nodes,) gradient at ``x``, when the caller has it.
        Returns ``((len(coords),) array, (m,) multipliers)``.
        """
        net = self.net
        if grad is None:
            grad = spring_gradient(x, net.springs, net.stiffness, net.rest_length).ravel()
        g = grad[coords]
        if not self.n_clamps:
            return g, np.empty(0)
        A = self.clamp_jacobian(x, coords, dense=dense_jacobian_pays(self.n_clamps, coords.size))
        mu = clamp_tensions(A, g, self.scale[coords])
        return g + A.T @ mu, mu

    def toward_clamps(
        self,
        y: NDArray,
        coords: NDArray | None = None,
        A: sp.csr_matrix | NDArray | None = None,
        metric: NDArray | None = None,
    ) -> NDArray:
        """One Gauss-Newton step of ``y`` (n_nodes, 2) back onto the clamp lengths.

        The minimum-norm move ``-M A^T (A M A^T)^-1 (r - l)`` over ``coords`` (default
        ``free_flat``), with the clamp Jacobian ``A`` at ``y`` unless one is given (columns
        in ``coords`` order) and ``M = diag(metric)`` (default the identity; ``metric``
        (n_coords,) positive). Returns a new array.
        """
        coords = self.free_flat if coords is None else coords
        A = self.clamp_jacobian(y, coords) if A is None else A
        if metric is None:
            MAt = A.T
        elif sp.issparse(A):
            MAt = sp.diags(metric) @ A.T
        else:
            MAt = A.T * metric[:, None]
        AAt = A @ MAt
        AAt = AAt.toarray() if sp.issparse(AAt) else AAt
        z = np.array(y, dtype=np.float64, copy=True)
        violation = self.clamp_violation(y)
        try:
            z.ravel()[coords] -= MAt @ np.linalg.solve(AAt, violation)
        except np.linalg.LinAlgError:  # dependent clamp directions: the least-squares move
            z.ravel()[coords] -= MAt @ np.linalg.lstsq(AAt, violation, rcond=None)[0]
        return z

    def onto_clamps(
        self, y: NDArray, coords: NDArray | None = None, metric: NDArray | None = None
    ) -> NDArray:
        """``y`` (n_nodes, 2) moved onto the exact clamp lengths by Gauss-Newton steps
        (:meth:`toward_clamps` over ``coords``, default ``free_flat``, minimum-norm in
        ``metric``) until every violation is within ``1e-14`` of the longest clamp length,
        at most 20 of them; ``y`` itself with rod clamps. Where 20 steps in ``metric`` do
        not get there (a long way to go for nodes the metric makes heavy: a chain of clamps
        82 + 2 + 30 long between two stiff nodes 10 apart), 20 more go in the identity."""
        if not self.exact:
            return y
        coords = self.free_flat if coords is None else coords
        target = 1e-14 * float(self.clamp_lengths.max())
        for weights in (metric, None) if metric is not None else (None,):
            for _ in range(20):
                if np.abs(self.clamp_violation(y)).max() <= target:
                    return y
                A = self.clamp_jacobian(y, coords, dense=True)
                y = self.toward_clamps(y, coords, A, weights)
        return y

    def nudged(self, x: NDArray) -> NDArray:
        """``x`` (n_nodes, 2) with the free coordinates of the clamped springs' nodes moved
        by ``1e-6`` of the mean rest length in fixed pseudo-random directions: off a start
        where the clamp directions are dependent (clamped springs in a line), which gives
        a projection onto the clamps no direction to lengthen them."""
        net = self.net
        ends = net.springs[self.clamp_springs].ravel()
        move = np.zeros_like(x)
        move[ends] = np.random.default_rng(0).uniform(-1.0, 1.0, (ends.size, 2))
        return x + 1e-6 * self.mean_rest_length * move * self.free

    # -- counting ---------------------------------------------------------------------
    def maxwell_zero_modes(self) -> int:
        """Lower bound on internal zero modes from Maxwell counting.

        Free coordinates minus constraints (springs with ``k > 0``, and clamps on springs
        with ``k == 0``) minus the rigid motions the pins leave, floored at 0.
        """
        n_free = np.count_nonzero(self.free)  # count_nonzero: sums without numpy's overhead
        stiff = self.net.stiffness > 0
        clamped = self.clamp_springs.size
        n_constraints = (
            np.count_nonzero(stiff) + clamped - np.count_nonzero(stiff[self.clamp_springs])
        )
        rigid_left = max(0, 3 - (self.free.size - n_free))
        return max(0, n_free - n_constraints - rigid_left)

    def start(self, x: NDArray) -> NDArray:
        """A copy of ``x`` (n_nodes, 2) with every clamped spring set to its clamp length.

        Each clamped spring is stretched symmetrically about its midpoint (or about a pinned
        end) to its clamp length, so the first iterate is close to feasible.
        """
        net = self.net
        x = np.array(x, dtype=np.float64, copy=True)
        for c, length in zip(self.clamp_springs, self.clamp_lengths):
            a, b = net.springs[c]
            d = x[b] - x[a]
            r = float(np.hypot(*d))
            if r == 0.0:
                raise ValueError(f"clamped spring {c} has zero length at the start; move its nodes")
            free_a, free_b = self.free[a].all(), self.free[b].all()
            grow = (length - r) * d / r
            if free_a and free_b:
                x[a] -= 0.5 * grow
                x[b] += 0.5 * grow
            elif free_b:
                x[b] += grow
            elif free_a:
                x[a] -= grow
        return x
