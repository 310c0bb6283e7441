"""Visco-elastic bodies in time: mass, damping and implicit stepping with one factorisation.

The semi-discrete equations are ``M u'' + C u' + K u = f`` with

- ``M``: consistent mass matrix of density ``rho`` (:func:`~.body.mass_matrix`);
- ``C``: damping (:class:`~.damping.Damping`, with :func:`~.damping.damping_matrix` and
  :func:`~.damping.lattice_damping` re-exported here): substrate drag ``eta M_1`` (the
  continuum of the network's node drag, see :func:`~.materials.node_drag_to_continuum`),
  Rayleigh ``alpha M + beta K``, and Kelvin-Voigt viscosity (viscous Lamé parameters, the
  continuum of spring dashpots, :func:`~.materials.lattice_viscous_lame`);
- ``K``: stiffness.

Fixed DOFs jump to their prescribed values at ``t = 0`` (a step, before the first
recorded frame) and are held. The step is an impulse through the coupling ``C_fb`` (and
``M_fb``) to the free DOFs, applied exactly (:func:`_step_impulse`): a Kelvin-Voigt body
is at its elastic solution at every ``t > 0``. A Maxwell arm (:mod:`.maxwell`, a standard
linear solid) adds internal strains to the unknowns, integrated by the same schemes.

Schemes (each factorises one matrix, once):

``"backward_euler"``
    L-stable, first order. Overdamped limit (``rho = 0``): ``(C + dt K) v = f - K u``.
``"newmark"``
    Average acceleration (trapezoidal rule), second order, energy-conserving without
    damping; with ``rho = 0`` it is Crank-Nicolson on ``C u' + K u = f``. It does not damp
    the stiff modes a sudden step excites (they ring, bounded), so after a step in the
    fixed DOFs the first few steps oscillate; backward Euler is the safe default there,
    Newmark the efficient one for smooth responses (the work-precision table in
    ``benchmarks/bench_continuum.py``: 3e-7 in 320 steps against 6e-4 for backward Euler).

Both are unconditionally stable: ``dt`` may be far above the explicit limit
(:func:`explicit_limit`).

What kind of dissipation matters for transmission (checked in the tests): pure
Kelvin-Voigt without mass relaxes every mode at the same rate (no delay between near and
far), substrate drag makes the response diffuse outwards (delay growing as distance
squared), inertia gives waves (delay growing linearly). A network and a continuum must be
given the same kind.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from ..linalg.spd import fixed_vector
from .body import ElasticBody, mass_matrix, stiffness_matrix
from .damping import Damping, damping_matrix, lattice_damping
from .maxwell import damping_arm
from .probes import Probe
from .static import Dirichlet, Ordering, factorise

__all__ = [
    "ContinuumTrajectory",
    "Damping",
    "damping_matrix",
    "explicit_limit",
    "lattice_damping",
    "linear_system",
    "relaxation_time",
    "simulate_body",
    "slowest_relaxation_time",
]

Scheme = Literal["backward_euler", "newmark"]


def explicit_limit(body: ElasticBody, *, density: float) -> float:
    """Largest stable step of an explicit (central-difference) scheme, ``2 / omega_max``.

    ``omega_max**2`` is the largest eigenvalue of ``K u = omega**2 M u`` with the
    consistent mass and no fixed DOFs (Lanczos); for comparison with the implicit schemes,
    which have no limit.
    """
    from scipy.sparse.linalg import eigsh

    if not density > 0:
        raise ValueError(f"density must be > 0, got {density}")
    K = stiffness_matrix(body).tocsc()
    M = mass_matrix(body, density).tocsc()
    lu = factorise(M)
    top = eigsh(
        K, k=1, M=M, Minv=_inverse(lu), which="LA", return_eigenvectors=False, tol=1e-4,
        v0=fixed_vector(K.shape[0]),
    )  # fmt: skip
    lam_max = float(top[0])
    return 2.0 / math.sqrt(lam_max)


def _inverse(lu: object) -> object:
    from scipy.sparse.linalg import LinearOperator

    n = lu.shape[0]
    return LinearOperator((n, n), matvec=lu.solve, dtype=float)


@dataclass(frozen=True, eq=False)
class ContinuumTrajectory:
    """A recorded run of :func:`simulate_body`.

    Attributes
    ----------
    times : (T,) float array
        Recorded times; ``times[0] = 0`` is just after the step of the fixed DOFs.
    observed : (T, ...) float array
        The probe's read-out at each recorded time (empty without a probe).
    energy : (T,) float array
        Elastic energy ``u.K.u / 2``.
    kinetic : (T,) float array
        Kinetic energy ``v.M.v / 2`` (zero without mass).
    u : (n_dofs,) float array
        Displacement at the last step.
    seconds, seconds_factorisation : float
        Wall-clock time of the whole run (assembly included) and of the factorisation.
    scheme : str
    dt : float
    """

    times: NDArray[np.float64]
    observed: NDArray[np.float64] = field(repr=False)
    energy: NDArray[np.float64] = field(repr=False)
    kinetic: NDArray[np.float64] = field(repr=False)
    u: NDArray[np.float64] = field(repr=False)
    seconds: float
    seconds_factorisation: float
    scheme: str
    dt: float


def simulate_body(
    body: ElasticBody,
    *,
    fixed: Dirichlet,
    dt: float,
    t_end: float,
    scheme: Scheme = "backward_euler",
    damping: Damping | None = None,
    density: float = 0.0,
    load: ArrayLike | None = None,
    u0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    observe: Probe | None = None,
    record_every: int = 1,
    ordering: Ordering = "MMD_AT_PLUS_A",
) -> ContinuumTrajectory:
    """Integrate ``M u'' + C u' + K u = f`` from ``t = 0`` to ``t_end`` with a fixed step.

    Parameters
    ----------
    body : ElasticBody
    fixed : Dirichlet
        DOFs stepped to their values at ``t = 0`` and held (may be empty when ``C`` or
        ``M`` is positive definite, e.g. with substrate drag).
    dt, t_end : float
        Time step and duration (> 0); ``ceil(t_end / dt)`` steps.
    scheme : {"backward_euler", "newmark"}
    damping : Damping, optional
    density : float
        Mass density ``rho`` (>= 0); 0 is the overdamped limit, which needs damping.
    load : (n_dofs,) float array, optional
        Constant load ``f`` switched on at ``t = 0``.
    u0, v0 : (n_dofs,) float arrays, optional
        Initial displacement (default 0; the fixed DOFs step from ``u0``'s values to
        ``fixed``'s) and velocity (default 0, needs mass). Maxwell arms start relaxed at
        ``u0``.
    observe : Probe, optional
        Read-out recorded at every recorded step.
    record_every : int
        Record every this many steps (first and last always).
    ordering : str
        SuperLU ordering of the single factorisation.

    Returns
    -------
    ContinuumTrajectory
    """
    t_start = time.perf_counter()
    if scheme not in ("backward_euler", "newmark"):
        raise ValueError(f"scheme must be 'backward_euler' or 'newmark', got {scheme!r}")
    dt, t_end = float(dt), float(t_end)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0, got {dt}")
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be finite and > 0, got {t_end}")
    if int(record_every) < 1:
        raise ValueError(f"record_every must be >= 1, got {record_every}")
    density = float(density)
    if not (math.isfinite(density) and density >= 0):
        raise ValueError(f"density must be finite and >= 0, got {density}")
    damping = Damping() if damping is None else damping
    n = body.n_dofs
    f = np.zeros(n) if load is None else np.asarray(load, dtype=float)
    if f.shape != (n,):
        raise ValueError(f"load must have shape ({n},), got {f.shape}")

    K, C, M, n_int = _system(body, damping, density)
    f_aug = np.concatenate([f, np.zeros(n_int)])
    Cu = C[:n, :n]
    if M is None and Cu.nnz == 0:
        raise ValueError(
            "no mass (density=0) and no damping of the displacements: nothing to integrate; "
            "use solve_static"
        )
    if scheme == "newmark" and M is not None and n_int:
        raise ValueError("scheme='newmark' with mass and a Maxwell arm: use 'backward_euler'")

    free = np.ones(n, dtype=bool)
    free[fixed.dofs] = False
    fu = np.flatnonzero(free)
    fi = np.concatenate([fu, n + np.arange(n_int)])  # free DOFs, then internal strains
    b = fixed.dofs
    for name, arr in (("u0", u0), ("v0", v0)):
        if arr is not None and np.shape(arr) != (n,):
            raise ValueError(f"{name} must have shape ({n},), got {np.shape(arr)}")
    if v0 is not None and M is None:
        raise ValueError("v0 needs mass (density > 0)")
    before = np.zeros(n) if u0 is None else np.asarray(u0, dtype=float).copy()
    u_full = np.concatenate([before, np.zeros(n_int)])
    if n_int:  # arms relaxed at the starting state
        u_full[n:] = damping_arm(body, damping).strain @ before
    u_full[b] = fixed.values
    u = u_full[fi].copy()
    v = np.zeros(fi.size)
    if v0 is not None:
        v[: fu.size] = np.asarray(v0, dtype=float)[fu]
    # the step of the fixed DOFs at t = 0 is an impulse on the coupled free DOFs
    jump_u, jump_v = _step_impulse(
        Cu, None if M is None else M[:n, :n], fu, b, fixed.values - before[b]
    )
    u[: fu.size] += jump_u
    v[: fu.size] += jump_v

    Kf = K[fi][:, fi].tocsc()
    Cf = C[fi][:, fi].tocsc()
    Mf = None if M is None else M[fi][:, fi].tocsc()
    g = f_aug[fi] - K[fi][:, b] @ fixed.values  # held DOFs do not move for t > 0
    u_full = np.zeros(n + n_int)
    u_full[b] = fixed.values

    if scheme == "backward_euler":
        A = Cf + dt * Kf if Mf is None else Mf / dt + Cf + dt * Kf
    else:
        beta, gamma = 0.25, 0.5
        if Mf is None:
            A = Cf / dt + 0.5 * Kf
        else:
            A = Kf + (gamma / (beta * dt)) * Cf + (1.0 / (beta * dt * dt)) * Mf
    lu = factorise(A, ordering=ordering)
    acc = None
    if scheme == "newmark" and Mf is not None:
        acc = factorise(Mf, ordering=ordering).solve(g - Cf @ v - Kf @ u)

    n_steps = max(1, math.ceil(t_end / dt - 1e-12))
    every = int(record_every)
    times, observed, energy, kinetic = [], [], [], []
    full = Kf @ u  # reused product

    def record(step: int, u: NDArray, v: NDArray) -> None:
        u_full[fi] = u
        times.append(step * dt)
        if observe is not None:
            observed.append(observe(u_full[:n]))
        energy.append(0.5 * float(u_full @ (K @ u_full)))
        kinetic.append(0.0 if Mf is None else 0.5 * float(v @ (Mf @ v)))

    record(0, u, v)
    for step in range(1, n_steps + 1):
        if scheme == "backward_euler":
            rhs = g - full if Mf is None else Mf @ v / dt + g - full
            v = lu.solve(rhs)
            u = u + dt * v
        elif Mf is None:
            u_new = lu.solve(Cf @ u / dt - 0.5 * full + g)
            v = (u_new - u) / dt
            u = u_new
        else:
            beta, gamma = 0.25, 0.5
            rhs = (
                g
                + Mf @ (u / (beta * dt * dt) + v / (beta * dt) + (0.5 / beta - 1.0) * acc)
                + Cf
                @ (
                    (gamma / (beta * dt)) * u
                    + (gamma / beta - 1.0) * v
                    + dt * (0.5 * gamma / beta - 1.0) * acc
                )
            )
            u_new = lu.solve(rhs)
            acc_new = (u_new - u) / (beta * dt * dt) - v / (beta * dt) - (0.5 / beta - 1) * acc
            v = v + dt * ((1 - gamma) * acc + gamma * acc_new)
            u, acc = u_new, acc_new
        full = Kf @ u
        if not np.all(np.isfinite(u)):
            raise FloatingPointError(f"non-finite displacement at step {step}")
        if step % every == 0 or step == n_steps:
            record(step, u, v)
    u_full[fi] = u
    obs = np.array(observed) if observed else np.empty((len(times), 0))
    return ContinuumTrajectory(
        times=np.array(times),
        observed=obs,
        energy=np.array(energy),
        kinetic=np.array(kinetic),
        u=u_full[:n].copy(),
        seconds=time.perf_counter() - t_start,
        seconds_factorisation=lu.seconds,
        scheme=scheme,
        dt=dt,
    )


def _system(
    body: ElasticBody, damping: Damping, density: float
) -> tuple[sp.csr_matrix, sp.csr_matrix, sp.csr_matrix | None, int]:
    """``K, C, M`` over the displacement DOFs and the arm's internal strains, and their
    number: ``K = [[K + B^T S B, -B^T S], [-S B, S]]``, ``C = diag(C, V)``, ``M = diag(M, 0)``
    (:mod:`.maxwell`)."""
    K = stiffness_matrix(body)
    M = mass_matrix(body, density) if density > 0 else None
    C = damping_matrix(body, damping, density=density, K=K, M=M)
    if not damping.has_arm:
        return K, C, M, 0
    arm = damping_arm(body, damping)
    B, S, V = arm.strain, arm.stiffness, arm.viscosity
    K = sp.bmat([[K + B.T @ S @ B, -(B.T @ S)], [-(S @ B), S]], format="csr")
    C = sp.bmat([[C, None], [None, V]], format="csr")
    if M is not None:
        M = sp.bmat([[M, None], [None, sp.csr_matrix(S.shape)]], format="csr")
    return K, C, M, arm.n_internal


def _step_impulse(
    C: sp.spmatrix, M: sp.spmatrix | None, free: NDArray, held: NDArray, delta: NDArray
) -> tuple[NDArray, NDArray]:
    """Jumps of the free displacements and velocities when the held DOFs step by ``delta``.

    Integrating ``M u'' + C u' + K u = f`` across the step: without mass ``C_ff du_f =
    -C_fb delta``; with mass ``du_f = -M_ff^{-1} M_fb delta`` and ``M_ff dv_f =
    -(C_ff du_f + C_fb delta)``. A Kelvin-Voigt body (``C`` proportional to ``K``) thus
    starts at its elastic solution; dropping the coupling made it creep instead.
    """
    zero = np.zeros(free.size)
    if held.size == 0 or not np.any(delta):
        return zero, zero
    C = sp.csr_matrix(C)
    C_fb = C[free][:, held] @ delta
    if M is None:
        if not np.any(C_fb):
            return zero, zero
        return factorise(C[free][:, free].tocsc()).solve(-C_fb), zero
    M = sp.csr_matrix(M)
    lu = factorise(M[free][:, free].tocsc())
    du = lu.solve(-(M[free][:, held] @ delta))
    return du, lu.solve(-(C[free][:, free] @ du + C_fb))


def linear_system(
    body: ElasticBody, damping: Damping, fixed: Dirichlet
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Stiffness and damping ``(K, C)`` of the overdamped body on its free unknowns (free
    displacement DOFs, then the arm's internal strains): ``C z' + K z = 0``, for
    :func:`slowest_relaxation_time`."""
    K, C, _, n_int = _system(body, damping, 0.0)
    free = np.ones(body.n_dofs, dtype=bool)
    free[fixed.dofs] = False
    fi = np.concatenate([np.flatnonzero(free), body.n_dofs + np.arange(n_int)])
    return K[fi][:, fi].tocsr(), C[fi][:, fi].tocsr()


def relaxation_time(
    times: ArrayLike,
    values: ArrayLike,
    *,
    final: ArrayLike | None = None,
    fraction: float = math.exp(-1.0),
) -> float:
    """Time after which ``values`` stay within ``fraction`` of their start from ``final``.

    ``values`` is (T,) or (T, k) (the largest component deviation counts); ``final``
    defaults to the last value (the run must have settled). The crossing is interpolated
    log-linearly between the two frames around it. With the default ``1/e`` this is the
    time constant of a single exponential.

    Raises
    ------
    ValueError
        ``fraction`` outside (0, 1), mismatched shapes, or no settling before the end.
    """
    t = np.asarray(times, dtype=float)
    y = np.asarray(values, dtype=float).reshape(t.size, -1)
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must lie in (0, 1), got {fraction}")
    end = y[-1] if final is None else np.asarray(final, dtype=float).reshape(-1)
    dev = np.max(np.abs(y - end), axis=1)
    if dev[0] == 0:
        return 0.0
    threshold = fraction * dev[0]
    above = np.flatnonzero(dev > threshold)
    last = int(above[-1])
    if last >= t.size - 1 or (final is None and last >= t.size - 2):
        raise ValueError(f"values do not settle within {fraction:g} of their start; run longer")
    d0, d1 = dev[last], dev[last + 1]
    if d1 <= 0:
        return float(t[last + 1])
    return float(t[last] + (t[last + 1] - t[last]) * math.log(d0 / threshold) / math.log(d0 / d1))


def slowest_relaxation_time(K: sp.spmatrix, C: sp.spmatrix) -> float:
    """Time constant ``1 / lambda_min`` of the slowest mode of ``C u' + K u = 0``.

    ``K`` and ``C`` are the (free-DOF) stiffness and damping matrices, symmetric, ``C``
    positive definite. For a network with node drag ``c`` pass its free Hessian and
    ``c I``; for a body, ``K_ff`` and ``C_ff``.
    """
    from scipy.sparse.linalg import eigsh

    K = sp.csc_matrix(K)
    C = sp.csc_matrix(C)
    if K.shape != C.shape or K.shape[0] != K.shape[1]:
        raise ValueError(f"K and C must be square and alike, got {K.shape}, {C.shape}")
    if K.shape[0] <= 3:
        from scipy.linalg import eigh

        lam = eigh(K.toarray(), C.toarray(), eigvals_only=True)[0]
    else:
        lam = eigsh(
            K, k=1, M=C, sigma=0, which="LM", return_eigenvectors=False,
            v0=fixed_vector(K.shape[0]),
        )[0]  # fmt: skip
    if not lam > 0:
        raise ValueError(f"the slowest mode does not decay (lambda_min = {lam:.3e}): fix more DOFs")
    return float(1.0 / lam)
