"""The spring terms one trust-region iteration evaluates, for one problem.

:func:`kernels` returns an object with the gradient, the reduced scaled Lagrangian Hessian,
the geodesic bending force and the cancellation-free energy change of :mod:`.trust`.
Networks of at most :data:`DENSE_NODES` nodes get :class:`DenseKernels`: every gather and
scatter is one product with the dense signed incidence matrix ``E`` (``d = E x``,
``grad = E^T t``), and the reduced Hessian is assembled directly in the model's basis
``B`` (n, r) from the springs' length and rotation Jacobians ``J``, ``P`` (one row each
per spring, ``u`` and ``u_perp`` on its node pair)::

    B^T W B = (J B)^T diag(k) (J B) + (P B)^T diag(t) (P B),   t = k (1 - L / r) (+ mu / r)

(``k u u^T + t (I - u u^T)`` per spring), so no (n, n) matrix is formed; ``J B`` and ``P B``
also give the bending force of every trial step. At the paper's N = 10 patch numpy's
per-call overhead, not arithmetic, is the cost: products are ``ndarray.dot``, not ``@``
(matmul's dispatch costs more a call at these sizes, with the same numbers:
``docs/solver-notes.md#trust-kernels-dot``), except where an
operand is strided (there the two round differently). Larger problems get :class:`SparseKernels`
(gathers, ``bincount`` scatters and the cached Hessian pattern). Both compute the same
quantities; results agree to round-off.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..linalg.memo import per_array
from .constraints import Problem
from .energy import spring_bending_on, spring_energy_change, spring_gradient
from .lagrangian import Frame, lagrangian_blocks
from .model import vector_lengths

__all__ = ["DENSE_NODES", "DenseKernels", "SparseKernels", "kernels"]

DENSE_NODES = 32  # nodes up to which the dense incidence products are used

_TINY = 1e-300
# u (s, 2) @ _TURN = (u0, u1, u1, -u0): a spring's length and rotation Jacobian coefficients
_TURN = np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, -1.0, 0.0]])


class SparseKernels:
    """The trust region's spring terms by gathers and scatters (any size).

    ``inv_root`` (n,) is ``D^-1/2`` on the rows ``coords`` (flat coordinates, frame order).
    A model's basis ``B`` (n, r) maps its reduced coordinates to moves of the free
    coordinates; None stands for ``diag(inv_root)``.
    """

    def __init__(self, problem: Problem, frame: Frame, inv_root: NDArray) -> None:
        self.problem = problem
        self.frame = frame
        self.coords = frame.coords
        self.springs = problem.all_springs()
        self.inv_root = inv_root
        self.m = problem.n_clamps if problem.exact else 0

    def gradient(self, x: NDArray) -> NDArray:
        """``dE/dx`` on ``coords`` (n,); remembers ``x`` for the other terms."""
        self.x = x
        return spring_gradient(x, *self.springs).ravel()[self.coords]

    def reduced_hessian(self, mu: NDArray, basis: NDArray | None) -> NDArray:
        """``B^T W B`` (r, r) at the last ``x``: ``W`` the Lagrangian Hessian with clamp
        multipliers ``mu``; remembers ``B`` for :meth:`reduced_bending`."""
        blocks = lagrangian_blocks(self.problem, self.x, mu[: self.m], 0.0)
        W = self.frame.pattern.assemble_dense(blocks)
        self.basis = basis
        if basis is None:
            return W * self.inv_root[:, None] * self.inv_root[None, :]
        return basis.T.dot(W).dot(basis)

    def bending(self, step: NDArray) -> NDArray:
        """:func:`~.energy.spring_bending_on` ``coords`` (n,) for an unscaled ``step`` (n,)
        from the last ``x``."""
        springs, k, _ = self.springs
        return spring_bending_on(self.x, self.coords, step, springs, k)

    def reduced_bending(self, p: NDArray, step: NDArray) -> NDArray:
        """``B^T`` :meth:`bending` ``(step)`` (r,) for ``step = B p``."""
        b = self.bending(step)
        return self.basis.T.dot(b) if self.basis is not None else b * self.inv_root

    def energy_change(self, y: NDArray, move: NDArray | None = None) -> float:
        """``E(y) - E(x)`` from the last ``x``, free of cancellation (``move``: ``y - x``
        (n_nodes, 2), when known)."""
        return spring_energy_change(y, self.x, *self.springs)


class DenseKernels(SparseKernels):
    """The same terms as :class:`SparseKernels` by dense products (small networks)."""

    def __init__(self, problem: Problem, frame: Frame, inv_root: NDArray) -> None:
        super().__init__(problem, frame, inv_root)
        _, k, L = self.springs
        s = len(k)
        self.E, self.Et = _incidence(self.springs[0], problem.net)
        self.k, self.L, self.k_half, self.L2, self.kL = k, L, 0.5 * k, 2.0 * L, k * L
        self.clamps = problem.clamp_springs if self.m else None
        self.weights = np.empty((s, 2))  # per spring: k (length), t (rotation)
        self.weights[:, 0] = k
        self.w = self.weights.reshape(2 * s, 1)
        self.n_nodes = problem.net.n_nodes
        self.full = bool(self.coords.size == 2 * self.n_nodes)  # natural order
        self.fixed = None  # E times diag(inv_root), the pinned problems' constant basis
        self.tried: tuple = (None,)  # the last energy_change's positions, d and r

    def _incident_basis(self, basis: NDArray | None) -> NDArray:
        """``E`` applied to the x and the y rows of the basis: (s, 2, r)."""
        if basis is None:
            if self.fixed is None:
                self.fixed = self._incident_basis(np.diag(self.inv_root))
            return self.fixed
        if not self.full:  # zero rows at the pinned coordinates
            embedded = np.zeros((2 * self.n_nodes, basis.shape[1]))
            embedded[self.coords] = basis
            basis = embedded
        return self.E.dot(basis.reshape(self.n_nodes, -1)).reshape(len(self.k), 2, -1)

    def gradient(self, x: NDArray) -> NDArray:
        if x is self.tried[0]:  # the last trial's positions: their geometry is known
            d, r = self.tried[1:]
        else:
            d = self.E.dot(x)
            r = vector_lengths(d)
        self.x = x
        r_safe = np.maximum(r, _TINY)
        self.d, self.r, self.r_safe, self.r_rest = d, r, r_safe, r - self.L2
        t = (self.k * (r - self.L) / r_safe)[:, None] * d
        g = self.Et.dot(t).ravel()
        return g if self.full else g[self.coords]

    def reduced_hessian(self, mu: NDArray, basis: NDArray | None) -> NDArray:
        r = self.r_safe
        tangential = self.k - self.kL / r  # k (1 - L / r)
        if self.clamps is not None:
            tangential[self.clamps] += mu[: self.m] / r[self.clamps]
        self.weights[:, 1] = tangential
        turn = (self.d / r[:, None]).dot(_TURN).reshape(-1, 2, 2)  # (u; u_perp) per spring
        # rows 2j, 2j + 1: spring j's length and rotation Jacobians times the basis
        KB = np.matmul(turn, self._incident_basis(basis)).reshape(self.w.size, -1)
        self.JBT, self.PB, self.k_r = KB[0::2].T, KB[1::2], self.k / r
        if np.count_nonzero(self.r) < r.size:  # a collapsed spring: u undefined, t I block
            return super().reduced_hessian(mu, basis)
        return KB.T.dot(self.w * KB)

    def reduced_bending(self, p: NDArray, step: NDArray) -> NDArray:
        perp = self.PB.dot(p)
        return self.JBT @ (self.k_r * perp * perp)  # strided: dot rounds otherwise

    def energy_change(self, y: NDArray, move: NDArray | None = None) -> float:
        d0 = self.d
        du = self.E.dot(y - self.x if move is None else move)
        d = d0 + du
        r = vector_lengths(d)
        self.tried = (y, d, r)
        # r - r0 = du . (d + d0) / (r + r0), without cancellation
        both = du * (d + d0)
        dr = (both[:, 0] + both[:, 1]) / (r + self.r_safe)
        return float(self.k_half.dot(dr * (r + self.r_rest)))


def _incidence(springs: NDArray, net) -> tuple[NDArray, NDArray]:
    """The signed incidence ``E`` (s, N) of ``springs`` (``net``'s, rods included) and its
    transpose, cached while ``net``'s springs array lives (``with_*`` copies share it)."""
    n_nodes = net.n_nodes
    key = (n_nodes, springs.tobytes())
    per = per_array(net.springs, "dense_incidence")
    if key not in per:
        s = len(springs)
        rows = np.arange(s)
        E = np.zeros((s, n_nodes))
        E[rows, springs[:, 1]] += 1.0
        E[rows, springs[:, 0]] -= 1.0
        per[key] = (E, np.ascontiguousarray(E.T))
    return per[key]


def kernels(problem: Problem, frame: Frame, inv_root: NDArray) -> SparseKernels:
    """:class:`DenseKernels` up to :data:`DENSE_NODES` nodes, else :class:`SparseKernels`."""
    if problem.net.n_nodes <= DENSE_NODES:
        return DenseKernels(problem, frame, inv_root)
    return SparseKernels(problem, frame, inv_root)
