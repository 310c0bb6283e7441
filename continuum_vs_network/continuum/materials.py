"""Material parameters and the mappings between networks and continua.

One function per mapping between conventions:

- Young's modulus and Poisson ratio to the 2D Lamé parameters, for plane strain and plane
  stress (:meth:`Material.from_young`, :func:`plane_stress_lambda`);
- a triangular lattice of springs ``k`` (spacing ``a``, pre-tension ``T``) to its Lamé
  parameters (:func:`lattice_lame`);
- spring dashpots to viscous Lamé parameters (:func:`lattice_viscous_lame`);
- Maxwell arms on the springs to the arm of a continuum standard linear solid
  (:func:`lattice_maxwell_arm`);
- node masses and node drag to a density and a substrate-drag coefficient
  (:func:`node_drag_to_continuum`);
- any network (for example a trained one) to its homogenised elastic tensor, by affine or
  relaxed-affine deformation (:func:`network_moduli`).

2D Lamé parameters ``(lam, mu)`` are the ones that enter the 2D stress
``sigma = lam tr(eps) I + 2 mu eps`` (force per length); every body in this package takes them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..linalg.spd import sparse_lu
from ..network.model import SpringNetwork

__all__ = [
    "Material",
    "NetworkModuli",
    "lattice_area_per_node",
    "lattice_lame",
    "lattice_maxwell_arm",
    "lattice_viscous_lame",
    "network_moduli",
    "node_drag_to_continuum",
    "plane_stress_lambda",
    "voigt_isotropic",
]

SQRT3 = math.sqrt(3.0)


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic 2D material.

    Attributes
    ----------
    lam, mu : float
        2D Lamé parameters (force per length in 2D units); ``mu > 0`` and
        ``lam + mu > 0`` (positive 2D bulk modulus).
    """

    lam: float
    mu: float

    def __post_init__(self) -> None:
        lam, mu = float(self.lam), float(self.mu)
        if not (math.isfinite(lam) and math.isfinite(mu)):
            raise ValueError(f"lam and mu must be finite, got lam={lam}, mu={mu}")
        if mu <= 0:
            raise ValueError(f"mu must be > 0, got {mu}")
        if lam + mu <= 0:
            raise ValueError(f"lam + mu (2D bulk modulus) must be > 0, got lam={lam}, mu={mu}")
        object.__setattr__(self, "lam", lam)
        object.__setattr__(self, "mu", mu)

    @classmethod
    def from_young(
        cls, young: float, poisson: float, *, plane: Literal["strain", "stress"] = "strain"
    ) -> Material:
        """Material from Young's modulus ``E`` and Poisson ratio ``nu``.

        ``plane="strain"``: ``lam = E nu / ((1 + nu)(1 - 2 nu))`` (needs ``nu < 0.5``);
        ``plane="stress"``: ``lam = E nu / (1 - nu**2)``. In both ``mu = E / (2 (1 + nu))``.
        """
        E, nu = float(young), float(poisson)
        if not (math.isfinite(E) and E > 0):
            raise ValueError(f"young must be finite and > 0, got {E}")
        if plane == "strain":
            if not (-1.0 < nu < 0.5):
                raise ValueError(f"poisson must lie in (-1, 0.5) for plane strain, got {nu}")
            lam = E * nu / ((1 + nu) * (1 - 2 * nu))
        elif plane == "stress":
            if not (-1.0 < nu < 1.0):
                raise ValueError(f"poisson must lie in (-1, 1) for plane stress, got {nu}")
            lam = E * nu / (1 - nu**2)
        else:
            raise ValueError(f"plane must be 'strain' or 'stress', got {plane!r}")
        return cls(lam, E / (2 * (1 + nu)))

    @property
    def bulk(self) -> float:
        """2D bulk modulus ``lam + mu``."""
        return self.lam + self.mu

    @property
    def p_wave(self) -> float:
        """P-wave (longitudinal) modulus ``lam + 2 mu``."""
        return self.lam + 2 * self.mu

    @property
    def poisson_plane_strain(self) -> float:
        """Poisson ratio if ``(lam, mu)`` are 3D parameters in plane strain."""
        return self.lam / (2 * (self.lam + self.mu))

    @property
    def locking_ratio(self) -> float:
        """``lam / mu``: above about 100 (``nu > 0.495``) P1 elements lock."""
        return self.lam / self.mu


def plane_stress_lambda(lam: float, mu: float) -> float:
    """First 2D Lamé parameter of a thin plate (plane stress) of a 3D material.

    ``lam_2d = 2 lam mu / (lam + 2 mu)``; ``mu`` is unchanged.
    """
    lam, mu = float(lam), float(mu)
    if mu <= 0 or lam + 2 * mu <= 0:
        raise ValueError(f"need mu > 0 and lam + 2 mu > 0, got lam={lam}, mu={mu}")
    return 2 * lam * mu / (lam + 2 * mu)


