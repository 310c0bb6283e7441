"""Damped dynamics of a spring network: Eq. 10 and its overdamped limit, Eq. 12.

Inertial (unit masses, ``inertia=True``)::

    x'' = -c x' - grad E(x)                                   (Eq. 10)

Overdamped (``inertia=False``)::

    c x' = -grad E(x)                                         (Eq. 12 with c = 1)

``c`` is ``damping`` (drag per unit velocity against the lab frame, so rigid-body motion
decays and no pins are needed). Boundary conditions:

* ``pinned``: coordinates held at their starting values;
* ``prescribed``: ``{node: (x, y)}``, nodes moved to a position at ``t = 0`` (a step) and
  held there;
* ``clamped``: ``{spring: length}``, a clamp imposed as a prescribed displacement of the
  clamped spring's two end nodes: they move apart (or together) symmetrically along the
  spring to the clamp length at ``t = 0`` and are then held. This is what a continuum
  comparison imposes (a displacement boundary condition on two small regions); unlike the
  equilibrium clamp of :func:`~.equilibrium.relax` the clamped spring cannot also rotate
  or translate. An exact length constraint would need a differential-algebraic
  integrator; rods would need a step ~ 1/sqrt(1e10) in explicit schemes.

Schemes (``scheme``):

``"implicit"``
    Backward Euler on the first-order system (L-stable: stiff modes are damped in one
    step, whatever ``dt``). First order in ``dt``.
``"newmark"``
    Newmark's average acceleration (the trapezoidal rule; Crank–Nicolson when overdamped).
    Second order, no numerical damping of oscillations (stiff modes ring, undamped by the
    scheme, but do not grow).
``"explicit"``
    Semi-implicit (symplectic) Euler with explicit damping, or forward Euler when
    overdamped. Stable only for ``dt`` below :func:`stability_limit`; a larger ``dt`` is
    refused with a ``ValueError``.

Every implicit step is the minimisation of ``Phi(x) = E(x) + a/2 |x - x_hat|^2`` over the
free coordinates (``a`` and ``x_hat`` depend on the scheme; see ``_implicit_coefficient``
and ``_implicit_target``), solved by Newton iterations with the sparse Hessian ``H + a I``
(the tangentially clipped Hessian where that is indefinite) and an Armijo line search on
``Phi`` (energy differences computed without cancellation). For backward Euler overdamped
``x_hat`` is the previous state, so ``E(x1) + a/2 |x1 - x0|^2 <= E(x0)``: the energy never
increases.

Factorisations: ``jacobian="update"`` factorises ``H + a I`` once at the start of each
step and reuses it for the step's corrections (chord iterations) while they cut the
residual at least 4-fold; ``"frozen"`` reuses one factorisation across steps as well
(exact for a linear network, i.e. small displacements, so a linear run factorises once).
A step that proves nonlinear (a reused factor gives a poor correction) switches to full
Newton, one factorisation per iteration. Very stiff springs (rods of k = 1e10 among
k ~ 1) that must rotate during a step make Newton zig-zag along a curved valley
(~60 iterations for a step; hence ``max_newton=200``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from .constraints import Pins, pin_mask
from .energy import (
    hessian_norm_bound,
    spring_energy,
    spring_gradient,
)
from .model import SpringNetwork
from .proximal import ProximalSolver

__all__ = ["Trajectory", "relaxation_time", "settling_time", "simulate", "stability_limit"]

Scheme = Literal["implicit", "newmark", "explicit"]
_SCHEMES = ("implicit", "newmark", "explicit")
_JACOBIANS = ("update", "frozen")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A recorded run of :func:`simulate`.

    Attributes
    ----------
    times : (T,) float array
        Recorded times (time units; the first is 0, after the prescribed step).
    positions, velocities : (T, n_nodes, 2) float arrays
    energy : (T,) float array
        Elastic energy of the network (Eq. 11).
    kinetic : (T,) float array
        ``|v|^2 / 2`` (unit masses). Overdamped runs report it for the drift velocity
        ``x'``; it is then not part of the mechanical energy.
    residual : (T,) float array
        Largest net spring force on a free coordinate (force units).
    seconds : (T,) float array
        Wall-clock time at which each frame was reached (for cost-against-accuracy plots).
    free : (n_nodes, 2) bool array
        Coordinates that moved (not pinned, prescribed or clamped).
    scheme : str
    dt, damping : float
    inertia : bool
    factorisations : int
        Sparse factorisations made (implicit schemes).
    arm : (T, n_springs) float array or None
        Maxwell-arm lengths (:func:`~.viscous.simulate_viscous` with arms), else None.
    """

    times: NDArray[np.float64]
    positions: NDArray[np.float64] = field(repr=False)
    velocities: NDArray[np.float64] = field(repr=False)
    energy: NDArray[np.float64] = field(repr=False)
    kinetic: NDArray[np.float64] = field(repr=False)
    residual: NDArray[np.float64] = field(repr=False)
    seconds: NDArray[np.float64] = field(repr=False)
    free: NDArray[np.bool_] = field(repr=False)
    scheme: str
    dt: float
    damping: float
    inertia: bool
    factorisations: int = 0
    arm: NDArray[np.float64] | None = field(default=None, repr=False)

    def relaxation_time(self, fraction: float = 1e-2, *, measure: str = "residual") -> float:
        """See :func:`relaxation_time`."""
        return relaxation_time(self, fraction, measure=measure)


