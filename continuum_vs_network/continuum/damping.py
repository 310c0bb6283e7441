"""Damping of a visco-elastic body: drag, Rayleigh, Kelvin-Voigt viscosity, a Maxwell arm.

:class:`Damping` holds the coefficients; :func:`damping_matrix` assembles ``C`` over the
displacement DOFs (the arm's internal strains are :mod:`.maxwell`'s); :func:`lattice_damping`
maps a network's :class:`~continuum_vs_network.network.viscous.Viscosity` (node drag, spring
dashpots, Maxwell arms) to its triangular lattice's continuum. Used by the time stepping of
:mod:`.viscoelastic` and the clamped steps of :mod:`.damped_states`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import scipy.sparse as sp

if TYPE_CHECKING:
    from ..network.viscous import Viscosity

from .body import ElasticBody, mass_matrix, stiffness_matrix
from .materials import (
    lattice_area_per_node,
    lattice_maxwell_arm,
    lattice_viscous_lame,
    node_drag_to_continuum,
)

__all__ = ["Damping", "damping_matrix", "lattice_damping"]

_RATES = ("drag", "rayleigh_mass", "rayleigh_stiffness", "viscous_lam", "viscous_mu")
_ARM = ("arm_lam", "arm_mu", "arm_viscous_lam", "arm_viscous_mu")


@dataclass(frozen=True)
class Damping:
    """Damping of a visco-elastic body (all coefficients >= 0, default none).

    Attributes
    ----------
    drag : float
        Substrate drag ``eta`` (force time per length**3 in 2D): ``C += eta M_1``.
    rayleigh_mass, rayleigh_stiffness : float
        Rayleigh ``alpha`` (1 / time) and ``beta`` (time): ``C += alpha M + beta K``.
    viscous_lam, viscous_mu : float
        Kelvin-Voigt viscous Lamé parameters (force time per length): the stiffness form
        with ``(lam_v, mu_v)`` is added to ``C``.
    arm_lam, arm_mu, arm_viscous_lam, arm_viscous_mu : float
        Maxwell arm of a standard linear solid (:mod:`.maxwell`): elastic Lamé parameters
        of the arm's spring and viscous ones of its dashpot; all four > 0 or all 0.
        Adds an internal strain per quadrature point.
    """

    drag: float = 0.0
    rayleigh_mass: float = 0.0
    rayleigh_stiffness: float = 0.0
    viscous_lam: float = 0.0
    viscous_mu: float = 0.0
    arm_lam: float = 0.0
    arm_mu: float = 0.0
    arm_viscous_lam: float = 0.0
    arm_viscous_mu: float = 0.0

    def __post_init__(self) -> None:
        for name in (*_RATES, *_ARM):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
            object.__setattr__(self, name, v)
        if self.viscous_lam > 0 and self.viscous_mu == 0:
            raise ValueError("viscous_lam > 0 needs viscous_mu > 0 (a shear viscosity)")
        if self.arm_lam + self.arm_mu + self.arm_viscous_lam + self.arm_viscous_mu > 0 and not (
            self.arm_mu > 0 and self.arm_viscous_mu > 0
        ):
            raise ValueError(
                "a Maxwell arm needs arm_mu > 0 and arm_viscous_mu > 0 "
                f"(got arm_mu={self.arm_mu}, arm_viscous_mu={self.arm_viscous_mu})"
            )

    @property
    def has_arm(self) -> bool:
        return self.arm_mu > 0


def lattice_damping(viscosity: Viscosity, *, spacing: float = 1.0) -> Damping:
    """The continuum :class:`Damping` of a triangular lattice with ``viscosity``.

    Node drag ``c`` -> substrate drag ``c / A`` (:func:`~.materials.node_drag_to_continuum`,
    ``A`` the area per node), spring dashpots -> Kelvin-Voigt viscosity
    (:func:`~.materials.lattice_viscous_lame`), Maxwell arms -> the continuum arm
    (:func:`~.materials.lattice_maxwell_arm`). Overdamped: no density.
    """
    from ..network.viscous import Viscosity

    if not isinstance(viscosity, Viscosity):
        raise ValueError(f"viscosity must be a Viscosity, got {type(viscosity).__name__}")
    _, eta = node_drag_to_continuum(viscosity.drag, area_per_node=lattice_area_per_node(spacing))
    lam_v, mu_v = lattice_viscous_lame(viscosity.dashpot)
    arm = (0.0, 0.0, 0.0, 0.0)
    if viscosity.has_arm:
        arm = lattice_maxwell_arm(viscosity.arm_stiffness, viscosity.arm_dashpot)
    return Damping(
        drag=eta,
        viscous_lam=lam_v,
        viscous_mu=mu_v,
        arm_lam=arm[0],
        arm_mu=arm[1],
        arm_viscous_lam=arm[2],
        arm_viscous_mu=arm[3],
    )


def damping_matrix(
    body: ElasticBody,
    damping: Damping,
    *,
    density: float = 0.0,
    K: sp.spmatrix | None = None,
    M: sp.spmatrix | None = None,
) -> sp.csr_matrix:
    """Damping matrix ``C`` (n_dofs, n_dofs) of ``damping`` on ``body``.

    ``K`` (stiffness) and ``M`` (mass at ``density``) are assembled when needed and not given.
    """
    n = body.n_dofs
    C = sp.csr_matrix((n, n))
    if damping.drag > 0:
        C = C + damping.drag * mass_matrix(body, 1.0)
    if damping.rayleigh_mass > 0:
        M = mass_matrix(body, density) if M is None else M
        C = C + damping.rayleigh_mass * M
    if damping.rayleigh_stiffness > 0:
        K = stiffness_matrix(body) if K is None else K
        C = C + damping.rayleigh_stiffness * K
    if damping.viscous_mu > 0:
        C = C + stiffness_matrix(body, lam=damping.viscous_lam, mu=damping.viscous_mu)
    return sp.csr_matrix(C)
