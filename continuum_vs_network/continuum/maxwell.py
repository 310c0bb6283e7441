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

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .body import ElasticBody

__all__ = ["ArmOperators", "arm_operators", "voigt"]


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