# -- boundary conditions ----------------------------------------------------------------------
def _boundary(
    net: SpringNetwork,
    pinned: Pins,
    prescribed: Mapping[int, ArrayLike] | None,
    clamped: Mapping[int, float] | None,
    x0: ArrayLike | None,
) -> tuple[NDArray, NDArray]:
    """Starting positions with prescribed and clamped nodes moved, and the free mask."""
    n = net.n_nodes
    x = net.positions.copy() if x0 is None else np.array(x0, dtype=np.float64, copy=True)
    if x.shape != (n, 2):
        raise ValueError(f"x0 must have shape ({n}, 2), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x0 must be finite")
    fixed = np.zeros((n, 2), dtype=bool) if pinned is None else pin_mask(net, pinned)
    held = np.zeros(n, dtype=bool)  # nodes moved by prescribed/clamped
    for node, pos in (prescribed or {}).items():
        i = int(node)
        if not 0 <= i < n:
            raise ValueError(f"prescribed names node {node} outside 0..{n - 1}")
        p = np.asarray(pos, dtype=np.float64)
        if p.shape != (2,) or not np.all(np.isfinite(p)):
            raise ValueError(f"prescribed position of node {i} must be 2 finite numbers, got {pos}")
        x[i] = p
        held[i] = True
    for spring, length in (clamped or {}).items():
        j = int(spring)
        if not 0 <= j < net.n_springs:
            raise ValueError(f"clamped names spring {spring} outside 0..{net.n_springs - 1}")
        length = float(length)
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f"clamped length of spring {j} must be finite and > 0, got {length}")
        a, b = net.springs[j]
        if held[a] or held[b]:
            raise ValueError(
                f"clamped spring {j} shares node {a if held[a] else b} with "
                "another clamp or a prescribed node"
            )
        d = x[b] - x[a]
        r = float(np.hypot(*d))
        if r == 0.0:
            raise ValueError(f"clamped spring {j} has zero length at the start")
        grow = (length - r) * d / r
        stay_a, stay_b = fixed[a].all(), fixed[b].all()
        if stay_a and stay_b:
            raise ValueError(f"clamped spring {j}: both end nodes are pinned")
        if stay_a:
            x[b] += grow
        elif stay_b:
            x[a] -= grow
        else:
            x[a] -= 0.5 * grow
            x[b] += 0.5 * grow
        held[[a, b]] = True
    fixed[held] = True
    return x, ~fixed


