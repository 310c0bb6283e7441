"""Allosteric strain transmission: sources in a continuum and in a network, strain vs distance.

Two sources:

- the continuum counterpart of a clamped source spring: two small rigid patches around the
  spring's end points, moved apart along the spring to its clamped length
  (:func:`patch_source`, and :func:`network_patch_source` for the same source in a network);
- a dilating circular inclusion (eigenstrain), with its closed-form (Eshelby) solution, in
  :mod:`.inclusion`.

The read-out is the strain of every spring of a network against its distance from the
source (:func:`network_transmission`, :func:`continuum_transmission`, where the continuum's
"spring strain" is the chord strain between the spring's end points), binned by
:func:`strain_profile` and fitted by a power law in :func:`decay_exponent`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..fits import power_law
from ..network.model import SpringNetwork
from .materials import Material

__all__ = [
    "DecayFit",
    "StrainProfile",
    "Transmission",
    "continuum_transmission",
    "decay_exponent",
    "network_dirichlet",
    "network_patch_source",
    "network_transmission",
    "patch_source",
    "strain_profile",
]


# -- patch sources -----------------------------------------------------------------------
def _source_geometry(
    centre_a: ArrayLike, centre_b: ArrayLike, radius: float
) -> tuple[NDArray, NDArray, NDArray, float]:
    a = np.asarray(centre_a, dtype=float)
    b = np.asarray(centre_b, dtype=float)
    if a.shape != (2,) or b.shape != (2,):
        raise ValueError("centre_a and centre_b must be points (x, y)")
    d = b - a
    dist = float(np.hypot(*d))
    if dist == 0:
        raise ValueError("centre_a and centre_b coincide")
    radius = float(radius)
    if not (0 < radius < dist / 2):
        raise ValueError(
            f"radius must lie in (0, {dist / 2:g}) so that the two patches do not overlap"
        )
    return a, b, d / dist, radius


def patch_source(
    body: object,
    centre_a: ArrayLike,
    centre_b: ArrayLike,
    *,
    radius: float,
    opening: float,
) -> object:
    """Two rigid patches moved apart: the continuum counterpart of a clamped spring.

    Every DOF within ``radius`` of ``centre_a`` is displaced by ``-opening/2 n`` and every
    DOF within ``radius`` of ``centre_b`` by ``+opening/2 n``, with ``n`` the unit vector
    from a to b; the distance between the patches grows by ``opening`` (clamped length
    minus rest length). The patches also stop rigid motion.

    Returns
    -------
    Dirichlet
    """
    from .static import Dirichlet, fix

    a, b, n, radius = _source_geometry(centre_a, centre_b, radius)
    half = 0.5 * float(opening)
    parts = []
    for c, sign in ((a, -1.0), (b, 1.0)):
        parts.append(
            fix(
                body,
                lambda x, y, c=c: np.hypot(x - c[0], y - c[1]) <= radius,
                displacement=(sign * half * n[0], sign * half * n[1]),
            )
        )
    return Dirichlet(
        np.concatenate([p.dofs for p in parts]), np.concatenate([p.values for p in parts])
    )


def network_patch_source(
    net: SpringNetwork,
    centre_a: ArrayLike,
    centre_b: ArrayLike,
    *,
    radius: float,
    opening: float,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """The same two-patch source in a network: pinned nodes at displaced positions.

    Returns
    -------
    pinned : (n_nodes, 2) bool array
        Nodes within ``radius`` of either centre (both coordinates).
    x0 : (n_nodes, 2) float array
        Start positions with the patch nodes moved by ``-+opening/2 n``; pass both to
        ``cvn.relax(net, pinned=pinned, x0=x0)``.
    """
    a, b, n, radius = _source_geometry(centre_a, centre_b, radius)
    x0 = np.array(net.positions, dtype=float, copy=True)
    pinned = np.zeros((net.n_nodes, 2), dtype=bool)
    for c, sign in ((a, -1.0), (b, 1.0)):
        near = np.hypot(*(x0 - c).T) <= radius
        if not near.any():
            raise ValueError(f"no node lies within radius={radius} of {c.tolist()}")
        pinned[near] = True
        x0[near] += sign * 0.5 * float(opening) * n
    return pinned, x0


def network_dirichlet(
    body: object,
    net: SpringNetwork,
    nodes: ArrayLike,
    displacement: ArrayLike,
    *,
    tol: float = 1e-9,
) -> object:
    """The continuum counterpart of prescribed network nodes, on the network's own outline.

    Every DOF of ``body`` (a mesh of :func:`~.mesh.network_mesh`) inside a face whose
    three nodes are prescribed, on a spring whose two nodes are, or at a prescribed node,
    gets the displacement interpolated linearly from the nodes'. The region held rigid is
    then exactly the network's (a rigid patch made of whole lattice triangles), which
    removes the patch-shape mismatch of :func:`patch_source`.

    Parameters
    ----------
    body : ElasticBody
    net : SpringNetwork
    nodes : (m,) int array
    displacement : (m, 2) float array
        Displacement of each prescribed node (length units).
    tol : float
        Relative tolerance of the inside / on-segment tests.

    Returns
    -------
    Dirichlet
    """
    from .mesh import network_faces
    from .static import Dirichlet

    x = net.positions
    nodes = np.asarray(nodes, dtype=np.int64).ravel()
    disp = np.asarray(displacement, dtype=float)
    if disp.shape != (nodes.size, 2):
        raise ValueError(f"displacement must have shape ({nodes.size}, 2), got {disp.shape}")
    if nodes.size == 0:
        raise ValueError("nodes is empty: nothing would be prescribed")
    if nodes.min() < 0 or nodes.max() >= net.n_nodes:
        raise ValueError(f"nodes must lie in 0..{net.n_nodes - 1}")
    held = np.zeros(net.n_nodes, dtype=bool)
    held[nodes] = True
    node_disp = np.zeros((net.n_nodes, 2))
    node_disp[nodes] = disp
    loc = body.dof_locations
    comp = body.dof_component
    value = np.full(body.n_dofs, np.nan)
    scale = float(np.mean(net.lengths()))

    def put(where: NDArray, u: NDArray) -> None:
        value[where] = np.where(comp[where] == 0, u[:, 0], u[:, 1])

    faces = network_faces(net)
    for f in faces[held[faces].all(axis=1)]:
        a = x[f[0]]
        T = np.column_stack([x[f[1]] - a, x[f[2]] - a])
        bary = np.linalg.solve(T, (loc - a).T)
        w = np.vstack([1 - bary.sum(axis=0), bary])
        inside = np.flatnonzero(w.min(axis=0) >= -tol)
        put(inside, w[:, inside].T @ node_disp[f])
    for i, j in net.springs[held[net.springs].all(axis=1)]:
        d = x[j] - x[i]
        t = np.clip((loc - x[i]) @ d / (d @ d), 0.0, 1.0)
        on = np.flatnonzero(np.hypot(*(loc - x[i] - t[:, None] * d).T) <= tol * scale)
        put(on, (1 - t[on])[:, None] * node_disp[i] + t[on][:, None] * node_disp[j])
    for i in nodes:
        at = np.flatnonzero(np.hypot(*(loc - x[i]).T) <= tol * scale)
        put(at, np.repeat(node_disp[i][None, :], at.size, axis=0))
    dofs = np.flatnonzero(~np.isnan(value))
    if dofs.size == 0:
        raise ValueError("no DOF of body lies at the prescribed nodes; is body a network_mesh?")
    return Dirichlet(dofs, value[dofs])


# -- transmission from a clamped source spring --------------------------------------------
@dataclass(frozen=True, eq=False)
class Transmission:
    """Strain of every spring but the source, against distance from the source.

    Attributes
    ----------
    springs : (m,) int array
        Spring indices (the source spring excluded).
    distance : (m,) float array
        Distance from the source spring's midpoint to each spring's midpoint.
    strain : (m,) float array
        Spring strain (network: ``r/L - 1``; continuum: chord strain of the same segment).
    seconds : float
        Wall-clock time of the solve.
    """

    springs: NDArray[np.int64]
    distance: NDArray[np.float64]
    strain: NDArray[np.float64]
    seconds: float


def _source_spring(net: SpringNetwork, source: int) -> tuple[NDArray, NDArray]:
    if not (0 <= int(source) < net.n_springs):
        raise ValueError(f"source must be a spring index in 0..{net.n_springs - 1}, got {source}")
    others = np.flatnonzero(np.arange(net.n_springs) != int(source))
    x = net.positions
    mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
    dist = np.hypot(*(mid[others] - mid[int(source)]).T)
    return others, dist


def network_transmission(
    net: SpringNetwork, source: int, strain: float, *, tol: float = 1e-10
) -> Transmission:
    """Clamp spring ``source`` at ``strain`` (Eq. 25), relax, read every other spring's strain.

    Uses ``cvn.relax`` (exact clamp, default far pins).
    """
    from ..network.equilibrium import relax

    others, dist = _source_spring(net, source)
    length = float(net.clamp_length(int(source), strain))
    t0 = time.perf_counter()
    eq = relax(net, clamped={int(source): length}, tol=tol)
    seconds = time.perf_counter() - t0
    return Transmission(others, dist, net.strains(eq.positions)[others], seconds)


def continuum_transmission(
    net: SpringNetwork,
    source: int,
    strain: float,
    *,
    material: Material | None = None,
    refine: int = 1,
    order: int = 2,
    patch_radius: float | None = None,
) -> Transmission:
    """The continuum of the network's shape with a two-patch source at the source spring.

    The body is the network's outline (:func:`~.mesh.network_mesh`, ``refine`` times
    refined) with ``material`` (default: the network's relaxed homogenised moduli,
    :func:`~.materials.network_moduli`). Patches of radius ``patch_radius`` (default
    0.3 times the source spring's length) around the source's end nodes are moved apart
    by ``L (1 + strain) - r`` so that the source reaches its clamped length; the linear
    solution is read as the chord strain of every other spring.

    A rigid patch is a finite-size object: the far field has the shape of the lattice's
    (a force dipole) but its amplitude grows as the patch shrinks (logarithmically in
    2D). With the default radius and ``refine=1`` the far-field amplitude was 0.9 times the
    triangular lattice's in the tests.
    """
    from .body import elastic_body
    from .materials import network_moduli
    from .mesh import network_mesh
    from .probes import chord_strain_probe
    from .static import solve_static

    others, dist = _source_spring(net, source)
    x = net.positions
    i, j = net.springs[int(source)]
    r0 = float(np.hypot(*(x[j] - x[i])))
    opening = float(net.clamp_length(int(source), strain)) - r0
    radius = 0.3 * r0 if patch_radius is None else float(patch_radius)
    t0 = time.perf_counter()
    mat = network_moduli(net).material if material is None else material
    body = elastic_body(network_mesh(net, refine=refine), mat, order=order)
    fixed = patch_source(body, x[i], x[j], radius=radius, opening=opening)
    sol = solve_static(body, fixed)
    s = net.springs[others]
    probe = chord_strain_probe(body, x[s[:, 0]], x[s[:, 1]])
    seconds = time.perf_counter() - t0
    return Transmission(others, dist, probe(sol.u), seconds)


# -- strain against distance --------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class StrainProfile:
    """Mean absolute strain in distance bins.

    Attributes
    ----------
    r : (n_bins,) float array
        Mean distance of the samples in each non-empty bin.
    strain : (n_bins,) float array
        Mean ``|strain|`` in each bin.
    count : (n_bins,) int array
    """

    r: NDArray[np.float64]
    strain: NDArray[np.float64]
    count: NDArray[np.int64]


def strain_profile(distance: ArrayLike, strain: ArrayLike, *, bins: ArrayLike) -> StrainProfile:
    """Bin ``|strain|`` by ``distance`` (bin edges ``bins``); empty bins are dropped."""
    d = np.asarray(distance, dtype=float).ravel()
    s = np.abs(np.asarray(strain, dtype=float).ravel())
    if d.shape != s.shape:
        raise ValueError(f"distance and strain must have the same size, got {d.size}, {s.size}")
    edges = np.asarray(bins, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise ValueError("bins must be an increasing 1D array of at least two edges")
    idx = np.digitize(d, edges) - 1
    ok = (idx >= 0) & (idx < edges.size - 1)
    count = np.bincount(idx[ok], minlength=edges.size - 1)
    r_sum = np.bincount(idx[ok], weights=d[ok], minlength=edges.size - 1)
    s_sum = np.bincount(idx[ok], weights=s[ok], minlength=edges.size - 1)
    keep = count > 0
    return StrainProfile(r_sum[keep] / count[keep], s_sum[keep] / count[keep], count[keep])


@dataclass(frozen=True)
class DecayFit:
    """Power law ``|strain| = prefactor * r**(-exponent)`` fitted on ``[r_min, r_max]``.

    Attributes
    ----------
    exponent, prefactor : float
    r_min, r_max : float
    n_bins : int
        Bins used in the fit.
    rms_log_residual : float
        Root-mean-square residual of ``log |strain|`` about the fit.
    exponent_error : float
        Standard error of the exponent (least squares on the bins' logarithms).
    """

    exponent: float
    prefactor: float
    r_min: float
    r_max: float
    n_bins: int
    rms_log_residual: float
    exponent_error: float


def decay_exponent(
    distance: ArrayLike,
    strain: ArrayLike,
    *,
    r_min: float,
    r_max: float,
    n_bins: int = 12,
) -> DecayFit:
    """Fit ``|strain| ~ r**(-exponent)`` to strains binned in ``n_bins`` log-spaced bins.

    A far-field source of zero net force and torque (a force dipole, a dilating inclusion)
    gives strain decaying as ``r**-2`` in an infinite 2D elastic body.
    """
    if not (0 < r_min < r_max):
        raise ValueError(f"need 0 < r_min < r_max, got {r_min}, {r_max}")
    prof = strain_profile(distance, strain, bins=np.geomspace(r_min, r_max, int(n_bins) + 1))
    good = prof.strain > 0
    if good.sum() < 3:
        raise ValueError("fewer than 3 non-empty bins with non-zero strain in [r_min, r_max]")
    fit = power_law(prof.r[good], prof.strain[good])
    return DecayFit(
        exponent=-fit.exponent,
        prefactor=fit.prefactor,
        r_min=float(r_min),
        r_max=float(r_max),
        n_bins=fit.points,
        rms_log_residual=fit.rms_log_residual,
        exponent_error=fit.exponent_error,
    )
