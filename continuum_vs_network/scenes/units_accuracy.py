"""Units of accuracy scenes: every method's error against a reference, with its run time.

Finite elements (``accuracy/fe/<element>/h<h>``): Lamé's thick cylinder (inner radius 1,
outer radius 2, unit pressure inside, the outside clamped; plane strain, Young's modulus 1,
Poisson's ratio ``[accuracy] poisson``) on ring meshes of size ``h``; the relative L2 error
of the displacement against the closed form ``u_r = A r + B / r``, the DOFs and the
wall-clock seconds of the whole solve (mesh, basis, assembly, factorisation, solve).
Elements: ``P1``, ``P2`` (straight-sided triangles: the boundary is a polygon) and
``P2_curved`` (isoparametric quadratic triangles on the circles).

Network time integrators (``accuracy/network/<problem>/<scheme>/n<steps>``): an ``n x n``
triangular lattice (``[accuracy] size``; spacing 1, k = 1, unit masses) with its left side
held and its right side stepped inwards by 1 % of the width relaxes for one slowest-mode
time (``overdamped``: ``x' = -grad E``) or half a period of its slowest mode (``inertial``:
``x'' = -0.1 x' - grad E``) in ``steps`` equal steps of
:func:`~continuum_vs_network.network.dynamics.simulate`. The reference is the same
nonlinear equations integrated by SciPy's DOP853 at ``rtol = 1e-12`` (an independent
method); the error is the largest distance of any node from the reference at any step,
relative to the step displacement. An explicit step above the stability limit is refused
by ``simulate`` (recorded, with the limit).

Continuum time integrators (``accuracy/continuum/<problem>/<scheme>/n<steps>``): a P2
block (2 x 1, clamped on the left) starts in its lowest mode, so the exact solution is the
mode times ``exp(-t / tau)`` (overdamped, substrate drag) or ``cos(omega t)`` (inertial,
undamped); run for ``tau`` or 0.3 periods. The continuum has no explicit scheme.

All units are timed and run one at a time in the main process.
"""

from __future__ import annotations

import functools
import math
import time
import warnings
from typing import Any

import numpy as np

from .results.accuracy import FiniteElementResult, IntegratorResult
from .schema import Scene
from .timing import single_threaded
from .units import Unit, UnitContext

__all__ = ["lame_error", "plan_accuracy"]

#: Network scheme names of :func:`~continuum_vs_network.network.dynamics.simulate`.
NETWORK_SCHEME = {"backward_euler": "implicit", "newmark": "newmark", "explicit": "explicit"}
_STEP = 0.01  # step displacement of the right side / width
_INERTIAL_DAMPING = 0.1


def plan_accuracy(scene: Scene) -> list[Unit]:
    """FE units, then network and continuum integrator units (every one timed, serial)."""
    a = scene.accuracy
    depends = {"seed": scene.seed, "accuracy": scene.to_dict()["accuracy"]}
    units = []
    for element in a.elements:
        for h in a.mesh_sizes:
            units.append(
                Unit(
                    key=f"accuracy/fe/{element}/h{h:g}",
                    func=fe_unit,
                    params={"element": element, "h": float(h)},
                    depends=depends,
                    parallel=False,
                )
            )
    for medium in ("network", "continuum"):
        for problem in a.problems:
            for scheme in a.schemes:
                if medium == "continuum" and scheme == "explicit":
                    continue
                for n in a.steps:
                    units.append(
                        Unit(
                            key=f"accuracy/{medium}/{problem}/{scheme}/n{n}",
                            func=network_unit if medium == "network" else continuum_unit,
                            params={"problem": problem, "scheme": scheme, "steps": int(n)},
                            depends=depends,
                            parallel=False,
                        )
                    )
    return units