# -- stability of the explicit scheme -------------------------------------------------------
def stability_limit(
    net: SpringNetwork, x: ArrayLike | None = None, *, damping: float = 1.0, inertia: bool = True
) -> float:
    """Largest stable ``dt`` of the explicit scheme at positions ``x`` (time units).

    With ``lambda`` the Gershgorin bound on the Hessian's largest eigenvalue
    (:func:`~.numerics.hessian_norm_bound`, ``2 max_nodes sum_incident k``):

    * inertial, semi-implicit Euler with explicit damping ``c``: a mode of stiffness
      ``lambda`` has the update matrix ``[[1 - dt^2 lambda, dt (1 - c dt)],
      [-dt lambda, 1 - c dt]]``, stable (Jury) for ``lambda dt^2 + 2 c dt < 4``, i.e.
      ``dt < 4 / (c + sqrt(c^2 + 4 lambda))``, which is ``2 / sqrt(lambda)`` undamped;
    * overdamped forward Euler: ``dt < 2 c / lambda``.
    """
    x = net.positions if x is None else np.asarray(x, dtype=np.float64)
    lam = hessian_norm_bound(x, net.springs, net.stiffness, net.rest_length)
    c = float(damping)
    if lam <= 0:
        return np.inf
    if inertia:
        return 4.0 / (c + np.sqrt(c * c + 4.0 * lam))
    return 2.0 * c / lam


# -- the run ----------------------------------------------------------------------------------
def _check_number(name: str, value: float, *, positive: bool = False) -> float:
    return check.real(name, value, low=0, low_open=positive)