def lattice_lame(stiffness: float, *, spacing: float = 1.0, tension: float = 0.0) -> Material:
    """Lamé parameters of a triangular lattice of identical springs.

    Parameters
    ----------
    stiffness : float
        Spring constant ``k`` (force per length).
    spacing : float
        Lattice spacing ``a`` (the stretched spring length).
    tension : float
        Pre-tension ``T = k (a - L)`` carried by every spring (force).

    Returns
    -------
    Material
        ``lam = sqrt(3)/4 (k - T/a)``, ``mu = sqrt(3)/4 (k + T/a)``: without tension
        ``lam = mu = sqrt(3) k / 4``, independent of the spacing.
    """
    k, a, T = float(stiffness), float(spacing), float(tension)
    if not (math.isfinite(k) and k > 0):
        raise ValueError(f"stiffness must be finite and > 0, got {k}")
    if not (math.isfinite(a) and a > 0):
        raise ValueError(f"spacing must be finite and > 0, got {a}")
    if not math.isfinite(T):
        raise ValueError(f"tension must be finite, got {T}")
    return Material(SQRT3 / 4 * (k - T / a), SQRT3 / 4 * (k + T / a))


def lattice_viscous_lame(dashpot: float) -> tuple[float, float]:
    """Viscous Lamé parameters ``(lam_v, mu_v)`` of a triangular lattice of spring dashpots.

    A dashpot adds the force ``gamma * dr/dt`` along its spring; the same affine argument
    as for :func:`lattice_lame` gives ``lam_v = mu_v = sqrt(3) gamma / 4``
    (Kelvin-Voigt stress ``lam_v tr(deps/dt) I + 2 mu_v deps/dt``).
    """
    g = float(dashpot)
    if not (math.isfinite(g) and g >= 0):
        raise ValueError(f"dashpot must be finite and >= 0, got {g}")
    return SQRT3 / 4 * g, SQRT3 / 4 * g


def lattice_maxwell_arm(arm_stiffness: float, arm_dashpot: float) -> tuple[float, ...]:
    """Continuum Maxwell arm of a triangular lattice whose springs carry Maxwell arms.

    An arm (spring ``k2`` in series with a dashpot ``gamma2``, one internal length per
    spring) maps, by the affine argument of :func:`lattice_lame` applied to the arm's
    elastic and viscous parts, to ``(arm_lam, arm_mu, arm_viscous_lam, arm_viscous_mu)
    = sqrt(3)/4 (k2, k2, gamma2, gamma2)``: the three spring directions of a triangle fix
    one internal strain tensor. The arm relaxation time ``gamma2 / k2`` is kept.
    """
    k2, g2 = float(arm_stiffness), float(arm_dashpot)
    if not (math.isfinite(k2) and k2 > 0):
        raise ValueError(f"arm_stiffness must be finite and > 0, got {arm_stiffness}")
    if not (math.isfinite(g2) and g2 > 0):
        raise ValueError(f"arm_dashpot must be finite and > 0, got {arm_dashpot}")
    lam = lattice_lame(k2)
    return (lam.lam, lam.mu, *lattice_viscous_lame(g2))


def lattice_area_per_node(spacing: float) -> float:
    """Area per node of a triangular lattice, ``sqrt(3)/2 a**2``."""
    a = float(spacing)
    if not (math.isfinite(a) and a > 0):
        raise ValueError(f"spacing must be finite and > 0, got {a}")
    return SQRT3 / 2 * a * a


def node_drag_to_continuum(
    drag: float, *, area_per_node: float, mass: float = 1.0
) -> tuple[float, float]:
    """Density and substrate drag of the continuum equivalent of node masses with drag.

    A node of mass ``m`` feeling the drag force ``-c v`` (Eq. 10) smeared over its area
    ``A`` gives ``rho = m / A`` and the drag coefficient ``eta = c / A`` (force time per
    length**3 in 2D). In the finite-element equations the damping matrix is then
    ``eta M_1`` with ``M_1`` the unit-density mass matrix: mass-proportional damping with
    ratio ``eta / rho = c / m``.

    Returns
    -------
    (rho, eta) : tuple of float
    """
    c, m, A = float(drag), float(mass), float(area_per_node)
    if not (math.isfinite(c) and c >= 0):
        raise ValueError(f"drag must be finite and >= 0, got {c}")
    if not (math.isfinite(m) and m >= 0):
        raise ValueError(f"mass must be finite and >= 0, got {m}")
    if not (math.isfinite(A) and A > 0):
        raise ValueError(f"area_per_node must be finite and > 0, got {A}")
    return m / A, c / A


def voigt_isotropic(C: ArrayLike) -> Material:
    """Isotropic part of a 2D elastic tensor in Voigt form ``(xx, yy, 2xy)``.

    Bulk ``lam + mu = (C11 + C22 + 2 C12) / 4`` and shear ``mu`` the mean of
    ``(C11 + C22 - 2 C12) / 4`` and ``C33``; exact when ``C`` is isotropic.
    """
    C = np.asarray(C, dtype=float)
    if C.shape != (3, 3):
        raise ValueError(f"C must have shape (3, 3), got {C.shape}")
    bulk = (C[0, 0] + C[1, 1] + 2 * C[0, 1]) / 4
    mu = 0.5 * ((C[0, 0] + C[1, 1] - 2 * C[0, 1]) / 4 + C[2, 2])
    return Material(bulk - mu, mu)