# -- finite elements ------------------------------------------------------------------------
def lame_error(element: str, h: float, poisson: float) -> dict[str, Any]:
    """Relative L2 displacement error of Lamé's cylinder, DOFs, seconds, locking warning.

    Parameters
    ----------
    element : {"P1", "P2", "P2_curved"}
    h : float
        Mesh size (length units; the radii are 1 and 2).
    poisson : float
        Poisson's ratio (plane strain, Young's modulus 1).
    """
    from ..continuum.body import LockingWarning, elastic_body, pressure_load
    from ..continuum.materials import Material
    from ..continuum.mesh import annulus_mesh
    from ..continuum.static import fix, solve_static

    mat = Material.from_young(1.0, poisson)
    a, b, p = 1.0, 2.0, 1.0
    lam, mu = mat.lam, mat.mu
    A = -p / (2 * (lam + mu) + 2 * mu * b**2 / a**2)
    B = -A * b**2
    order = 1 if element == "P1" else 2
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LockingWarning)
        mesh = annulus_mesh(a, b, h=h, curved=element == "P2_curved")
        body = elastic_body(mesh, mat, order=order)
    f = pressure_load(body, p, where=lambda x, y: np.hypot(x, y) < 1.5)
    fixed = fix(body, lambda x, y: np.hypot(x, y) > 1.5, boundary=True)
    sol = solve_static(body, fixed, load=f)
    seconds = time.perf_counter() - t0
    uh = np.asarray(body.basis.interpolate(sol.u))
    X = np.asarray(body.basis.global_coordinates())
    r = np.hypot(X[0], X[1])
    ur = A * r + B / r
    ux, uy = ur * X[0] / r, ur * X[1] / r
    dx = body.basis.dx
    err = math.sqrt(
        float(np.sum(((uh[0] - ux) ** 2 + (uh[1] - uy) ** 2) * dx))
        / float(np.sum((ux**2 + uy**2) * dx))
    )
    warned = any(issubclass(w.category, LockingWarning) for w in caught)
    return {"error": err, "dofs": int(body.n_dofs), "seconds": seconds, "warned": warned}


@single_threaded
def fe_unit(scene: Scene, params: dict, ctx: UnitContext) -> FiniteElementResult:
    """One element type at one mesh size on Lamé's cylinder."""
    lame_error("P2_curved", 0.5, 0.3)  # warm-up: imports and first calls are not timed
    out = lame_error(params["element"], params["h"], scene.accuracy.poisson)
    return FiniteElementResult(element=params["element"], h=params["h"], **out)


# -- network time integrators ---------------------------------------------------------------
@functools.cache
def _network_problem(size: int, problem: str) -> dict[str, Any]:
    """The lattice, its boundary conditions, run length and the DOP853 reference."""
    from scipy.integrate import solve_ivp

    from ..network.builders import triangular_lattice
    from ..network.energy import hessian, spring_gradient

    net = triangular_lattice(size, size)
    x = net.positions
    width = float(np.ptp(x[:, 0]))
    left = np.flatnonzero(x[:, 0] < x[:, 0].min() + 0.6)
    right = np.flatnonzero(x[:, 0] > x[:, 0].max() - 0.6)
    x0 = x.copy()
    x0[right, 0] -= _STEP * width
    prescribed = {int(i): tuple(x0[i]) for i in right}
    free = np.ones(net.n_nodes, dtype=bool)
    free[left] = free[right] = False
    fi = np.flatnonzero(free)
    # slowest mode of the linearised free coordinates (dense: the lattice is small)
    H = hessian(x0, net).toarray()
    dof = np.concatenate([2 * fi, 2 * fi + 1])
    dof.sort()
    lam_min = float(np.linalg.eigvalsh(H[np.ix_(dof, dof)])[0])
    inertial = problem == "inertial"
    c = _INERTIAL_DAMPING if inertial else 1.0
    t_end = math.pi / math.sqrt(lam_min) if inertial else c / lam_min

    def force(xf: np.ndarray) -> np.ndarray:
        xx = x0.copy()
        xx[fi] = xf.reshape(-1, 2)
        return -spring_gradient(xx, net.springs, net.stiffness, net.rest_length)[fi].ravel()

    m = 2 * fi.size
    if inertial:

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            return np.concatenate([y[m:], force(y[:m]) - c * y[m:]])

        y0 = np.concatenate([x0[fi].ravel(), np.zeros(m)])
    else:

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            return force(y) / c

        y0 = x0[fi].ravel()
    ref = solve_ivp(
        rhs, (0.0, 1.05 * t_end), y0, method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True
    )
    if not ref.success:  # pragma: no cover - a smooth small problem
        raise RuntimeError(f"reference integration failed: {ref.message}")
    return {
        "net": net,
        "x0": x0,
        "left": left,
        "prescribed": prescribed,
        "fi": fi,
        "m": m,
        "c": c,
        "inertial": inertial,
        "t_end": t_end,
        "ref": ref.sol,
        "scale": _STEP * width,
    }