def simulate(
    net: SpringNetwork,
    *,
    dt: float,
    t_end: float,
    pinned: Pins = None,
    prescribed: Mapping[int, ArrayLike] | None = None,
    clamped: Mapping[int, float] | None = None,
    x0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    damping: float = 1.0,
    inertia: bool = True,
    scheme: Scheme = "implicit",
    record_every: int = 1,
    tol: float = 1e-10,
    jacobian: Literal["update", "frozen"] = "update",
    max_newton: int = 200,
) -> Trajectory:
    """Integrate the damped dynamics of ``net`` from ``t = 0`` to ``t_end``.

    Parameters
    ----------
    net : SpringNetwork
    dt : float
        Time step (> 0). ``ceil(t_end / dt)`` steps are taken; the last time may pass
        ``t_end`` by less than ``dt``.
    t_end : float
        Duration (> 0).
    pinned : node indices, (n_nodes, 2) bool mask, or None
        Coordinates held at their values in ``x0``. None pins nothing: the drag
        ``damping`` acts against the lab frame, so rigid-body motion decays by itself (pass
        :func:`~.constraints.default_pins` to match :func:`~.equilibrium.relax`).
    prescribed : {node: (x, y)}, optional
        Nodes stepped to a position at ``t = 0`` and held there.
    clamped : {spring: length}, optional
        Clamps as prescribed displacements of both end nodes (see module docstring).
    x0 : (n_nodes, 2) float array, optional
        Starting positions (default ``net.positions``).
    v0 : (n_nodes, 2) float array, optional
        Starting velocities (inertial only; default zero). Held coordinates get zero.
    damping : float
        ``c`` in Eq. 10 (>= 0; > 0 when overdamped), force per velocity.
    inertia : bool
        Eq. 10 with unit masses (True) or the overdamped ``c x' = -grad E`` (False).
    scheme : {"implicit", "newmark", "explicit"}
        See the module docstring.
    record_every : int
        Record every this many steps (the first and last states are always recorded).
    tol : float
        Implicit steps: each step's equation is solved to a residual force
        ``<= tol * net.force_scale`` (or a Newton correction ``<= tol * mean(L)``).
    jacobian : {"update", "frozen"}
        Implicit steps: refactorise ``H + a I`` every step, or only when needed.
    max_newton : int
        Newton iterations allowed per implicit step.

    Returns
    -------
    Trajectory

    Raises
    ------
    ValueError
        Bad input, or an explicit ``dt`` above :func:`stability_limit` (naming both).
    RuntimeError
        An implicit step that does not converge, or an explicit run that leaves its
        stability limit (springs compressed below half their rest length) or blows up.
    """
    if scheme not in _SCHEMES:
        raise ValueError(f"scheme must be one of {_SCHEMES}, got {scheme!r}")
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {_JACOBIANS}, got {jacobian!r}")
    dt = _check_number("dt", dt, positive=True)
    t_end = _check_number("t_end", t_end, positive=True)
    c = _check_number("damping", damping, positive=not inertia)
    tol = _check_number("tol", tol, positive=True)
    record_every = check.integer("record_every", record_every, low=1)
    max_newton = check.integer("max_newton", max_newton, low=1)
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    frames = math.ceil(t_end / dt) // record_every + 2
    # every frame keeps positions, velocities and forces, (n_nodes, 2) each, and 4 scalars
    check.memory("t_end", t_end, frames * (48 * net.n_nodes + 32), f"{frames} recorded frames")
    inertia = bool(inertia)
    t0 = time.perf_counter()

    x, free = _boundary(net, pinned, prescribed, clamped, x0)
    fixed_flat = ~free.ravel()
    v = np.zeros_like(x)
    if v0 is not None:
        if not inertia:
            raise ValueError("v0 is only meaningful with inertia=True")
        v = np.array(v0, dtype=np.float64, copy=True)
        if v.shape != x.shape or not np.all(np.isfinite(v)):
            raise ValueError(f"v0 must be a finite array of shape {x.shape}")
        v.ravel()[fixed_flat] = 0.0
    springs, k, L = net.springs, net.stiffness, net.rest_length

    def grad(y: NDArray) -> NDArray:
        g = spring_gradient(y, springs, k, L)
        g.ravel()[fixed_flat] = 0.0
        return g

    G = grad(x)
    if not inertia:
        v = -G / c
    acc = -c * v - G  # inertial acceleration (Newmark needs it)

    if scheme == "explicit":
        limit = stability_limit(net, x, damping=c, inertia=inertia)
        if dt >= limit:
            raise ValueError(
                f"dt = {dt:g} is above the explicit stability limit {limit:.4g} "
                f"({'inertial' if inertia else 'overdamped'}, damping {c:g}, from the "
                "Gershgorin bound on the stiffest node); use a smaller dt or "
                "scheme='implicit'"
            )

    solver = None
    if scheme != "explicit":
        a = _implicit_coefficient(scheme, inertia, dt, c)
        solver = ProximalSolver(net, free, a, tol=tol, jacobian=jacobian, max_newton=max_newton)

    n_steps = max(1, int(np.ceil(t_end / dt - 1e-9)))
    frames: list[tuple] = []

    def record(step: int, x: NDArray, v: NDArray, G: NDArray) -> None:
        residual = float(np.max(np.abs(G))) if free.any() else 0.0
        frames.append(
            (
                step * dt,
                x.copy(),
                v.copy(),
                spring_energy(x, springs, k, L),
                0.5 * float(np.sum(v * v)),
                residual,
                time.perf_counter() - t0,
            )
        )

    record(0, x, v, G)
    for step in range(1, n_steps + 1):
        t = step * dt
        if scheme == "explicit":
            if inertia:
                v = v + dt * (-c * v - G)
            else:
                v = -G / c
            v.ravel()[fixed_flat] = 0.0
            x = x + dt * v
            G = grad(x)
            if not np.all(np.isfinite(G)):
                raise RuntimeError(f"explicit run blew up at t={t:g} (dt={dt:g})")
        else:
            x_hat = _implicit_target(scheme, inertia, x, v, acc, G, dt, c, solver.a)
            x_new = solver.step(x + dt * v if inertia else x, x_hat, t)
            G_new = grad(x_new)
            if scheme == "implicit":
                v_new = (x_new - x) / dt if inertia else -G_new / c
            elif inertia:  # Newmark average acceleration
                v_new = 2.0 * (x_new - x) / dt - v
            else:
                v_new = -G_new / c
            v_new.ravel()[fixed_flat] = 0.0
            acc = -c * v_new - G_new
            x, v, G = x_new, v_new, G_new
        if step % record_every == 0 or step == n_steps:
            if scheme == "explicit":
                limit = stability_limit(net, x, damping=c, inertia=inertia)
                if dt >= limit:
                    raise RuntimeError(
                        f"explicit run left its stability limit at t={t:g}: dt = {dt:g} >= "
                        f"{limit:.4g} (springs compressed below half their rest length)"
                    )
            record(step, x, v, G)

    times, pos, vel, energy, kinetic, residual, seconds = (np.asarray(z) for z in zip(*frames))
    for arr in (times, pos, vel, energy, kinetic, residual, seconds):
        arr.setflags(write=False)
    free = free.copy()
    free.setflags(write=False)
    return Trajectory(
        times=times,
        positions=pos,
        velocities=vel,
        energy=energy,
        kinetic=kinetic,
        residual=residual,
        seconds=seconds,
        free=free,
        scheme=scheme,
        dt=dt,
        damping=c,
        inertia=inertia,
        factorisations=solver.factorisations if solver is not None else 0,
    )


