"""Damped dynamics of a spring network: Eq. 10, its overdamped limit (Eq. 12), and the
visco-elastic network of :mod:`.viscous` (spring dashpots, Maxwell arms).

Inertial (unit masses, ``inertia=True``) and overdamped (``inertia=False``)::

    x'' = -c x' - D_kv(x) x' - grad E(x, l)        c x' + D_kv(x) x' = -grad E(x, l)

``c`` is the node drag (against the lab frame, so rigid-body motion decays and no pins are
needed); ``D_kv`` the Kelvin-Voigt dashpots and ``l`` the Maxwell arms of a
:class:`~.viscous.Viscosity` (:func:`simulate_viscous`; :func:`simulate` has drag only).
Boundary conditions (``pinned``, ``prescribed``, ``clamped``, held from ``t = 0``):
:func:`~.held_boundary.held_boundary`.

Each step is made by :class:`~.stepper.Stepper` (schemes, the implicit step's Newton and
its factorisations are described there).

A displacement step of held nodes at ``t = 0`` in :func:`simulate_viscous` drives the
dashpots by an impulse: the free nodes jump by ``-D_ff^{-1} D_fb Delta_b`` (overdamped;
inertial: the velocity jumps by ``-D_fb Delta_b``) with the arm dashpots still. A pure
Kelvin-Voigt network (``c = 0``) then sits at its elastic equilibrium at every ``t > 0``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..linalg.spd import factor_spd
from .constraints import Pins
from .energy import hessian_norm_bound
from .held_boundary import held_boundary
from .model import SpringNetwork
from .stepper import Scheme, Stepper
from .viscous import Viscosity, dashpot_matrix

__all__ = [
    "Trajectory",
    "relaxation_time",
    "settling_time",
    "simulate",
    "simulate_viscous",
    "stability_limit",
]


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A recorded run of :func:`simulate` or :func:`simulate_viscous`.

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
        Maxwell-arm lengths (:func:`simulate_viscous` with arms), else None.
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


# -- runs -------------------------------------------------------------------------------------
class _Frames:
    """Recorded frames of a run (every ``record_every`` steps, the first and last)."""

    def __init__(self, stepper: Stepper, net: SpringNetwork, record_every: int, n_steps: int):
        self.stepper, self.net = stepper, net
        self.every, self.n_steps = record_every, n_steps
        self.t0 = time.perf_counter()
        self.rows: list[tuple] = []

    def due(self, step: int) -> bool:
        return step % self.every == 0 or step == self.n_steps

    def record(self, step, x, v, arm=None, gradient=None) -> None:
        st = self.stepper
        g = st.gradient(self.net, x, arm) if gradient is None else gradient
        self.rows.append(
            (
                step * st.dt,
                x.copy(),
                v.copy(),
                st.energy(self.net, x, arm),
                0.5 * float(np.sum(v * v)),
                float(np.max(np.abs(g))) if st.free.any() else 0.0,
                time.perf_counter() - self.t0,
                None if arm is None else arm.copy(),
            )
        )

    def trajectory(self, scheme: str) -> Trajectory:
        st = self.stepper
        cols = list(zip(*self.rows))
        arrays = [np.asarray(c) for c in cols[:7]]
        arms = None if cols[7][0] is None else np.asarray(cols[7])
        free = st.free.copy()
        for a in [*arrays, arms, free]:
            if a is not None:
                a.setflags(write=False)
        times, pos, vel, energy, kinetic, residual, seconds = arrays
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
            dt=st.dt,
            damping=st.drag,
            inertia=st.inertia,
            factorisations=st.factorisations,
            arm=arms,
        )


def _n_steps(t_end: float, dt: float) -> int:
    return max(1, int(np.ceil(t_end / dt - 1e-9)))


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
    """Integrate the damped dynamics of ``net`` (node drag only) from ``t = 0`` to ``t_end``.

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
        Clamps as prescribed displacements of both end nodes (:mod:`.held_boundary`).
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
    tol, jacobian, max_newton
        Implicit steps: see :class:`~.stepper.Stepper`.

    Returns
    -------
    Trajectory
        Overdamped runs record the drift velocity ``-grad E / c`` at each frame.

    Raises
    ------
    ValueError
        Bad input, or an explicit ``dt`` above :func:`stability_limit` (naming both).
    RuntimeError
        An implicit step that does not converge, or an explicit run that leaves its
        stability limit (springs compressed below half their rest length) or blows up.
    """
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
    x, free = held_boundary(net, pinned, prescribed, clamped, x0)
    v = np.zeros_like(x)
    if v0 is not None:
        if not inertia:
            raise ValueError("v0 is only meaningful with inertia=True")
        v = np.array(v0, dtype=np.float64, copy=True)
        if v.shape != x.shape or not np.all(np.isfinite(v)):
            raise ValueError(f"v0 must be a finite array of shape {x.shape}")
        v.ravel()[~free.ravel()] = 0.0
    explicit = scheme == "explicit"
    if explicit:
        limit = stability_limit(net, x, damping=c, inertia=inertia)
        if dt >= limit:
            raise ValueError(
                f"dt = {dt:g} is above the explicit stability limit {limit:.4g} "
                f"({'inertial' if inertia else 'overdamped'}, damping {c:g}, from the "
                "Gershgorin bound on the stiffest node); use a smaller dt or "
                "scheme='implicit'"
            )
    stepper = Stepper(
        net, c, free, dt, inertia=inertia, scheme=scheme, tol=tol, max_newton=max_newton,
        jacobian=jacobian,
    )  # fmt: skip
    G = stepper.gradient(net, x)
    if not inertia:
        v = -G / c
    n_steps = _n_steps(t_end, dt)
    run = _Frames(stepper, net, record_every, n_steps)
    run.record(0, x, v, gradient=G)
    for step in range(1, n_steps + 1):
        x, v1, _ = stepper.step(net, x, v=v, gradient=G, t=step * dt)
        G = stepper.gradient(net, x)
        if explicit and not np.all(np.isfinite(G)):
            raise RuntimeError(f"explicit run blew up at t={step * dt:g} (dt={dt:g})")
        v = v1 if inertia or explicit else -G / c
        if run.due(step):
            if explicit:
                limit = stability_limit(net, x, damping=c, inertia=inertia)
                if dt >= limit:
                    raise RuntimeError(
                        f"explicit run left its stability limit at t={step * dt:g}: dt = "
                        f"{dt:g} >= {limit:.4g} (springs compressed below half their rest "
                        "length)"
                    )
            run.record(step, x, v, gradient=G)
    return run.trajectory(scheme)


def _check_number(name: str, value: float, *, positive: bool = False) -> float:
    return check.real(name, value, low=0, low_open=positive)


def _impulse(
    net: SpringNetwork, vis: Viscosity, free: NDArray, x_before: NDArray, x_after: NDArray
) -> NDArray:
    """Free-node jump ``-D_ff^{-1} D_fb Delta_b`` of a step ``Delta_b`` of held nodes."""
    delta = (x_after - x_before).ravel()
    if vis.dashpot == 0 or not np.any(delta):
        return np.zeros_like(delta)
    D = dashpot_matrix(x_before, net, vis.dashpot) + vis.drag * sp.identity(2 * net.n_nodes)
    D = D.tocsr()
    f = np.flatnonzero(free.ravel())
    h = np.flatnonzero(~free.ravel())
    rhs = -(D[f][:, h] @ delta[h])
    out = np.zeros_like(delta)
    factor = factor_spd(D[f][:, f].tocsr())
    if factor is None:
        raise ValueError("the dashpots and drag do not hold every free coordinate (add drag)")
    out[f] = factor.solve(rhs)
    return out


def simulate_viscous(
    net: SpringNetwork,
    viscosity: Viscosity,
    *,
    dt: float,
    t_end: float,
    pinned: Pins = None,
    prescribed: Mapping[int, ArrayLike] | None = None,
    clamped: Mapping[int, float] | None = None,
    x0: ArrayLike | None = None,
    arm0: ArrayLike | None = None,
    inertia: bool = False,
    record_every: int = 1,
    tol: float = 1e-10,
) -> Trajectory:
    """Integrate a visco-elastic network from ``t = 0`` to ``t_end`` (backward Euler).

    Boundary conditions as in :func:`simulate` (held nodes stepped at ``t = 0`` with the
    dashpot impulse, module docstring). ``arm0``: starting arm lengths (default: the
    spring lengths at ``x0``, arms relaxed). Returns a :class:`Trajectory` whose ``arm``
    holds the arm lengths (T, n_springs) and whose ``residual`` is the net force (springs
    and arms) on the free coordinates.
    """
    if not isinstance(viscosity, Viscosity):
        raise ValueError(f"viscosity must be a Viscosity, got {type(viscosity).__name__}")
    t_end = _check_number("t_end", t_end, positive=True)
    record_every = check.integer("record_every", record_every, low=1)
    start = net.positions if x0 is None else np.asarray(x0, dtype=np.float64)
    x, free = held_boundary(net, pinned, prescribed, clamped, x0)
    arm = None
    if viscosity.has_arm:
        arm = net.lengths(start) if arm0 is None else np.array(arm0, dtype=np.float64)
        if arm.shape != (net.n_springs,) or not np.all(np.isfinite(arm)):
            raise ValueError(f"arm0 must be {net.n_springs} finite lengths")
    elif arm0 is not None:
        raise ValueError("arm0 needs Maxwell arms (arm_stiffness > 0)")
    stepper = Stepper(net, viscosity, free, dt, inertia=inertia, tol=tol)
    jump = _impulse(net, viscosity, free, start, x).reshape(x.shape)
    v = np.zeros_like(x)
    if inertia:
        v = jump  # unit masses: the impulse sets the velocity
    else:
        x = x + jump
    n_steps = _n_steps(t_end, stepper.dt)
    run = _Frames(stepper, net, record_every, n_steps)
    run.record(0, x, v, arm)
    for step in range(1, n_steps + 1):
        x, v, arm = stepper.step(net, x, v=v, arm=arm, t=step * stepper.dt)
        if run.due(step):
            run.record(step, x, v, arm)
    return run.trajectory("implicit")


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