@dataclass(frozen=True, eq=False)
class NetworkModuli:
    """Homogenised elasticity of a network.

    Attributes
    ----------
    C : (3, 3) float array
        Elastic tensor in Voigt form: energy density ``W = e.C.e / 2`` with
        ``e = (eps_xx, eps_yy, 2 eps_xy)`` (force per length).
    material : Material
        Its isotropic part (:func:`voigt_isotropic`).
    area : float
        Area of the network's body (sum of its triangular faces).
    relaxed : bool
        Whether interior nodes were relaxed (non-affine) or moved affinely.
    """

    C: NDArray[np.float64]
    material: Material
    area: float
    relaxed: bool


def _face_weights(net: SpringNetwork, faces: NDArray) -> NDArray:
    """Springs on two faces count fully, springs on one face (the outline) half."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    pairs = np.sort(net.springs, axis=1)
    n = net.n_nodes
    key_u = uniq[:, 0] * n + uniq[:, 1]
    key_s = pairs[:, 0] * n + pairs[:, 1]
    pos = np.searchsorted(key_u, key_s)
    pos = np.minimum(pos, key_u.size - 1)
    found = key_u[pos] == key_s
    w = np.ones(net.n_springs)
    w[found & (counts[pos] == 1)] = 0.5
    return w


def network_moduli(
    net: SpringNetwork,
    *,
    positions: ArrayLike | None = None,
    relaxed: bool = True,
    force_tol: float = 1e-8,
) -> NetworkModuli:
    """Homogenised elastic tensor of a network by (relaxed) affine deformation.

    The outline nodes (nodes on springs that border a single triangular face) follow a
    uniform strain ``eps`` exactly; interior nodes follow it too (``relaxed=False``,
    the affine estimate) or relax to mechanical equilibrium (``relaxed=True``, linear
    response with the network's Hessian at ``positions``). The energy density is the
    second-order energy divided by the body's area, with outline springs counted half
    (they are shared with the material outside); for a uniform triangular lattice every
    face then carries the same energy and the result is the bulk value exactly.

    Parameters
    ----------
    net : SpringNetwork
        A network whose springs form triangular faces (see
        :func:`~.mesh.network_faces`); pre-stress (``r != L``) is allowed.
    positions : (n_nodes, 2) float array, optional
        Reference positions (default ``net.positions``); with ``relaxed=True`` they must be
        an equilibrium of the interior nodes.
    relaxed : bool
    force_tol : float
        Largest interior net force allowed at ``positions``, relative to ``net.force_scale``.

    Returns
    -------
    NetworkModuli
    """
    from ..network.energy import hessian
    from .mesh import network_faces

    x = net.positions if positions is None else np.asarray(positions, dtype=float)
    if x.shape != (net.n_nodes, 2):
        raise ValueError(f"positions must have shape ({net.n_nodes}, 2), got {x.shape}")
    faces = network_faces(net, x)
    d1 = x[faces[:, 1]] - x[faces[:, 0]]
    d2 = x[faces[:, 2]] - x[faces[:, 0]]
    area = float(np.sum(0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])))
    w = _face_weights(net, faces)
    outline = np.zeros(net.n_nodes, dtype=bool)
    outline[net.springs[w < 1].ravel()] = True

    H_w = hessian(x, net.with_stiffness(net.stiffness * w)).tocsr()
    strains = np.array(
        [[[1, 0], [0, 0]], [[0, 0], [0, 1]], [[0, 0.5], [0.5, 0]]], dtype=float
    )  # unit Voigt components (eps_xx, eps_yy, gamma_xy)
    U = np.stack([(x @ e.T).ravel() for e in strains], axis=1)  # (2n, 3), affine
    if relaxed:
        from ..network.energy import gradient

        interior = np.repeat(~outline, 2)
        g = gradient(x, net).ravel()[interior]
        if g.size and np.max(np.abs(g)) > force_tol * net.force_scale:
            raise ValueError(
                f"positions are not an equilibrium of the interior nodes (largest force "
                f"{np.max(np.abs(g)):.3e} > {force_tol} * force_scale); relax the network first"
            )
        if interior.any():
            H = hessian(x, net).tocsr()
            ii = np.flatnonzero(interior)
            bb = np.flatnonzero(~interior)
            H_ii = H[ii][:, ii].tocsc()
            H_ib = H[ii][:, bb]
            try:
                # partial pivoting: with pre-stress H_ii need not be positive definite
                lu = sparse_lu(H_ii, symmetric=False)
            except RuntimeError as err:
                raise ValueError(
                    "the interior of the network is floppy (singular Hessian); its relaxed "
                    "moduli are not defined"
                ) from err
            U = U.copy()
            U[ii] = -lu.solve(np.asarray(H_ib @ U[bb]))
    C = (U.T @ (H_w @ U)) / area
    C = 0.5 * (C + C.T)
    return NetworkModuli(C=C, material=voigt_isotropic(C), area=area, relaxed=bool(relaxed))
