"""Free, clamped and adjoint states of a learnable body: one factorisation, many clamps.

The clamped problem ``min E(u)`` subject to ``G_c u = v`` (material springs ``c`` clamped
at strains ``v``, DOFs ``task.fixed`` at zero) is the KKT system::

    [ K    G_c^T ] [ u      ]   [ f ]
    [ G_c  0     ] [ lambda ] = [ v ]

It is solved through the Schur complement: ``K`` (fixed DOFs removed) is factorised once,
``Z = K^-1 G^T`` is formed for every source *and* target functional (one multi-column
solve), and then any clamp set costs one solve for ``u0 = K^-1 f`` plus a dense system of
the size of the clamp set: ``lambda = (G_c Z_c)^-1 (G_c u0 - v)``, ``u = u0 - Z_c lambda``.
The free state (sources clamped), the nudged and the fully clamped states and the adjoint
all reuse the one factorisation; with eigenstrain learning ``K`` never changes, so a whole
training run factorises once. The factorisation (:func:`~..linalg.kkt.factor_spd`) and the
Schur-complement solve (:func:`~..linalg.kkt.schur_solve`) are the network engine's.

Adjoint: a cost ``C = d^T W d / 2`` of the free target strains ``d = G_t u^F - S_T``
has ``dC/dtheta = p . (df/dtheta - dK/dtheta u^F)`` with
``[K G_s^T; G_s 0] [p; mu] = [G_t^T W d; 0]``, i.e. ``p = Z_t w - Z_s (G_s Z_s)^-1
G_s Z_t w`` with ``w = W d``: no further factorisation or solve.

Effective stiffness of the targets: ``K_T = (G_t P K^-1 G_t^T)^-1`` with the sources
clamped, ``= (S_tt - S_ts S_ss^-1 S_st)^-1`` in the blocks of ``S = G Z``. In linear
elasticity ``E^C - E^F = (v - S^F)^T K_T (v - S^F) / 2`` exactly, which is why coupled
learning of the eigenstrain is the gradient of ``(S^F - S_T)^T K_T (S^F - S_T) / 2`` at
every nudge amplitude (``tests/test_continuum_learning.py``).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..linalg.kkt import schur_solve

__all__ = [
    "MaterialState",
    "clamped_state",
    "cost_gradient",
    "effective_stiffness",
    "free_state",
    "free_state_measurements",
    "free_target_strain",
]


@dataclass(frozen=True, eq=False)
class MaterialState:
    """An equilibrium of a learnable body with some material springs clamped.

    Attributes
    ----------
    u : (n_dofs,) float array
        Displacement.
    multipliers : (n_clamped,) float array
        Lagrange multipliers (clamp forces) of the clamped springs, sources first.
    source_strain, target_strain : (n_sources,), (n_targets,) float arrays
        Strains of the source and target material springs in this state.
    energy : float
        Elastic energy.
    residual : float
        Largest absolute out-of-balance force on a free DOF, clamp forces included.
    positions : (n_vertices, 2) float array
        Deformed mesh vertices.
    """

    u: NDArray[np.float64] = field(repr=False)
    multipliers: NDArray[np.float64]
    source_strain: NDArray[np.float64]
    target_strain: NDArray[np.float64]
    energy: float
    residual: float
    positions: NDArray[np.float64] = field(repr=False)
    converged: bool = True
    iterations: int = 0


class _System:
    """Factorised stiffness of one modulus field and one task's clamps (cached)."""

    def __init__(self, medium, task, tracker) -> None:
        from ..linalg.kkt import factor_spd
        from .probes import material_spring_probe

        n = medium.n_dofs
        keep = np.ones(n, dtype=bool)
        keep[task.fixed] = False
        self.free = np.flatnonzero(keep)
        K = medium.stiffness()[self.free][:, self.free]
        self.K = K
        factor = factor_spd(K, certify=False)  # K > 0: the task's fixed DOFs stop rigid motion
        if factor is None:
            raise ValueError(
                "the stiffness with the fixed DOFs removed is not positive definite: the body "
                "can move without strain; fix enough DOFs to stop rigid motion"
            )
        self.factor = factor
        body = medium.body
        G = material_spring_probe(
            body,
            np.vstack([task.source_a, task.target_a]),
            np.vstack([task.source_b, task.target_b]),
            task.radius,
        ).operator
        self.G = G.tocsc()[:, self.free].tocsr()
        self.Z = np.asarray(factor.solve(self.G.T.toarray()))  # (n_free, n_s + n_t)
        self.S = self.G @ self.Z
        self.n_sources = task.n_sources
        self._u0: tuple[NDArray, tuple] | None = None
        self._const: tuple[NDArray, float] | None = None
        self._rows: dict[bytes, tuple] = {}
        if tracker is not None:
            tracker.stats.factorisations += 1

    def held(self, clamped: NDArray) -> tuple:
        """``G``'s rows ``clamped`` (sparse), ``Z``'s columns and ``S``'s block for them,
        kept per clamp set (a solve's free and clamped states use two; slicing the sparse
        rows at every solve cost more than the solve)."""
        clamped = np.asarray(clamped, dtype=np.int64)  # one dtype: equal sets, equal keys
        key = clamped.tobytes()
        hit = self._rows.get(key)
        if hit is None:
            hit = self._rows[key] = (
                self.G[clamped],
                self.Z[:, clamped],
                self.S[np.ix_(clamped, clamped)],
            )
        return hit

    def u0(self, medium) -> tuple[NDArray, NDArray]:
        """``K^-1 f`` and the load ``f`` on the free DOFs of the medium's eigenstrain
        (cached)."""
        key = medium.eigenstrain  # read-only; a new field is a new array
        if self._u0 is None or self._u0[0] is not key:
            f = medium.load()[self.free]
            u0 = self.factor.solve(f) if np.any(f) else np.zeros_like(f)
            self._u0 = (key, (u0, f))
        return self._u0[1]

    def energy_constant(self, medium) -> float:
        """``sum_e s_e A_e m0 . C m0 / 2`` of the medium's eigenstrain (cached)."""
        key = medium.eigenstrain
        if self._const is None or self._const[0] is not key:
            self._const = (key, medium.eigenstrain_energy())
        return self._const[1]