def _implicit_coefficient(scheme: str, inertia: bool, dt: float, c: float) -> float:
    """``a`` in ``Phi = E + a/2 |x - x_hat|^2`` (force per length)."""
    if scheme == "implicit":
        return (1.0 + c * dt) / dt**2 if inertia else c / dt
    return 4.0 / dt**2 + 2.0 * c / dt if inertia else 2.0 * c / dt


def _implicit_target(
    scheme: str,
    inertia: bool,
    x: NDArray,
    v: NDArray,
    acc: NDArray,
    G: NDArray,
    dt: float,
    c: float,
    a: float,
) -> NDArray:
    """``x_hat`` of the step from ``(x, v, acc)``; ``grad E(x1) + a (x1 - x_hat) = 0``.

    Backward Euler: ``x_hat = x + dt v / (1 + c dt)`` (inertial), ``x`` (overdamped).
    Newmark: ``x_hat = x + (4 v / dt + acc + c v) / a`` (inertial), ``x - grad E / a``
    (overdamped, trapezoidal).
    """
    if scheme == "implicit":
        return x + (dt / (1.0 + c * dt)) * v if inertia else x
    if inertia:
        return x + (4.0 * v / dt + acc + c * v) / a
    return x - G / a


# -- relaxation time --------------------------------------------------------------------------
def settling_time(
    times: ArrayLike, values: ArrayLike, start: ArrayLike, end: ArrayLike, fraction: float
) -> float:
    """Time after which ``values`` (T, m) stay within ``fraction`` of their total change
    ``|end - start|`` (Euclidean norms over the m components) of ``end``; the crossing is
    interpolated linearly between the last frame outside and the next. ``inf`` when the
    last frame is still outside, 0 when nothing changes."""
    v = np.asarray(values, float).reshape(len(times), -1)
    total = float(np.linalg.norm(np.asarray(end, float) - np.asarray(start, float)))
    if total == 0:
        return 0.0
    d = np.linalg.norm(v - np.asarray(end, float), axis=1)
    level = fraction * total
    outside = np.flatnonzero(d > level)
    if outside.size == 0:
        return float(times[0])
    j = int(outside[-1])
    if j + 1 >= d.size:
        return math.inf
    return float(times[j] + (times[j + 1] - times[j]) * (d[j] - level) / (d[j] - d[j + 1]))


def relaxation_time(
    traj: Trajectory, fraction: float = 1e-2, *, measure: str = "residual"
) -> float:
    """Time after which ``measure`` stays below ``fraction`` of its value at ``t = 0``.

    ``measure="residual"``: the largest net force on a free coordinate.
    ``measure="displacement"``: ``max_nodes |x(t) - x(t_end)|``, the distance to the last
    recorded state; meaningful only when the run has settled by ``t_end``.

    The crossing is interpolated log-linearly between the two recorded frames around it.

    Raises
    ------
    ValueError
        ``fraction`` outside (0, 1), an unknown ``measure``, or a run that never stays
        below the threshold before its last frame (run longer).
    """
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction}")
    if measure == "residual":
        m = np.asarray(traj.residual)
    elif measure == "displacement":
        diff = traj.positions - traj.positions[-1]
        m = np.max(np.hypot(diff[..., 0], diff[..., 1]), axis=1)
    else:
        raise ValueError(f"measure must be 'residual' or 'displacement', got {measure!r}")
    if m[0] == 0:
        return 0.0
    threshold = fraction * m[0]
    above = np.flatnonzero(m > threshold)
    last = int(above[-1])
    if last >= m.size - 1 or (measure == "displacement" and last >= m.size - 2):
        raise ValueError(
            f"the {measure} does not settle below {fraction:g} of its start within "
            f"t_end = {traj.times[-1]:g}; run longer"
        )
    t0, t1 = traj.times[last], traj.times[last + 1]
    m0, m1 = m[last], m[last + 1]
    if m1 <= 0:
        return float(t1)
    return float(t0 + (t1 - t0) * np.log(m0 / threshold) / np.log(m0 / m1))
