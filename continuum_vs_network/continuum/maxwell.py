"""Maxwell arm of a standard linear solid: an internal strain at every quadrature point.

The arm is an elastic material ``C2`` (Lamé ``arm_lam, arm_mu``) in series with a viscous
one ``V2`` (``arm_viscous_lam, arm_viscous_mu``). Its internal variable is the dashpot
strain ``e`` (Voigt ``xx, yy, 2xy``) at each quadrature point ``q`` of weight ``w_q``::

    energy       sum_q w_q (B u - e)_q . C2 (B u - e)_q / 2
    dissipation  sum_q w_q e'_q . V2 e'_q / 2

so ``V2 e' = C2 (eps(u) - e)`` pointwise and the body's equations gain the arm stress.
``B`` maps displacement DOFs to Voigt strains at quadrature points. This is the continuum
of a network's Maxwell arms (one internal length per spring, :mod:`~..network.viscous`):
in a triangular lattice the three spring directions of a triangle fix one strain tensor,
so per-spring arm lengths and a tensor internal strain are the same thing
(:func:`~.materials.lattice_maxwell_arm`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .body import ElasticBody

__all__ = ["ArmOperators", "ArmStep", "arm_operators", "arm_step", "damping_arm", "voigt"]


def voigt(lam: float, mu: float) -> np.ndarray:
    """Isotropic 2D tensor ``lam tr I + 2 mu`` in Voigt form (engineering shear), (3, 3)."""
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


@dataclass(frozen=True, eq=False)
class ArmOperators:
    """Matrices of a Maxwell arm on a body.

    Attributes
    ----------
    strain : (3 n_q, n_dofs) sparse
        ``B``: Voigt strains at the quadrature points.
    stiffness, viscosity : (3 n_q, 3 n_q) sparse, block diagonal
        ``w_q C2`` and ``w_q V2``.
    """

    strain: sp.csr_matrix
    stiffness: sp.csr_matrix
    viscosity: sp.csr_matrix

    @property
    def n_internal(self) -> int:
        return int(self.strain.shape[0])


def arm_operators(
    body: ElasticBody, *, arm_lam: float, arm_mu: float, viscous_lam: float, viscous_mu: float
) -> ArmOperators:
    """``B``, ``w C2`` and ``w V2`` of a uniform Maxwell arm on ``body``."""
    basis = body.basis
    ne, nq = basis.dx.shape
    rows, cols, vals = [], [], []
    qp = np.arange(ne * nq).reshape(ne, nq)
    for i, fields in enumerate(basis.basis):
        g = fields[0].grad  # (component, derivative, element, point)
        dof = np.broadcast_to(basis.element_dofs[i][:, None], (ne, nq))
        for c, comp in enumerate((g[0, 0], g[1, 1], g[0, 1] + g[1, 0])):
            rows.append((3 * qp + c).ravel())
            cols.append(dof.ravel())
            vals.append(comp.ravel())
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(3 * ne * nq, body.n_dofs),
    )
    B.eliminate_zeros()
    w = basis.dx.ravel()
    S = sp.kron(sp.diags(w), sp.csr_matrix(voigt(arm_lam, arm_mu)), format="csr")
    V = sp.kron(sp.diags(w), sp.csr_matrix(voigt(viscous_lam, viscous_mu)), format="csr")
    return ArmOperators(B, S, V)


def damping_arm(body: ElasticBody, damping) -> ArmOperators:
    """The arm operators of a :class:`~.damping.Damping` with a Maxwell arm on ``body``."""
    if not damping.has_arm:
        raise ValueError("damping has no Maxwell arm (arm_mu and arm_viscous_mu are 0)")
    return arm_operators(
        body,
        arm_lam=damping.arm_lam,
        arm_mu=damping.arm_mu,
        viscous_lam=damping.arm_viscous_lam,
        viscous_mu=damping.arm_viscous_mu,
    )


@dataclass(frozen=True, eq=False)
class ArmStep:
    """A backward-Euler step of the arm with its internal strain eliminated.

    ``V (e1 - e0) / dt = S (B u1 - e1)`` gives ``B u1 - e1 = P (B u1 - e0)`` with ``P =
    (V + dt S)^-1 V`` per quadrature point, so the arm's stress over the step is
    ``S_dt (B u1 - e0)``, ``S_dt = S P = (S^-1 + dt V^-1)^-1``: a spring (stiffness
    ``B^T S_dt B``) pulled towards the old internal strain. L-stable: ``dt = inf`` gives
    ``S_dt = 0`` and ``e1 = B u1`` (the arm relaxed, no force).

    Attributes
    ----------
    operators : ArmOperators
    dt : float
    stiffness : (3 n_q, 3 n_q) sparse
        ``S_dt`` (block diagonal).
    memory : (3 n_q, 3 n_q) sparse
        ``P`` (block diagonal).
    """

    operators: ArmOperators
    dt: float
    stiffness: sp.csr_matrix
    memory: sp.csr_matrix

    def update(self, strain: np.ndarray, arm: np.ndarray) -> np.ndarray:
        """The internal strain ``e1`` (3 n_q,) after the step, from ``B u1`` and ``e0``."""
        return strain - self.memory @ (strain - arm)

    def force(self, strain: np.ndarray, arm: np.ndarray) -> np.ndarray:
        """The arm's nodal force ``B^T S_dt (B u1 - e0)`` (n_dofs,) over the step."""
        return self.operators.strain.T @ (self.stiffness @ (strain - arm))


def _blocks(matrix: sp.spmatrix, n: int) -> np.ndarray:
    """The (n, 3, 3) diagonal blocks of a block-diagonal (3 n, 3 n) matrix."""
    coo = sp.coo_matrix(matrix)
    if np.any(coo.row // 3 != coo.col // 3):
        raise ValueError("the arm operators must be block diagonal (3 x 3 per point)")
    out = np.zeros((n, 3, 3))
    np.add.at(out, (coo.row // 3, coo.row % 3, coo.col % 3), coo.data)
    return out


def _block_diagonal(blocks: np.ndarray) -> sp.csr_matrix:
    n = blocks.shape[0]
    return sp.bsr_matrix((blocks, np.arange(n), np.arange(n + 1)), shape=(3 * n, 3 * n)).tocsr()


def arm_step(operators: ArmOperators, dt: float) -> ArmStep:
    """The eliminated backward-Euler step of length ``dt`` (> 0, ``inf`` allowed) of an arm."""
    dt = float(dt)
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    n = operators.n_internal // 3
    if not math.isfinite(dt):
        zero = sp.csr_matrix((3 * n, 3 * n))
        return ArmStep(operators, dt, zero, zero)
    S = _blocks(operators.stiffness, n)
    V = _blocks(operators.viscosity, n)
    P = np.linalg.solve(V + dt * S, V)
    return ArmStep(operators, dt, _block_diagonal(S @ P), _block_diagonal(P))