def _key(task) -> str:
    h = hashlib.sha1()
    for a in (task.fixed, task.source_a, task.source_b, task.target_a, task.target_b):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(np.float64(task.radius).tobytes())
    return h.hexdigest()


def cached_system(medium, task, tracker) -> _System:
    """The medium's factorised system for ``task`` (its sources and targets), built once
    and kept in ``medium._cache`` until another task's is asked for; shared by the free
    and clamped states here and the damped stepper at equilibrium."""
    key = _key(task)
    system = medium._cache.get(key)
    if system is None:
        medium._cache.clear()
        system = medium._cache[key] = _System(medium, task, tracker)
    return system


def _clamped(medium, task, clamped: NDArray, values: NDArray, tracker):
    """The clamped solve on the cached system: ``(system, f, Gc, uf, lam)``, with ``f`` the
    load and ``Gc`` the rows of the clamped strains; FloatingPointError if not finite."""
    sys_ = cached_system(medium, task, tracker)
    u0, f = sys_.u0(medium)
    Gc, Zc, Sc = sys_.held(clamped)
    uf, lam = schur_solve(u0, Gc, Zc, Sc, values)
    if tracker is not None:
        tracker.stats.solves += 1
    if not (np.all(np.isfinite(uf)) and np.all(np.isfinite(lam))):
        raise FloatingPointError("the clamped solve returned non-finite values")
    return sys_, f, Gc, uf, lam


