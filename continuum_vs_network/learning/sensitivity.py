"""Implicit differentiation of clamped equilibria: exact gradients of the task error.

At a free-state equilibrium with the sources clamped (exact constraints ``r_s(x) = l_s``)
the positions ``x`` and clamp tensions ``mu`` solve ``F = [grad E + A^T mu; r_s - l_s] = 0``.
For a cost ``C(x, theta)`` the adjoint ``[v; w] = K^{-1} [dC/dx; 0]`` with the KKT matrix
``K = [[W, A^T], [A, 0]]`` (``W`` the Hessian of the Lagrangian) gives::

    dC/dtheta = dC/dtheta|_x  -  v . d(grad E)/dtheta  +  w . dl_s/dtheta

For rest lengths ``d(grad E)/dL_j = -k_j dr_j/dx`` and for stiffnesses
``d(grad E)/dk_j = (r_j - L_j) dr_j/dx``, so both gradients need the single vector
``J v`` (the length change of every spring under the adjoint displacement). One
factorisation of ``W`` and ``m + 1`` solves give everything.

:class:`Sensitivity` holds that factorisation; :func:`cost_gradient` is the exact gradient
of Eq. 26 (or of the length cost) used by :class:`~.rules.ExactGradient` and the tests;
:meth:`Sensitivity.compliance` gives the effective stiffness of the targets, the factor
that relates coupled learning's ``eta -> 0`` limit to the gradient.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from ..linalg.kkt import schur_solve
from ..network.constraints import Problem
from ..network.equilibrium import Equilibrium
from ..network.lagrangian import Frame, lagrangian_hessian
from ..network.model import SpringNetwork, spring_vectors
from .tasks import AllosteryTask, StrainReference

__all__ = ["Cost", "Sensitivity", "cost_gradient", "gcl_limit", "length_jacobian_rows"]

Cost = Literal["strain", "length"]
Dof = Literal["rest_length", "stiffness"]


def length_jacobian_rows(net: SpringNetwork, x: NDArray, v: NDArray) -> NDArray:
    """Length change ``dr_j = u_j . (v_b - v_a)`` of every spring under displacement ``v``.

    ``x`` and ``v`` are (n_nodes, 2); returns (n_springs,).
    """
    d = spring_vectors(x, net.springs)
    u = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    dv = spring_vectors(v, net.springs)
    return np.einsum("ij,ij->i", u, dv)


class Sensitivity:
    """The factorised KKT system of one clamped equilibrium.

    Parameters
    ----------
    net : SpringNetwork
    pinned : (n_nodes, 2) bool array
    clamped : {spring: length}
        The clamps active at the equilibrium, in the order of ``eq.clamp_force``.
    eq : Equilibrium
        The equilibrium (positions and clamp forces).
    """

    def __init__(
        self,
        net: SpringNetwork,
        pinned: NDArray,
        clamped: dict[int, float],
        eq: Equilibrium,
    ) -> None:
        self.net = net
        self.x = np.asarray(eq.positions, dtype=np.float64)
        self.problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
        # Equilibrium.clamp_force is dE/dl_c, minus the multiplier of grad E + A^T mu = 0
        mu = -np.asarray(eq.clamp_force, dtype=np.float64)
        m = self.problem.n_clamps
        if mu.shape != (m,):
            raise ValueError(f"eq.clamp_force has {mu.size} entries for {m} clamps")
        self.frame = Frame(net, self.problem.free)
        self.n = self.frame.n
        W = lagrangian_hessian(self.problem, self.x, mu, frame=self.frame)
        self.A = (
            self.frame.rows(net, self.x, self.problem.clamp_springs, dense=False) if m else None
        )
        factor = self.frame.factor(W)
        if factor is not None:
            self._solve_W = factor.solve
            self._lu = None
            if m:
                self._Z = np.asarray(self._solve_W(self.A.T.toarray())).reshape(self.n, m)
                self._S = self.A @ self._Z
        else:  # not positive definite (an unstable state): general LU of the KKT matrix
            K = W if not m else sp.bmat([[W, self.A.T], [self.A, None]], format="csc")
            self._lu = spla.splu(sp.csc_matrix(K))
            self._solve_W = None

    def solve(self, b: ArrayLike) -> tuple[NDArray, NDArray]:
        """Solve ``[W A^T; A 0] [v; w] = [b; 0]``.

        ``b`` is (n_nodes, 2) (its free entries are used) or (n,) / (n, p) in the rows'
        order (:attr:`frame`). Returns ``v`` as (n_nodes, 2) (zero on pinned coordinates;
        for (n, p) input, (n, p) in row order) and ``w``, (m,) or (m, p).
        """
        b = np.asarray(b, dtype=np.float64)
        full_input = b.shape == (self.net.n_nodes, 2)
        bf = self.frame.take(b) if full_input else b
        if bf.shape[0] != self.n:
            raise ValueError(f"b must be (n_nodes, 2) or ({self.n}, ...), got {b.shape}")
        m = self.problem.n_clamps
        if self._lu is not None:
            rhs = np.concatenate([bf, np.zeros((m, *bf.shape[1:]))]) if m else bf
            sol = self._lu.solve(rhs)
            vf, w = sol[: self.n], sol[self.n :]
        else:
            z = np.asarray(self._solve_W(bf))
            if m:
                vf, w = schur_solve(z, self.A, self._Z, self._S, 0.0)
            else:
                vf, w = z, np.zeros((0, *bf.shape[1:]))
        if bf.ndim == 1:
            return self.frame.put(vf), w
        return vf, w

    def length_rows(self, springs: ArrayLike) -> NDArray:
        """``dr/dx`` of ``springs`` on free coordinates, dense (len(springs), n)."""
        return self.frame.rows(self.net, self.x, springs, dense=True)

    def compliance(self, springs: ArrayLike) -> NDArray:
        """Length change of ``springs`` per unit tension pair on them, (p, p).

        Its inverse is the effective stiffness ``d tension / d length`` that the rest of
        the (clamped) network presents to those springs: the Hessian of the constrained
        minimum energy with respect to their lengths.
        """
        rows = self.length_rows(springs)
        v, _ = self.solve(rows.T)
        return rows @ v


def _check_dof(dof: str) -> None:
    if dof not in ("rest_length", "stiffness"):
        raise ValueError(f"dof must be 'rest_length' or 'stiffness', got {dof!r}")


def cost_gradient(
    net: SpringNetwork,
    task: AllosteryTask,
    eq: Equilibrium,
    *,
    strain_reference: StrainReference = "initial",
    dof: Dof = "rest_length",
    cost: Cost = "strain",
    through_reference: bool = True,
    target_lengths: ArrayLike | None = None,
    sensitivity: Sensitivity | None = None,
) -> NDArray:
    """Exact gradient of the task error with respect to every spring's ``L`` or ``k``.

    Parameters
    ----------
    net, task : the network and the task; ``eq`` is its free state (sources clamped at
        ``task.source_lengths(net, strain_reference)``, in source order).
    strain_reference : {"initial", "current"}
        Strain convention (see :mod:`.tasks`).
    dof : {"rest_length", "stiffness"}
    cost : {"strain", "length"}
        ``"strain"``: Eq. 26, ``sum (r_T / L_T - 1 - S_T)^2 / 2``. ``"length"``:
        ``sum (r_T - l_T)^2 / 2`` with ``l_T = L_T (S_T + 1)``.
    through_reference : bool
        With ``strain_reference="current"`` the reference rest lengths are the learning ``L``:
        the strain's denominator, the desired lengths and the source clamp lengths all
        move with ``L``. True differentiates through all of that (the gradient of the
        error as measured); False holds them fixed (what coupled learning sees).
    target_lengths : (n_targets,) float array, optional
        Measured target lengths to use in place of the equilibrium's (read-out noise).

    Returns
    -------
    (n_springs,) float array
    """
    _check_dof(dof)
    if cost not in ("strain", "length"):
        raise ValueError(f"cost must be 'strain' or 'length', got {cost!r}")
    x = np.asarray(eq.positions, float)
    t = task.targets
    r_t = net.lengths(x, t) if target_lengths is None else np.asarray(target_lengths, float)
    ref_t = task.target_rest(net, strain_reference)
    if cost == "strain":
        err = r_t / ref_t - 1.0 - task.target_strain
        dC_dr = err / ref_t
        dC_dref = -err * r_t / ref_t**2
    else:
        err = r_t - ref_t * (1.0 + task.target_strain)
        dC_dr = err
        dC_dref = -err * (1.0 + task.target_strain)
    sens = sensitivity or Sensitivity(
        net, task.pinned, task.source_clamps(net, strain_reference), eq
    )
    rows = sens.length_rows(t)
    b = rows.T @ dC_dr
    v, w = sens.solve(b)
    dr = length_jacobian_rows(net, x, v)
    if dof == "rest_length":
        grad = net.stiffness * dr
    else:
        grad = -(net.lengths(x) - net.rest_length) * dr
    if dof == "rest_length" and strain_reference == "current" and through_reference:
        np.add.at(grad, t, dC_dref)
        # the source clamp lengths l_s = L_s (S_s + 1) move with L_s
        np.add.at(grad, task.sources, w * (task.source_strain + 1.0))
    return grad


def gcl_limit(
    net: SpringNetwork,
    task: AllosteryTask,
    eq: Equilibrium,
    *,
    strain_reference: StrainReference = "initial",
    dof: Dof = "rest_length",
    sensitivity: Sensitivity | None = None,
) -> tuple[NDArray, NDArray]:
    """The ``eta -> 0`` limit of coupled learning's update divided by ``alpha``.

    Coupled learning descends ``(E^C - E^F) / eta``, and to first order in ``eta`` this is
    the *length* cost ``(r_T - l_T)^T K (r_T - l_T) / 2`` weighted by the targets'
    effective stiffness ``K`` (the inverse of :meth:`Sensitivity.compliance`), with the
    clamp and desired lengths ``l`` held fixed. Returns ``(limit, K)``: the limit
    ``-grad`` of that cost, (n_springs,), and ``K``, (n_targets, n_targets).
    """
    _check_dof(dof)
    x = np.asarray(eq.positions, float)
    sens = sensitivity or Sensitivity(
        net, task.pinned, task.source_clamps(net, strain_reference), eq
    )
    K = np.linalg.inv(sens.compliance(task.targets))
    err = net.lengths(x, task.targets) - task.desired_lengths(net, strain_reference)
    rows = sens.length_rows(task.targets)
    v, _ = sens.solve(rows.T @ (K @ err))
    dr = length_jacobian_rows(net, x, v)
    if dof == "rest_length":
        grad = net.stiffness * dr
    else:
        grad = -(net.lengths(x) - net.rest_length) * dr
    return -grad, K
