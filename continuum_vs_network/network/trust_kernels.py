"""The spring terms one trust-region iteration evaluates, for one problem.

:func:`kernels` returns an object with the gradient, the scaled Lagrangian Hessian, the
geodesic bending force and the cancellation-free energy change of
:mod:`.trust`. Networks of at most :data:`DENSE_NODES` nodes get :class:`DenseKernels`:
every gather and scatter is one product with the dense signed incidence matrix ``E``
(``d = E x``, ``grad = E^T t``) and the Hessian one product with the per-spring node-pair
outer products, built once per solve; at the paper's N = 10 patch numpy's per-call
overhead, not arithmetic, is the cost, and this takes each iteration from about 40 numpy
calls to about 15. Larger problems get :class:`SparseKernels` (gathers, ``bincount``
scatters and the cached Hessian pattern). Both compute the same quantities; results
agree to round-off.
"""

from __future__ import annotations

import weakref

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem
from .energy import _scatter_nodes, spring_energy_change, spring_gradient
from .lagrangian import Frame, lagrangian_blocks

__all__ = ["DENSE_NODES", "DenseKernels", "SparseKernels", "kernels"]

DENSE_NODES = 32  # nodes up to which the dense incidence products are used

_TINY = 1e-300


class SparseKernels:
    """The trust region's spring terms by gathers and scatters (any size).

    ``inv_root`` (n,) is ``D^-1/2`` on the rows ``coords`` (flat coordinates, frame order).
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

    def hessian(self, mu: NDArray) -> NDArray:
        """Scaled Lagrangian Hessian ``D^-1/2 W D^-1/2`` (n, n) at the last ``x``."""
        blocks = lagrangian_blocks(self.problem, self.x, mu[: self.m], 0.0)
        W = self.frame.pattern.assemble_dense(blocks)
        return W * self.inv_root[:, None] * self.inv_root[None, :]

    def bending(self, step: NDArray) -> NDArray:
        """``J^T (k r_vv)`` on ``coords`` (n,) for an unscaled ``step`` (n,) from the last
        ``x``: the force of every spring's second-order length change ``|dd_perp|^2 / r``."""
        x = self.x
        springs, k, _ = self.springs
        full = np.zeros(x.size)
        full[self.coords] = step
        full = full.reshape(x.shape)
        d = x[springs[:, 1]] - x[springs[:, 0]]
        r = np.maximum(np.hypot(d[:, 0], d[:, 1]), _TINY)
        u = d / r[:, None]
        dd = full[springs[:, 1]] - full[springs[:, 0]]
        perp = dd[:, 0] * u[:, 1] - dd[:, 1] * u[:, 0]
        t = (k * perp * perp / r)[:, None] * u
        return _scatter_nodes(t, springs, x.shape[0]).ravel()[self.coords]

    def set_basis(self, basis: NDArray | None) -> None:
        """The model's scaled basis (n, r) (None: ``D^-1/2`` itself), after :meth:`hessian`."""
        self.basis = basis

    def reduced_bending(self, p: NDArray, step: NDArray) -> NDArray:
        """``basis^T`` :meth:`bending` ``(step)`` (r,) for ``step = basis @ p``."""
        b = self.bending(step)
        return self.basis.T @ b if self.basis is not None else b * self.inv_root

    def energy_change(self, y: NDArray) -> float:
        """``E(y) - E(x)`` from the last ``x``, free of cancellation."""
        return spring_energy_change(y, self.x, *self.springs)


