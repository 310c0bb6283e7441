"""Element operators of a P1/P2 vector basis for element-wise material fields.

Mandel strain ``m = (eps_xx, eps_yy, sqrt(2) eps_xy)``: ``eps : C : eps = m . C_m . m``.
Per element (unit modulus): stiffness ``K_e = int B^T C B``, eigenstrain coupling
``G_e = int B^T C``, integrated strain ``int B``; and the fixed CSR pattern of the global
stiffness with the scatter map that assembles ``sum_e s_e K_e`` by one ``bincount``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ISOTROPIC", "SQRT2", "mandel", "tensor"]

SQRT2 = float(np.sqrt(2.0))
ISOTROPIC = np.array([1.0, 1.0, 0.0])  # eps0 = e I in Mandel form


def mandel(eps: ArrayLike) -> NDArray[np.float64]:
    """Tensor components ``(xx, yy, xy)`` -> Mandel ``(xx, yy, sqrt(2) xy)``, (..., 3)."""
    e = np.array(eps, dtype=float)
    e[..., 2] *= SQRT2
    return e


def tensor(m: ArrayLike) -> NDArray[np.float64]:
    """Mandel ``(xx, yy, sqrt(2) xy)`` -> tensor components ``(xx, yy, xy)``, (..., 3)."""
    e = np.array(m, dtype=float)
    e[..., 2] /= SQRT2
    return e


@dataclass(frozen=True, eq=False)
class _Operators:
    """Element operators of one mesh and basis (shared by every field on it)."""

    edofs: NDArray[np.int64]  # (n_el, nb) global DOFs of each element
    area: NDArray[np.float64]  # (n_el,)
    C: NDArray[np.float64]  # (n_el, 3, 3) Mandel elasticity at unit modulus
    Ke: NDArray[np.float64]  # (n_el, nb, nb) element stiffness at unit modulus
    Ge: NDArray[np.float64]  # (n_el, nb, 3) int B^T C
    Bbar: NDArray[np.float64]  # (n_el, 3, nb) int B
    rows: NDArray[np.int64]  # CSR structure of the global stiffness
    cols: NDArray[np.int64]
    indptr: NDArray[np.int64]
    scatter: NDArray[np.int64]  # (n_el * nb * nb,) entry -> position in the CSR data
    n_dofs: int
    memo: dict = field(default_factory=dict, repr=False)  # per-mesh caches (masks)


def _operators(basis: Any, lam: NDArray, mu: NDArray) -> _Operators:
    nb = basis.Nbfun
    n_el = basis.mesh.t.shape[1]
    B = np.empty((n_el, basis.dx.shape[1], 3, nb))
    for i in range(nb):
        G = np.asarray(basis.basis[i][0].grad)  # (2, 2, n_el, n_q): d v_c / d x_j
        B[:, :, 0, i] = G[0, 0]
        B[:, :, 1, i] = G[1, 1]
        B[:, :, 2, i] = (G[0, 1] + G[1, 0]) / SQRT2
    dx = np.asarray(basis.dx)
    C = np.zeros((n_el, 3, 3))
    C[:, 0, 0] = C[:, 1, 1] = lam + 2 * mu
    C[:, 0, 1] = C[:, 1, 0] = lam
    C[:, 2, 2] = 2 * mu
    Bw = B * dx[:, :, None, None]
    Bbar = Bw.sum(axis=1)
    CB = np.einsum("eab,eqbj->eqaj", C, B)
    Ke = np.einsum("eqai,eqaj->eij", Bw, CB)
    Ke = 0.5 * (Ke + Ke.transpose(0, 2, 1))
    Ge = np.einsum("eai,eab->eib", Bbar, C)
    edofs = np.ascontiguousarray(basis.element_dofs.T.astype(np.int64))
    N = int(basis.N)
    r = np.repeat(edofs, nb, axis=1).ravel()
    c = np.tile(edofs, (1, nb)).ravel()
    keys, scatter = np.unique(r * N + c, return_inverse=True)
    rows, cols = keys // N, keys % N
    indptr = np.zeros(N + 1, dtype=np.int64)
    np.add.at(indptr, rows + 1, 1)
    indptr = np.cumsum(indptr)
    return _Operators(
        edofs, dx.sum(axis=1), C, Ke, Ge, Bbar, rows, cols, indptr, scatter.ravel(), N
    )