@single_threaded
def network_unit(scene: Scene, params: dict, ctx: UnitContext) -> IntegratorResult:
    """One network scheme at one step count against the DOP853 reference."""
    from ..network.dynamics import simulate, stability_limit

    P = _network_problem(scene.accuracy.size, params["problem"])
    n = params["steps"]
    dt = P["t_end"] / n
    scheme = NETWORK_SCHEME[params["scheme"]]
    limit = float(stability_limit(P["net"], P["x0"], damping=P["c"], inertia=P["inertial"]))
    kw = dict(
        pinned=P["left"],
        prescribed=P["prescribed"],
        damping=P["c"],
        inertia=P["inertial"],
        tol=1e-10,
    )
    simulate(P["net"], dt=P["t_end"] / 4, t_end=P["t_end"] / 2, scheme="implicit", **kw)
    run = functools.partial(IntegratorResult, **params, dt=dt, dt_limit=limit, t_end=P["t_end"])
    try:
        tr = simulate(P["net"], dt=dt, t_end=P["t_end"], scheme=scheme, **kw)
    except (ValueError, RuntimeError) as err:
        return run(error=math.nan, seconds=math.nan, refused=f"{type(err).__name__}: {err}")
    ref = P["ref"](tr.times)[: P["m"]].T.reshape(len(tr.times), -1, 2)
    dev = np.linalg.norm(tr.positions[:, P["fi"]] - ref, axis=2)
    return run(error=float(dev.max() / P["scale"]), seconds=float(tr.seconds[-1]), refused="")


# -- continuum time integrators -------------------------------------------------------------
@functools.cache
def _continuum_problem(problem: str) -> dict[str, Any]:
    from scipy.sparse.linalg import eigsh

    from ..continuum.body import elastic_body, mass_matrix, stiffness_matrix
    from ..continuum.materials import Material
    from ..continuum.mesh import rectangle_mesh
    from ..continuum.static import fix
    from ..linalg.spd import fixed_vector

    body = elastic_body(rectangle_mesh(2.0, 1.0, h=0.125), Material(1.0, 1.0), order=2)
    fixed = fix(body, lambda x, y: x < 1e-9)
    K, M = stiffness_matrix(body), mass_matrix(body, 1.0)
    free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    K_free, M_free = K[free][:, free].tocsc(), M[free][:, free].tocsc()
    w2, phi = eigsh(K_free, k=1, M=M_free, sigma=0, v0=fixed_vector(free.size))
    w2 = float(w2[0])
    mode = np.zeros(body.n_dofs)
    mode[free] = phi[:, 0] / np.abs(phi[:, 0]).max()
    if problem == "inertial":
        t_end = 0.3 * 2 * math.pi / math.sqrt(w2)
        exact = math.cos(0.3 * 2 * math.pi)
    else:
        t_end = 1.0 / w2  # drag 1 on unit mass density: tau = 1 / omega^2
        exact = math.exp(-1.0)
    return {"body": body, "fixed": fixed, "mode": mode, "t_end": t_end, "exact": exact}


@single_threaded
def continuum_unit(scene: Scene, params: dict, ctx: UnitContext) -> IntegratorResult:
    """One continuum scheme at one step count against the lowest mode's closed form."""
    from ..continuum.viscoelastic import Damping, simulate_body

    P = _continuum_problem(params["problem"])
    kw: dict[str, Any] = (
        {"density": 1.0} if params["problem"] == "inertial" else {"damping": Damping(drag=1.0)}
    )
    n = params["steps"]
    run = functools.partial(
        simulate_body, P["body"], fixed=P["fixed"], u0=P["mode"], record_every=n, **kw
    )
    run(dt=P["t_end"] / 2, t_end=P["t_end"], scheme=params["scheme"])  # warm-up
    tr = run(dt=P["t_end"] / n, t_end=P["t_end"], scheme=params["scheme"])
    err = float(np.max(np.abs(tr.u - P["exact"] * P["mode"])))
    return IntegratorResult(**params, dt=P["t_end"] / n, error=err, seconds=float(tr.seconds))