class DenseKernels(SparseKernels):
    """The same terms as :class:`SparseKernels` by dense products (small networks)."""

    def __init__(self, problem: Problem, frame: Frame, inv_root: NDArray) -> None:
        super().__init__(problem, frame, inv_root)
        _, k, L = self.springs
        n_nodes = problem.net.n_nodes
        self.E, self.Et, self.pairs, self.take, self.G = _incidence(problem, self.coords)
        self.weight = inv_root[:, None] * inv_root[None, :]
        self.k, self.L = k, L
        self.clamps = problem.clamp_springs if self.m else None
        self.full = np.zeros(2 * n_nodes)
        self.blocks = np.empty((len(k), 4))

    def gradient(self, x: NDArray) -> NDArray:
        self.x = x
        d = self.E @ x
        r = np.hypot(d[:, 0], d[:, 1])
        self.d, self.r = d, r
        t = (self.k * (r - self.L) / np.maximum(r, _TINY))[:, None] * d
        return (self.Et @ t).ravel()[self.coords]

    def hessian(self, mu: NDArray) -> NDArray:
        r = np.maximum(self.r, _TINY)
        u = self.d / r[:, None]
        self.u, self.r_safe = u, r
        tangential = self.k * (1.0 - self.L / r)
        if self.clamps is not None:
            tangential[self.clamps] += mu[: self.m] / r[self.clamps]
        c = self.k - tangential
        u0, u1 = u[:, 0], u[:, 1]
        blocks = self.blocks  # (s, 4): the 2x2 block of every spring, ravelled
        blocks[:, 0] = c * u0 * u0 + tangential
        blocks[:, 1] = blocks[:, 2] = c * u0 * u1
        blocks[:, 3] = c * u1 * u1 + tangential
        return (self.pairs @ blocks).ravel()[self.take] * self.weight

    def bending(self, step: NDArray) -> NDArray:
        full = self.full
        full[self.coords] = step
        dd = self.E @ full.reshape(-1, 2)
        u = self.u
        perp = dd[:, 0] * u[:, 1] - dd[:, 1] * u[:, 0]
        t = (self.k * perp * perp / self.r_safe)[:, None] * u
        return (self.Et @ t).ravel()[self.coords]

    def set_basis(self, basis: NDArray | None) -> None:
        # length Jacobian J (s, n) and the perpendicular one at the last x, onto the basis:
        # the bending force of a reduced step p is (J B)^T (k/r (P B p)^2)
        u0, u1 = self.u[:, 0, None], self.u[:, 1, None]
        G0, G1 = self.G
        J, P = u0 * G0 + u1 * G1, u1 * G0 - u0 * G1
        if basis is None:
            J, P = J * self.inv_root, P * self.inv_root
        else:
            J, P = J @ basis, P @ basis
        self.JT, self.P = np.ascontiguousarray(J.T), P
        self.k_r = self.k / self.r_safe

    def reduced_bending(self, p: NDArray, step: NDArray) -> NDArray:
        perp = self.P @ p
        return self.JT @ (self.k_r * perp * perp)

    def energy_change(self, y: NDArray) -> float:
        d0, r0 = self.d, self.r
        du = self.E @ (y - self.x)
        d = self.E @ y
        r = np.hypot(d[:, 0], d[:, 1])
        dr = np.einsum("ij,ij->i", du, d + d0) / np.maximum(r + r0, _TINY)
        return float(0.5 * np.dot(self.k, dr * (r + r0 - 2.0 * self.L)))


_CACHE: dict[int, dict] = {}


def _incidence(problem: Problem, coords: NDArray) -> tuple:
    """The constant arrays of :class:`DenseKernels`, cached while the springs array lives
    (networks made with ``with_*`` share it): the signed incidence ``E`` (s, N) and its
    transpose, the node-pair outer products (N*N, s) and the index of each ``(coords,
    coords)`` entry in the products' ravelled (N, N, 2, 2) result, and ``E`` on the x and the
    y components of ``coords`` (two (s, n) arrays)."""
    springs = problem.all_springs()[0]
    net = problem.net
    key_array = id(net.springs)
    if key_array not in _CACHE:
        _CACHE[key_array] = {}
        weakref.finalize(net.springs, _CACHE.pop, key_array, None)
    key = (net.n_nodes, coords.tobytes(), springs.tobytes())
    per = _CACHE[key_array]
    if key not in per:
        n_nodes, s = net.n_nodes, len(springs)
        rows = np.arange(s)
        E = np.zeros((s, n_nodes))
        E[rows, springs[:, 1]] += 1.0
        E[rows, springs[:, 0]] -= 1.0
        pairs = np.ascontiguousarray((E[:, :, None] * E[:, None, :]).reshape(s, -1).T)
        p = coords
        take = ((p[:, None] // 2) * n_nodes + p[None, :] // 2) * 4 + (p[:, None] % 2) * 2
        G = tuple(E[:, p // 2] * (p % 2 == c) for c in (0, 1))
        per[key] = (E, np.ascontiguousarray(E.T), pairs, take + p[None, :] % 2, G)
    return per[key]


def kernels(problem: Problem, frame: Frame, inv_root: NDArray) -> SparseKernels:
    """:class:`DenseKernels` up to :data:`DENSE_NODES` nodes, else :class:`SparseKernels`."""
    if problem.net.n_nodes <= DENSE_NODES:
        return DenseKernels(problem, frame, inv_root)
    return SparseKernels(problem, frame, inv_root)
