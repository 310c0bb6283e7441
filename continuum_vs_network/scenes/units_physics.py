"""Units of transmission and relaxation scenes: one unit per lattice size.

Transmission (``transmission/n<n>``): the spring nearest the centre of an ``n x n``
triangular lattice is clamped at ``[task] strain``; every other spring's strain is read
against its distance from the source, in the network
(:func:`~continuum_vs_network.continuum.transmission.network_transmission`) and, with
``[continuum]``, in the finite-element body of the same shape with a two-patch source
(:func:`~continuum_vs_network.continuum.transmission.continuum_transmission`); power laws
are fitted to both.

Relaxation (``relaxation/n<n>``): the left side of the lattice is held, the right side is
stepped inwards by ``[dynamics] step`` of the width, and the damped network relaxes
(:func:`~continuum_vs_network.network.dynamics.simulate`); with ``[continuum]`` the
visco-elastic body of the same shape, with the continuum equivalent of the node drag
(:func:`~continuum_vs_network.continuum.materials.node_drag_to_continuum`), relaxes too
(:func:`~continuum_vs_network.continuum.viscoelastic.simulate_body`). Both record the
slowest-mode time and the time to relax to ``[dynamics] fraction``.

scikit-fem is imported only by the continuum parts, i.e. only with ``[continuum]``.
Fields for meshes and images are computed only with ``[export]`` or ``[report] images``,
and only for the largest size.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .results.physics import RelaxationResult, TransmissionResult
from .schema import Scene
from .units import Unit, UnitContext

__all__ = ["centre_spring", "lattice", "plan_physics", "principal_strain"]

_LEFT = 0.6  # nodes within 0.6 spacings of the left (right) edge form the held side


def plan_physics(scene: Scene) -> list[Unit]:
    """One unit per size."""
    d = scene.to_dict()
    depends = {
        k: d[k] for k in ("seed", "network", "task", "continuum", "solver", "dynamics") if k in d
    }
    sizes = scene.network.sizes
    wants_fields = scene.export is not None or scene.report.images
    func = transmission_unit if scene.kind == "transmission" else relaxation_unit
    return [
        Unit(
            key=f"{scene.kind}/n{n}",
            func=func,
            params={"n": int(n), "fields": bool(wants_fields and n == sizes[-1])},
            depends=depends,
        )
        for n in sizes
    ]


def lattice(scene: Scene, n: int, *, default_noise: float = 0.0):
    """The scene's ``n x n`` triangular lattice (spacing 1, k = 1, stress-free).

    Position noise ``[network] noise`` (``default_noise`` when absent) is drawn from a
    generator seeded with ``(scene.seed, n)``.
    """
    from ..network.builders import triangular_lattice

    noise = default_noise if scene.network.noise is None else scene.network.noise
    rng = np.random.default_rng([scene.seed, n])
    return triangular_lattice(n, n, noise=noise, rng=rng if noise > 0 else None)


def centre_spring(net) -> int:
    """The spring whose midpoint is nearest the centroid of the nodes."""
    x = net.positions
    mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
    return int(np.argmin(np.hypot(*(mid - x.mean(axis=0)).T)))


def principal_strain(eps: np.ndarray) -> np.ndarray:
    """Signed principal strain of largest magnitude of ``(n, 2, 2)`` tensors, (n,)."""
    m = 0.5 * (eps[:, 0, 0] + eps[:, 1, 1])
    r = np.hypot(0.5 * (eps[:, 0, 0] - eps[:, 1, 1]), eps[:, 0, 1])
    return np.where(np.abs(m + r) >= np.abs(m - r), m + r, m - r)


def _tensors(e: np.ndarray) -> np.ndarray:
    """``(n, 3)`` rows ``(xx, yy, xy)`` -> ``(n, 2, 2)`` symmetric tensors."""
    out = np.empty((e.shape[0], 2, 2))
    out[:, 0, 0], out[:, 1, 1] = e[:, 0], e[:, 1]
    out[:, 0, 1] = out[:, 1, 0] = e[:, 2]
    return out


def _material(scene: Scene, net):
    from ..continuum.materials import lattice_lame, network_moduli

    if scene.continuum.material == "lattice":
        return lattice_lame(float(np.mean(net.stiffness)))
    return network_moduli(net).material


def _fit(distance, strain, n: int) -> tuple[float, float, float, float, float]:
    """Power-law decay (exponent, prefactor, r_min, r_max, exponent's standard error)
    between 2 spacings and 0.3 n."""
    from ..continuum.transmission import decay_exponent

    r_min, r_max = 2.0, 0.3 * n
    if r_max < 2 * r_min:
        return (math.nan,) * 5
    try:
        fit = decay_exponent(distance, strain, r_min=r_min, r_max=r_max, n_bins=8)
    except ValueError:
        return (math.nan,) * 5
    return fit.exponent, fit.prefactor, fit.r_min, fit.r_max, fit.exponent_error


def transmission_unit(scene: Scene, params: dict, ctx: UnitContext) -> TransmissionResult:
    """Strain against distance in the network and (with ``[continuum]``) the continuum."""
    from ..continuum.transmission import network_transmission

    n = params["n"]
    net = lattice(scene, n)
    src = centre_spring(net)
    strain = scene.task.strain
    tol = scene.solver.tol if scene.solver is not None else 1e-10
    a = network_transmission(net, src, strain, tol=tol)
    fit = _fit(a.distance, a.strain, n)
    continuum: dict[str, Any] = {}
    if scene.continuum is not None:
        from ..continuum.transmission import continuum_transmission

        c = scene.continuum
        length = float(net.lengths(None, src))
        b = continuum_transmission(
            net,
            src,
            strain,
            material=_material(scene, net),
            refine=c.refine,
            order=c.order,
            patch_radius=c.patch_radius * length,
        )
        cfit = _fit(b.distance, b.strain, n)
        continuum = {
            "continuum_strain": b.strain,
            "continuum_seconds": b.seconds,
            "continuum_exponent": cfit[0],
            "continuum_exponent_error": cfit[4],
            "continuum_prefactor": cfit[1],
            "correlation": float(np.corrcoef(a.strain, b.strain)[0, 1]),
        }
    return TransmissionResult(
        n=n,
        n_nodes=net.n_nodes,
        n_springs=net.n_springs,
        source=src,
        strain=strain,
        springs=a.springs,
        distance=a.distance,
        network_strain=a.strain,
        network_seconds=a.seconds,
        network_exponent=fit[0],
        network_exponent_error=fit[4],
        network_prefactor=fit[1],
        fit_r_min=fit[2],
        fit_r_max=fit[3],
        fields=_transmission_fields(scene, net, src, strain, tol) if params["fields"] else {},
        **continuum,
    )


def _transmission_fields(scene: Scene, net, src: int, strain: float, tol: float) -> dict:
    from ..network.equilibrium import relax

    eq = relax(net, clamped={src: float(net.clamp_length(src, strain))}, tol=tol)
    out = {
        "net/positions": net.positions,
        "net/springs": net.springs,
        "net/stiffness": net.stiffness,
        "net/rest_length": net.rest_length,
        "net/x": eq.positions,
        "net/sources": np.array([src]),
    }
    if scene.continuum is not None:
        from ..continuum.body import elastic_body
        from ..continuum.mesh import network_mesh
        from ..continuum.static import solve_static
        from ..continuum.transmission import patch_source

        c = scene.continuum
        x = net.positions
        i, j = net.springs[src]
        r0 = float(np.hypot(*(x[j] - x[i])))
        mat = _material(scene, net)
        body = elastic_body(network_mesh(net, refine=c.refine), mat, order=c.order)
        fixed = patch_source(
            body,
            x[i],
            x[j],
            radius=c.patch_radius * r0,
            opening=float(net.clamp_length(src, strain)) - r0,
        )
        sol = solve_static(body, fixed)
        out.update(_continuum_fields(body, sol.u, mat))
    return out


def _continuum_fields(body, u, mat) -> dict:
    from ..continuum.body import vertex_displacement
    from ..continuum.probes import strain_probe

    eps = _tensors(strain_probe(body, body.centroids)(u))
    tr = eps[:, 0, 0] + eps[:, 1, 1]
    sigma = 2 * mat.mu * eps
    sigma[:, 0, 0] += mat.lam * tr
    sigma[:, 1, 1] += mat.lam * tr
    return {
        "cont/points": body.mesh.p.T,
        "cont/triangles": body.mesh.t.T.astype(np.int64),
        "cont/displacement": vertex_displacement(body, u),
        "cont/strain": eps,
        "cont/stress": sigma,
        "cont/principal": principal_strain(eps),
    }


# -- relaxation ----------------------------------------------------------------------------
def _sides(net) -> tuple[np.ndarray, np.ndarray]:
    x = net.positions[:, 0]
    return np.flatnonzero(x < x.min() + _LEFT), np.flatnonzero(x > x.max() - _LEFT)


def _decay_rate(lam_min: float, damping: float, inertia: bool) -> float:
    """Slowest decay rate of ``m x'' + c x' + lam x = 0`` (m = 1) or ``c x' + lam x = 0``."""
    if not inertia:
        return lam_min / damping
    disc = damping**2 - 4 * lam_min
    return 0.5 * (damping - math.sqrt(disc)) if disc > 0 else 0.5 * damping


def _smallest_eigenvalue(K, M=None) -> float:
    import scipy.sparse.linalg as spla

    from ..linalg.spd import fixed_vector

    vals = spla.eigsh(
        K.tocsc(),
        k=1,
        M=None if M is None else M.tocsc(),
        sigma=0.0,
        which="LM",
        return_eigenvectors=False,
        v0=fixed_vector(K.shape[0]),
    )
    return float(vals[0])


def relaxation_unit(scene: Scene, params: dict, ctx: UnitContext) -> RelaxationResult:
    """Relaxation time of the network (and the continuum) after a step of one side."""
    from ..continuum.viscoelastic import relaxation_time
    from ..network.dynamics import simulate
    from ..network.energy import hessian

    dyn = scene.dynamics
    n = params["n"]
    net = lattice(scene, n)
    x = net.positions
    left, right = _sides(net)
    shift = dyn.step * float(np.ptp(x[:, 0]))
    prescribed = {int(i): x[i] - [shift, 0.0] for i in right}
    held = np.zeros(net.n_nodes, bool)
    held[left] = held[right] = True
    free = np.repeat(~held, 2)
    H = hessian(x, net).tocsr()[free][:, free]
    lam_net = _smallest_eigenvalue(H)
    tau = 1.0 / _decay_rate(lam_net, dyn.damping, dyn.inertia)
    dt, t_end = tau / dyn.steps_per_tau, dyn.duration * tau
    t0 = time.perf_counter()
    tr = simulate(
        net,
        dt=dt,
        t_end=t_end,
        pinned=left,
        prescribed=prescribed,
        damping=dyn.damping,
        inertia=dyn.inertia,
        scheme=dyn.scheme,
        jacobian="frozen",
    )
    net_seconds = time.perf_counter() - t0
    T = tr.times.size
    disp = tr.positions - x
    fields: dict[str, np.ndarray] = {}
    if params["fields"]:
        idx = np.unique(np.linspace(0, T - 1, dyn.frames).round().astype(int))
        fields.update(
            {
                "net/positions": x,
                "net/springs": net.springs,
                "net/stiffness": net.stiffness,
                "net/rest_length": net.rest_length,
                "net/x": tr.positions[-1],
                "net/series_times": tr.times[idx],
                "net/series_x": tr.positions[idx],
            }
        )
    continuum: dict[str, Any] = {}
    if scene.continuum is not None:
        continuum, continuum_fields = _relax_continuum(
            scene, net, left, right, shift, dt, t_end, fields=params["fields"]
        )
        fields.update(continuum_fields)
    return RelaxationResult(
        n=n,
        n_nodes=net.n_nodes,
        dt=dt,
        t_end=t_end,
        network_times=tr.times,
        network_deviation=np.max(np.abs(disp - disp[-1]).reshape(T, -1), axis=1),
        network_tau_mode=tau,
        network_tau=relaxation_time(tr.times, disp.reshape(T, -1), fraction=dyn.fraction),
        network_seconds=net_seconds,
        network_factorisations=tr.factorisations,
        fields=fields,
        **continuum,
    )


def _relax_continuum(
    scene: Scene, net, left, right, shift, dt, t_end, *, fields: bool
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The continuum's part of a :class:`RelaxationResult` (its ``continuum_*`` values)
    and, with ``fields``, its fields for mesh export."""
    from ..continuum.body import elastic_body, near_segments, stiffness_matrix
    from ..continuum.materials import lattice_area_per_node, node_drag_to_continuum
    from ..continuum.mesh import network_mesh
    from ..continuum.probes import displacement_probe
    from ..continuum.static import fix
    from ..continuum.viscoelastic import (
        Damping,
        damping_matrix,
        relaxation_time,
        simulate_body,
        slowest_relaxation_time,
    )

    dyn, c = scene.dynamics, scene.continuum
    x = net.positions
    mat = _material(scene, net)
    body = elastic_body(network_mesh(net, refine=c.refine), mat, order=c.order)

    def side(nodes):
        inside = np.isin(net.springs, nodes).all(axis=1)
        s = net.springs[inside]
        return near_segments(x[s[:, 0]], x[s[:, 1]], tol=1e-6)

    fixed = fix(body, side(left)) + fix(body, side(right), displacement=(-shift, 0.0))
    rho, eta = node_drag_to_continuum(dyn.damping, area_per_node=lattice_area_per_node(1.0))
    damping = Damping(drag=eta)
    density = rho if dyn.inertia else 0.0
    scheme = "newmark" if dyn.scheme == "newmark" else "backward_euler"
    probe = displacement_probe(body, x)
    t0 = time.perf_counter()
    traj = simulate_body(
        body,
        fixed=fixed,
        dt=dt,
        t_end=t_end,
        scheme=scheme,
        damping=damping,
        density=density,
        observe=probe,
    )
    seconds = time.perf_counter() - t0
    T = traj.times.size
    obs = traj.observed.reshape(T, -1)
    K = stiffness_matrix(body)
    freedofs = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    Kf = K[freedofs][:, freedofs]
    if dyn.inertia:
        from ..continuum.body import mass_matrix

        M = mass_matrix(body, density)[freedofs][:, freedofs]
        # rho s^2 + eta s + lam = 0 with eta / rho = c / m = damping (unit node masses)
        tau_mode = 1.0 / _decay_rate(_smallest_eigenvalue(Kf, M), dyn.damping, True)
    else:
        C = damping_matrix(body, damping, density=0.0, K=K)[freedofs][:, freedofs]
        tau_mode = slowest_relaxation_time(Kf, C)
    values = {
        "continuum_times": traj.times,
        "continuum_deviation": np.max(np.abs(obs - obs[-1]), axis=1),
        "continuum_tau_mode": tau_mode,
        "continuum_tau": relaxation_time(traj.times, obs, fraction=dyn.fraction),
        "continuum_seconds": seconds,
        "continuum_dofs": body.n_dofs,
    }
    return values, _continuum_fields(body, traj.u, mat) if fields else {}