def _solve(medium, task, clamped: NDArray, values: NDArray, tracker) -> MaterialState:
    sys_, f, Gc, uf, lam = _clamped(medium, task, clamped, values, tracker)
    u = np.zeros(medium.n_dofs)
    u[sys_.free] = uf
    Ku = sys_.K @ uf
    residual = float(np.max(np.abs(Ku + Gc.T @ lam - f), initial=0.0))
    energy = float(0.5 * uf @ Ku - f @ uf + sys_.energy_constant(medium))
    strains = sys_.G @ uf
    if not np.isfinite(residual):
        raise FloatingPointError("the clamped solve returned non-finite values")
    ns = task.n_sources
    return MaterialState(
        u=u,
        multipliers=lam,
        source_strain=strains[:ns],
        target_strain=strains[ns:],
        energy=energy,
        residual=residual,
        positions=medium.vertex_positions(u),
    )


def free_state(medium, task, *, tracker=None) -> MaterialState:
    """Sources clamped at ``task.source_strain``; targets free."""
    return _solve(medium, task, np.arange(task.n_sources), task.source_strain, tracker)


def free_target_strain(medium, task) -> NDArray[np.float64]:
    """``free_state(medium, task).target_strain`` alone (the same numbers), without the
    state's energy, residual and positions: what learning in time records at every step."""
    sys_, _, _, uf, _ = _clamped(medium, task, np.arange(task.n_sources), task.source_strain, None)
    return (sys_.G @ uf)[task.n_sources :]


def clamped_state(medium, task, target_strain: ArrayLike, *, tracker=None) -> MaterialState:
    """Sources clamped at their strains and targets at ``target_strain`` (n_targets,)."""
    v = np.concatenate([task.source_strain, np.asarray(target_strain, float)])
    return _solve(medium, task, np.arange(task.n_sources + task.n_targets), v, tracker)


def effective_stiffness(medium, task, *, tracker=None) -> NDArray[np.float64]:
    """Effective stiffness of the target strains with the sources clamped, (n_t, n_t):
    ``E^C - E^F = (v - S^F)^T K_T (v - S^F) / 2`` for targets clamped at ``v``."""
    S = cached_system(medium, task, tracker).S
    ns = task.n_sources
    Q = S[ns:, ns:] - S[ns:, :ns] @ np.linalg.solve(S[:ns, :ns], S[:ns, ns:])
    return np.linalg.inv(0.5 * (Q + Q.T))


def cost_gradient(
    medium,
    task,
    free: MaterialState,
    dof: str,
    *,
    weight: ArrayLike | None = None,
    tracker=None,
) -> NDArray[np.float64]:
    """``dC/dtheta`` per unit element area for ``C = d^T W d / 2``, ``d = S^F_T - S_T``.

    ``weight`` ``W`` is (n_targets, n_targets) (default the identity: Eq. 26).
    """
    sys_ = cached_system(medium, task, tracker)
    ns = task.n_sources
    d = free.target_strain - task.target_strain
    w = d if weight is None else np.asarray(weight, float) @ d
    # p solves [K G_s^T; G_s 0] [p; mu] = [G_t^T w; 0], and K^-1 G_t^T w = Z_t w
    pf, _ = schur_solve(sys_.Z[:, ns:] @ w, sys_.G[:ns], sys_.Z[:, :ns], sys_.S[:ns, :ns], 0.0)
    p = np.zeros(medium.n_dofs)
    p[sys_.free] = pf
    return medium.parameter_gradient(free.u, p, dof)


def free_state_measurements(
    medium: Any, task: Any, free: Any, dof: str, mask: NDArray
) -> dict[str, Any]:
    """What :func:`~continuum_vs_network.train` records of a learning medium's free state:
    target lengths (those of the material springs: undeformed ``|ab|``, deformed
    ``|ab| (1 + S)``), strains, the error (one convention: the material has no learning rest
    length), the energy and the norm of ``medium``'s local gradient of ``dof`` on ``mask``."""
    length = task.target_length
    g = medium.local_gradient(free, dof)[mask]
    err = task.error(free.target_strain)
    return {
        "target_rest_length": length,
        "desired_length": length * (1.0 + task.target_strain),
        "target_length": length * (1.0 + free.target_strain),
        "target_strain": free.target_strain,
        "error_current": err,
        "error_initial": err,
        "energy_free": free.energy,
        "energy_gradient_free": float(np.sqrt(np.sum(g * g))),
        "residual": free.residual,
    }
