"""Visco-elastic spring networks: spring dashpots (Kelvin-Voigt) and Maxwell arms (standard
linear solid), beside the node drag of Eq. 10.

Forces on the nodes (unit masses when ``inertia=True``)::

    m x'' = -c x' - D_kv(x) x' - grad_x E(x, l)

* node drag ``c`` (``drag``) against the lab frame, as in :mod:`.dynamics`;
* a dashpot of coefficient ``gamma`` (``dashpot``) along every spring: the force
  ``gamma dr/dt`` along the spring, so ``D_kv = sum_j gamma e_j e_j^T`` over the spring's
  two nodes (``e_j`` the unit vector, signs as in the Hessian) - a Kelvin-Voigt network,
  the lattice of :func:`~continuum_vs_network.continuum.materials.lattice_viscous_lame`;
* a Maxwell arm on every spring: a spring ``k2`` (``arm_stiffness``) in series with a
  dashpot ``gamma2`` (``arm_dashpot``); its internal variable ``l_j`` is the length at which
  the arm carries no force, so the energy is ``E = sum k (r - L)^2/2 + sum k2 (r - l)^2/2``
  and ``gamma2 l' = k2 (r - l)`` (a standard linear solid per spring, arm relaxation time
  ``gamma2 / k2``). The same equation with ``k2 = k`` and ``gamma2 = 1 / alpha`` is
  prospective configuration in time (``L' = alpha k (r - L)``).

Time stepping (backward Euler, the arms eliminated in closed form, the dashpot impulse of a
displacement step) is :class:`~.stepper.Stepper` and :func:`~.dynamics.simulate_viscous`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .energy import HessianPattern, spring_hessian_blocks
from .model import SpringNetwork, spring_vectors, unit_vectors, vector_lengths

__all__ = ["Viscosity", "dashpot_force", "dashpot_matrix", "linear_system"]


@dataclass(frozen=True)
class Viscosity:
    """Dissipation of a network (all >= 0; the same for every spring).

    Attributes
    ----------
    drag : float
        Node drag ``c`` (force per velocity).
    dashpot : float
        Kelvin-Voigt dashpot ``gamma`` along every spring (force per rate of length change).
    arm_stiffness, arm_dashpot : float
        Maxwell arm ``k2`` (force per length) and ``gamma2`` (force per rate); both > 0 or
        both 0 (no arm). Arm relaxation time ``gamma2 / k2``.
    """

    drag: float = 1.0
    dashpot: float = 0.0
    arm_stiffness: float = 0.0
    arm_dashpot: float = 0.0

    def __post_init__(self) -> None:
        for name in ("drag", "dashpot", "arm_stiffness", "arm_dashpot"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {getattr(self, name)}")
            object.__setattr__(self, name, v)
        if (self.arm_stiffness > 0) != (self.arm_dashpot > 0):
            raise ValueError(
                "arm_stiffness and arm_dashpot must both be > 0 (a Maxwell arm) or both 0, "
                f"got {self.arm_stiffness} and {self.arm_dashpot}"
            )
        if self.drag == 0 and self.dashpot == 0:
            raise ValueError("drag and dashpot are both 0: no dissipation on the nodes")

    @property
    def has_arm(self) -> bool:
        return self.arm_stiffness > 0

    @property
    def arm_time(self) -> float:
        """Relaxation time ``gamma2 / k2`` of an arm (inf without one)."""
        return self.arm_dashpot / self.arm_stiffness if self.has_arm else math.inf


def dashpot_blocks(x: NDArray, springs: NDArray, gamma: float) -> NDArray:
    """Per-spring blocks ``gamma e e^T`` (n_springs, 2, 2): the Hessian blocks at ``L = r``."""
    r = vector_lengths(spring_vectors(x, springs))
    return spring_hessian_blocks(x, springs, np.full(len(springs), float(gamma)), r)


def dashpot_matrix(
    x: ArrayLike, net: SpringNetwork, gamma: float, *, pattern: HessianPattern | None = None
) -> sp.csr_matrix:
    """Kelvin-Voigt damping matrix ``sum_j gamma e_j e_j^T`` (2 n_nodes square, or the
    ``pattern``'s free coordinates), force per velocity."""
    x = np.asarray(x, dtype=np.float64)
    pattern = pattern or HessianPattern(net.springs, net.n_nodes)
    return pattern.assemble(dashpot_blocks(x, net.springs, gamma))


def dashpot_force(x: ArrayLike, net: SpringNetwork, gamma: float, v: ArrayLike) -> NDArray:
    """Dashpot force ``-D_kv(x) v`` on every node (n_nodes, 2) for velocities ``v``."""
    x = np.asarray(x, dtype=np.float64)
    e, _ = unit_vectors(x, net.springs)
    dv = spring_vectors(np.asarray(v), net.springs)
    rate = gamma * np.einsum("ij,ij->i", e, dv)
    # the force on b is -rate e, on a +rate e: the gradient of a spring with tension `rate`
    t = rate[:, None] * e
    f = np.zeros_like(x)
    np.add.at(f, net.springs[:, 1], -t)
    np.add.at(f, net.springs[:, 0], t)
    return f


def linear_system(
    net: SpringNetwork, viscosity: Viscosity, free: ArrayLike
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Stiffness and damping ``(K, C)`` of the dynamics linearised about ``net.positions``.

    Unknowns: the free coordinates (``free``: (n_nodes, 2) bool, in ``ravel`` order), then
    one arm variable per spring when there are arms (arms relaxed, ``l = r``). ``C z' +
    K z = 0``; both symmetric, so the relaxation times are ``1 / eig(K, C)`` (pass them to
    :func:`~continuum_vs_network.continuum.viscoelastic.slowest_relaxation_time`).
    """
    x = net.positions
    free = np.asarray(free, dtype=bool)
    pattern = HessianPattern(net.springs, net.n_nodes, free)
    H = pattern.assemble(spring_hessian_blocks(x, net.springs, net.stiffness, net.rest_length))
    D = pattern.assemble(dashpot_blocks(x, net.springs, viscosity.dashpot), viscosity.drag)
    if not viscosity.has_arm:
        return H.tocsr(), D.tocsr()
    k2, g2 = viscosity.arm_stiffness, viscosity.arm_dashpot
    e, _ = unit_vectors(x, net.springs)
    idx = pattern.free_index
    rows, cols, vals = [], [], []
    for node_col, sign in ((1, 1.0), (0, -1.0)):
        for c in range(2):
            col = idx[2 * net.springs[:, node_col] + c]
            keep = col >= 0
            rows.append(np.flatnonzero(keep))
            cols.append(col[keep])
            vals.append(sign * e[keep, c])
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(net.n_springs, pattern.size),
    )
    I_s = sp.identity(net.n_springs, format="csr")
    K = sp.bmat([[H + k2 * (B.T @ B), -k2 * B.T], [-k2 * B, k2 * I_s]], format="csr")
    C = sp.bmat([[D, None], [None, g2 * I_s]], format="csr")
    return K, C
