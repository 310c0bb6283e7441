"""Static solves of an elastic body: Dirichlet conditions, one sparse factorisation, timings.

``K u = f`` with prescribed displacements on some DOFs is reduced to the free DOFs and
factorised with SuperLU. Two choices matter for speed (``benchmarks/bench_continuum.py``
measures both):

- the ordering ``MMD_AT_PLUS_A`` (minimum degree on ``A + A^T``, right for the symmetric
  matrices of elasticity) gave 35-55 % less fill than SciPy's default ``COLAMD`` and
  factorised 1.6-1.8x (P1) and 2.0-2.4x (P2) faster at 1e5 DOFs; one exception measured:
  on a perfectly regular 158 x 79 P2 grid (ties in the minimum degree) it was 1.3x slower;
- for symmetric positive definite matrices (every matrix factorised here) SuperLU's
  symmetric mode (diagonal pivots, ``diag_pivot_thresh=0``) keeps that ordering; SuperLU's
  default partial pivoting breaks it and made P2 factorisations 5x slower at 5e4 DOFs and
  more than 50x slower at 1e5. A relative-residual check guards every solve.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from ..linalg.kkt import sparse_lu
from .body import ElasticBody, dofs_where, stiffness_matrix

__all__ = [
    "Dirichlet",
    "Factorisation",
    "StaticSolution",
    "factorise",
    "fix",
    "solve_static",
]

Ordering = Literal["MMD_AT_PLUS_A", "COLAMD", "MMD_ATA", "NATURAL"]


@dataclass(frozen=True, eq=False)
class Dirichlet:
    """Prescribed displacements.

    Attributes
    ----------
    dofs : (m,) int array
        Sorted, unique DOF indices.
    values : (m,) float array
        Their displacements (length units).
    """

    dofs: NDArray[np.int64]
    values: NDArray[np.float64]

    def __post_init__(self) -> None:
        dofs = np.asarray(self.dofs, dtype=np.int64).ravel()
        values = np.broadcast_to(np.asarray(self.values, dtype=float), dofs.shape).copy()
        if np.any(~np.isfinite(values)):
            raise ValueError("Dirichlet values must be finite")
        order = np.argsort(dofs, kind="stable")
        dofs, values = dofs[order], values[order]
        dup = np.flatnonzero(np.diff(dofs) == 0)
        if dup.size and np.any(values[dup] != values[dup + 1]):
            bad = dofs[dup[values[dup] != values[dup + 1]][0]]
            raise ValueError(f"DOF {bad} is prescribed twice with different values")
        keep = np.ones(dofs.size, dtype=bool)
        keep[dup + 1] = False
        dofs, values = dofs[keep], values[keep]
        dofs.setflags(write=False)
        values.setflags(write=False)
        object.__setattr__(self, "dofs", dofs)
        object.__setattr__(self, "values", values)

    def __add__(self, other: Dirichlet) -> Dirichlet:
        return Dirichlet(
            np.concatenate([self.dofs, other.dofs]), np.concatenate([self.values, other.values])
        )

    def scaled(self, factor: float) -> Dirichlet:
        """The same DOFs with values multiplied by ``factor``."""
        return Dirichlet(self.dofs, self.values * float(factor))

    def vector(self, n_dofs: int) -> NDArray[np.float64]:
        """Full (n_dofs,) vector: the prescribed values, zero elsewhere."""
        u = np.zeros(n_dofs)
        u[self.dofs] = self.values
        return u


def fix(
    body: ElasticBody,
    where: Callable[[NDArray, NDArray], NDArray],
    *,
    displacement: tuple[float, float] | Callable[[NDArray, NDArray], tuple] = (0.0, 0.0),
    component: int | None = None,
    boundary: bool = False,
) -> Dirichlet:
    """Prescribe the displacement of the DOFs located where ``where(x, y)`` holds.

    Parameters
    ----------
    displacement : (2,) floats or callable ``(x, y) -> (u_x, u_y)``
        The displacement to impose (length units); default zero (clamped).
    component : {0, 1, None}
        Prescribe only ``x`` (0) or ``y`` (1).
    boundary : bool
        Only boundary DOFs.
    """
    dofs = dofs_where(body, where, component=component, boundary=boundary)
    if dofs.size == 0:
        raise ValueError("no DOF satisfies `where`: nothing would be fixed")
    loc = body.dof_locations[dofs]
    comp = body.dof_component[dofs]
    if callable(displacement):
        ux, uy = displacement(loc[:, 0], loc[:, 1])
        ux = np.broadcast_to(np.asarray(ux, float), comp.shape)
        uy = np.broadcast_to(np.asarray(uy, float), comp.shape)
        values = np.where(comp == 0, ux, uy)
    else:
        d = np.asarray(displacement, dtype=float)
        if d.shape != (2,):
            raise ValueError(f"displacement must be a pair (u_x, u_y) or a callable, got {d}")
        values = d[comp]
    return Dirichlet(dofs, values)


class Factorisation:
    """A sparse LU factorisation of a square matrix, built once and reused.

    Attributes
    ----------
    seconds : float
        Wall-clock time of the factorisation.
    ordering : str
        SuperLU column ordering used.
    """

    def __init__(
        self, A: sp.spmatrix, *, ordering: Ordering = "MMD_AT_PLUS_A", symmetric: bool = True
    ) -> None:
        if A.shape[0] != A.shape[1]:
            raise ValueError(f"matrix must be square, got shape {A.shape}")
        t0 = time.perf_counter()
        try:
            self._lu = sparse_lu(A, ordering=ordering, symmetric=symmetric)
        except RuntimeError as err:
            raise ValueError(
                f"the matrix is singular ({err}): the body can move without strain. Fix "
                "enough displacements to remove rigid motion, or add mass/damping"
            ) from err
        self.seconds = time.perf_counter() - t0
        self.ordering = ordering
        self.symmetric = bool(symmetric)
        self.shape = A.shape

    @property
    def fill(self) -> int:
        """Non-zeros of the factors ``L + U``."""
        return int(self._lu.L.nnz + self._lu.U.nnz)

    def solve(self, b: ArrayLike) -> NDArray[np.float64]:
        """``A^{-1} b`` for a (n,) or (n, k) right-hand side."""
        x = self._lu.solve(np.asarray(b, dtype=float))
        if not np.all(np.isfinite(x)):
            raise FloatingPointError("the factorised solve returned non-finite values")
        return x


def factorise(
    A: sp.spmatrix, *, ordering: Ordering = "MMD_AT_PLUS_A", symmetric: bool = True
) -> Factorisation:
    """Factorise ``A`` once with SuperLU.

    Parameters
    ----------
    A : (n, n) sparse matrix
    ordering : str
        SuperLU ``permc_spec``.
    symmetric : bool
        ``A`` is symmetric positive definite: diagonal pivots in SuperLU's symmetric mode
        (fast, keeps the ordering). False uses SuperLU's partial pivoting.
    """
    return Factorisation(A, ordering=ordering, symmetric=symmetric)


def _check_rigid(body: ElasticBody, fixed: Dirichlet) -> None:
    """Fixed DOFs must stop both translations and the rotation."""
    loc = body.dof_locations[fixed.dofs]
    comp = body.dof_component[fixed.dofs]
    if loc.size == 0:
        raise ValueError("no DOF is fixed: the body is free to move rigidly (static solve)")
    centre = body.dof_locations.mean(axis=0)
    scale = float(np.ptp(body.dof_locations, axis=0).max())
    rigid = np.column_stack(
        [
            comp == 0,
            comp == 1,
            np.where(comp == 0, -(loc[:, 1] - centre[1]), loc[:, 0] - centre[0]) / scale,
        ]
    ).astype(float)
    if np.linalg.matrix_rank(rigid, tol=1e-8) < 3:
        raise ValueError(
            "the fixed DOFs do not stop rigid motion (both translations and the rotation); "
            "fix more DOFs"
        )


@dataclass(frozen=True, eq=False)
class StaticSolution:
    """Result of :func:`solve_static`.

    Attributes
    ----------
    u : (n_dofs,) float array
        Displacement DOFs (length units).
    reaction : (m,) float array
        Force needed at each fixed DOF, ``(K u - f)[fixed.dofs]``.
    residual : float
        ``|K_ff u_f - rhs| / |rhs|`` on the free DOFs (relative; 0 when ``rhs`` is 0).
    seconds_assembly, seconds_factorisation, seconds_solve : float
        Wall-clock times of the stiffness assembly (0 when ``K`` was given), the
        factorisation and the triangular solves.
    """

    u: NDArray[np.float64]
    reaction: NDArray[np.float64]
    residual: float
    seconds_assembly: float
    seconds_factorisation: float
    seconds_solve: float
    fixed: Dirichlet = field(repr=False)

    @property
    def seconds(self) -> float:
        return self.seconds_assembly + self.seconds_factorisation + self.seconds_solve


def solve_static(
    body: ElasticBody,
    fixed: Dirichlet,
    *,
    load: ArrayLike | None = None,
    K: sp.spmatrix | None = None,
    ordering: Ordering = "MMD_AT_PLUS_A",
    symmetric: bool = True,
    residual_tol: float = 1e-6,
) -> StaticSolution:
    """Solve ``K u = load`` with the displacements in ``fixed`` prescribed.

    Parameters
    ----------
    body : ElasticBody
    fixed : Dirichlet
        Must stop rigid motion (checked; a ``ValueError`` says so otherwise).
    load : (n_dofs,) float array, optional
        Load vector (see :func:`~.body.pressure_load`, :func:`~.body.eigenstrain_load`,
        :func:`~.body.body_force_load`); zero by default.
    K : sparse matrix, optional
        The stiffness matrix, if already assembled.
    ordering : str
        SuperLU column ordering.
    symmetric : bool
        Factorise in SuperLU's symmetric mode (see :func:`factorise`).
    residual_tol : float
        Largest accepted relative residual; beyond it (an ill-conditioned system) a
        ``RuntimeError`` is raised instead of returning a wrong answer.

    Returns
    -------
    StaticSolution
    """
    n = body.n_dofs
    if fixed.dofs.size and (fixed.dofs[0] < 0 or fixed.dofs[-1] >= n):
        raise ValueError(f"fixed DOFs must lie in 0..{n - 1}")
    _check_rigid(body, fixed)
    f = np.zeros(n) if load is None else np.asarray(load, dtype=float)
    if f.shape != (n,):
        raise ValueError(f"load must have shape ({n},), got {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("load must be finite")
    t_asm = 0.0
    if K is None:
        t0 = time.perf_counter()
        K = stiffness_matrix(body)
        t_asm = time.perf_counter() - t0
    else:
        K = sp.csr_matrix(K)
        if K.shape != (n, n):
            raise ValueError(f"K must have shape ({n}, {n}), got {K.shape}")
    free = np.ones(n, dtype=bool)
    free[fixed.dofs] = False
    fi = np.flatnonzero(free)
    u = fixed.vector(n)
    K_f = K[fi]
    rhs = f[fi] - K_f[:, fixed.dofs] @ fixed.values
    lu = factorise(K_f[:, fi], ordering=ordering, symmetric=symmetric)
    t1 = time.perf_counter()
    u[fi] = lu.solve(rhs)
    t_solve = time.perf_counter() - t1
    Ku = K @ u
    r = Ku[fi] - f[fi]
    scale = float(np.linalg.norm(rhs))
    residual = float(np.linalg.norm(r) / scale) if scale > 0 else float(np.linalg.norm(r))
    if residual > residual_tol:
        raise RuntimeError(
            f"static solve is inaccurate (relative residual {residual:.2e} > {residual_tol:g}); "
            "the stiffness matrix is too ill-conditioned (extreme modulus contrast or "
            "degenerate elements)"
        )
    return StaticSolution(
        u=u,
        reaction=(Ku - f)[fixed.dofs],
        residual=residual,
        seconds_assembly=t_asm,
        seconds_factorisation=lu.seconds,
        seconds_solve=t_solve,
        fixed=fixed,
    )
