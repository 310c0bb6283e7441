"""Damped dynamics of a spring network: Eq. 10, its overdamped limit (Eq. 12), and the
visco-elastic network of :mod:`.viscous` (spring dashpots, Maxwell arms).

Inertial (unit masses, ``inertia=True``) and overdamped (``inertia=False``)::

    x'' = -c x' - D_kv(x) x' - grad E(x, l)        c x' + D_kv(x) x' = -grad E(x, l)

``c`` is the node drag (against the lab frame, so rigid-body motion decays and no pins are
needed); ``D_kv`` the Kelvin-Voigt dashpots and ``l`` the Maxwell arms of a
:class:`~.viscous.Viscosity` (:func:`simulate_viscous`; :func:`simulate` has drag only).
Boundary conditions:

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

Schemes of :class:`Stepper` (``scheme``):

``"implicit"``
    Backward Euler on the first-order system (L-stable: stiff modes are damped in one
    step, whatever ``dt``). First order in ``dt``. The dashpot matrix is taken at the start
    of each step (linearly implicit in the dashpots, exact for small displacements); the
    arms are eliminated in closed form: over a step an arm acts as a spring of stiffness
    ``k2 g / (k2 + g)`` (``g = gamma2 / dt``) and rest length ``l0``, joined with the main
    spring, and ``l1 = (g l0 + k2 r1) / (g + k2)``.
``"newmark"``
    Newmark's average acceleration (the trapezoidal rule; Crank–Nicolson when overdamped).
    Second order, no numerical damping of oscillations (stiff modes ring, undamped by the
    scheme, but do not grow). Node drag only.
``"explicit"``
    Semi-implicit (symplectic) Euler with explicit damping, or forward Euler when
    overdamped. Stable only for ``dt`` below :func:`stability_limit`; :func:`simulate`
    refuses a larger ``dt`` with a ``ValueError``. Node drag only.

Every implicit step minimises ``Phi(x) = E_step(x) + s^T A s / 2 - b.s`` over the free
coordinates (``s = x - x0`` the step, ``A = (c I + D_kv) / dt (+ I / dt^2)`` for backward
Euler, ``(2 c / dt + 4 / dt^2) I`` for Newmark; ``b`` the momentum, the dashpot impulse of
held nodes that move, Newmark's explicit half), by Newton with the sparse Hessian ``H + A``
(the tangentially clipped Hessian where that is indefinite) and an Armijo line search on
``Phi`` (energy differences computed without cancellation). Overdamped backward Euler
therefore never increases the energy: ``E(x1) + s^T A s / 2 <= E(x0)``.

Factorisations: ``jacobian="frozen"`` keeps the last factorisation of ``H + A`` across
iterations and steps while a correction with it (a chord iteration) cuts the net force at
least 4-fold, and refactorises at the current state otherwise (exact for a linear network,
i.e. small displacements, so a linear run factorises once); ``"update"`` refactorises at
the first correction of every step. The converged state is the same, only the cost
changes. Very stiff springs (rods of k = 1e10 among k ~ 1) that must rotate during a step
make Newton zig-zag along a curved valley (~60 iterations for a step; hence
``max_newton=200`` in :func:`simulate`).

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
from .constraints import Pins, pin_mask
from .energy import (
    hessian_norm_bound,
    spring_energy,
    spring_energy_change,
    spring_gradient,
    spring_hessian_blocks,
)
from .lagrangian import pattern_for
from .model import SpringNetwork, spring_vectors, vector_lengths
from .viscous import Viscosity, dashpot_blocks, dashpot_force, dashpot_matrix

__all__ = [
    "Stepper",
    "Trajectory",
    "relaxation_time",
    "settling_time",
    "simulate",
    "simulate_viscous",
    "stability_limit",
]

Scheme = Literal["implicit", "newmark", "explicit"]
_SCHEMES = ("implicit", "newmark", "explicit")
_JACOBIANS = ("update", "frozen")


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


# -- the stepper ------------------------------------------------------------------------------
class _Scaled:
    """``a I`` as a matrix for ``@``."""

    def __init__(self, a: float) -> None:
        self.a = a

    def __matmul__(self, v: NDArray) -> NDArray:
        return self.a * v


class Stepper:
    """Steps of a damped network (module docstring).

    Built once per topology, free mask, ``dt``, dissipation and scheme; :meth:`step` takes
    the network each time (rest lengths and stiffnesses may change between steps, as in
    learning).

    Parameters
    ----------
    net : SpringNetwork
        Any network with the topology (for the sparsity pattern).
    viscosity : Viscosity or float
        The dissipation; a number is a node drag ``c`` alone (0 allowed with inertia).
    free : (n_nodes, 2) bool array
        Coordinates that move; the others follow what the caller puts in ``x_held``.
    dt : float
        Time step (> 0).
    inertia : bool
        Unit masses (True) or overdamped (False).
    scheme : {"implicit", "newmark", "explicit"}
        Newmark and explicit steps take node drag only.
    tol : float
        Each implicit step is solved to a net force ``<= tol * net.force_scale`` (or a
        Newton correction ``<= tol * mean(L)``).
    max_newton : int
        Newton iterations allowed per implicit step.
    jacobian : {"frozen", "update"}
        Keep a factorisation across steps while it serves, or refactorise every step.

    Attributes
    ----------
    factorisations, newton_iterations : int
        Sparse factorisations made and Newton corrections taken, over all steps.
    """

    def __init__(
        self,
        net: SpringNetwork,
        viscosity: Viscosity | float,
        free: NDArray,
        dt: float,
        *,
        inertia: bool = False,
        scheme: Scheme = "implicit",
        tol: float = 1e-10,
        max_newton: int = 100,
        jacobian: Literal["update", "frozen"] = "frozen",
    ) -> None:
        if scheme not in _SCHEMES:
            raise ValueError(f"scheme must be one of {_SCHEMES}, got {scheme!r}")
        if jacobian not in _JACOBIANS:
            raise ValueError(f"jacobian must be one of {_JACOBIANS}, got {jacobian!r}")
        vis = viscosity if isinstance(viscosity, Viscosity) else None
        self.viscosity = vis
        self.drag = vis.drag if vis else check.real("damping", viscosity, low=0)
        self.dashpot = vis.dashpot if vis else 0.0
        self.has_arm = vis is not None and vis.has_arm
        if scheme != "implicit" and (self.dashpot or self.has_arm):
            raise ValueError(f"the {scheme} scheme takes node drag only (no dashpots or arms)")
        if not inertia and self.drag == 0 and self.dashpot == 0:
            raise ValueError("damping must be > 0 when overdamped")
        self.dt = dt = check.real("dt", dt, low=0, low_open=True)
        self.free = np.asarray(free, dtype=bool)
        self.inertia = bool(inertia)
        self.scheme = scheme
        self.tol = float(tol)
        self.max_newton = int(max_newton)
        self.jacobian = jacobian
        mass = (4.0 if scheme == "newmark" else 1.0) / dt**2 if self.inertia else 0.0
        self.shift = (2.0 if scheme == "newmark" else 1.0) * self.drag / dt + mass
        self._held = ~self.free.ravel()
        if scheme != "explicit":
            self.pattern = pattern_for(net.springs, net.n_nodes, self.free, net.positions)
            self.rows = self.pattern.coords
        self._stored = None
        self.factorisations = 0
        self.newton_iterations = 0

    # -- forces and energy, arms included -------------------------------------------------
    def _arm_k(self, net: SpringNetwork) -> NDArray:
        return np.full(net.n_springs, self.viscosity.arm_stiffness)

    def gradient(self, net: SpringNetwork, x: NDArray, arm: NDArray | None = None) -> NDArray:
        """``grad E`` at ``x`` (n_nodes, 2), arms included, zero on held coordinates."""
        g = spring_gradient(x, net.springs, net.stiffness, net.rest_length)
        if arm is not None:
            g = g + spring_gradient(x, net.springs, self._arm_k(net), arm)
        g.ravel()[self._held] = 0.0
        return g

    def energy(self, net: SpringNetwork, x: NDArray, arm: NDArray | None = None) -> float:
        """Elastic energy of the springs and arms at ``x``."""
        e = spring_energy(x, net.springs, net.stiffness, net.rest_length)
        if arm is not None:
            e += spring_energy(x, net.springs, self._arm_k(net), arm)
        return e

    def _step_springs(self, net: SpringNetwork, arm: NDArray | None) -> tuple[NDArray, NDArray]:
        """Stiffness and rest length of the main spring joined with the eliminated arm."""
        k, L = net.stiffness, net.rest_length
        vis = self.viscosity
        if not self.has_arm:
            return k, L
        g = vis.arm_dashpot / self.dt
        k_eff = vis.arm_stiffness * g / (vis.arm_stiffness + g)
        kc = k + k_eff
        return kc, (k * L + k_eff * arm) / kc

    def arm_update(self, arm: NDArray, lengths: NDArray) -> NDArray:
        """``l1 = (g l0 + k2 r1) / (g + k2)``, the backward-Euler arm after a step."""
        vis = self.viscosity
        g = vis.arm_dashpot / self.dt
        return (g * arm + vis.arm_stiffness * lengths) / (g + vis.arm_stiffness)

    # -- one step --------------------------------------------------------------------------
    def step(
        self,
        net: SpringNetwork,
        x: NDArray,
        *,
        v: NDArray | None = None,
        arm: NDArray | None = None,
        x_held: NDArray | None = None,
        guess: NDArray | None = None,
        gradient: NDArray | None = None,
        t: float | None = None,
    ) -> tuple[NDArray, NDArray, NDArray | None]:
        """One step from positions ``x`` (n_nodes, 2).

        ``v``: velocities (inertial; default zero). ``arm``: (n_springs,) arm lengths (with
        arms). ``x_held``: positions at the end of the step whose held coordinates are
        imposed (default: held coordinates stay); their motion drives the dashpots.
        ``guess``: (n_nodes, 2) first Newton iterate for the free coordinates (default
        ``x``, inertial ``x + dt v``; a predictor such as ``2 x - x_previous`` saves
        iterations, the converged step is the same). ``gradient``: :meth:`gradient` at
        ``x`` if at hand (Newmark and explicit steps need it). ``t``: the step's end time,
        for error messages.

        Returns the new positions, velocities and arms. The velocities are ``(x1 - x) / dt``
        (Newmark inertial: ``2 (x1 - x) / dt - v``; explicit: the update's velocity).
        """
        dt, scheme = self.dt, self.scheme
        if self.has_arm and arm is None:
            raise ValueError("this viscosity has Maxwell arms: pass arm (n_springs,)")
        v0 = v if self.inertia and v is not None else np.zeros_like(x)
        if scheme != "implicit" and gradient is None:
            gradient = self.gradient(net, x)
        if scheme == "explicit":
            c = self.drag
            v1 = v0 + dt * (-c * v0 - gradient) if self.inertia else -gradient / c
            v1.ravel()[self._held] = 0.0
            return x + dt * v1, v1, None
        rows = self.rows
        x1 = x.copy() if x_held is None else np.where(self.free, x, x_held)
        if scheme == "newmark":  # b = a (x_hat - x), x_hat the explicit half of the step
            b = (4.0 / dt * v0 - gradient if self.inertia else -gradient).ravel()[rows]
        else:
            gamma = self.dashpot
            b = dashpot_force(x, net, gamma, (x1 - x) / dt).ravel()[rows] if gamma else 0.0
            if self.inertia:
                b = b + v0.ravel()[rows] / dt
        if guess is None and self.inertia:
            guess = x1 + dt * v0
        y = x1 if guess is None else np.where(self.free, guess, x1)
        kc, Lc = self._step_springs(net, arm)
        if self.dashpot:
            blocks = dashpot_blocks(x, net.springs, self.dashpot / dt)
            D = self.pattern.assemble(blocks, self.shift)
        else:  # drag (and mass) only: D = shift I, no assembly
            D = _Scaled(self.shift)
        where = "implicit step" if t is None else f"implicit step at t={t:g}"
        y = self._solve(net, kc, Lc, D, x, b, y, where)
        v1 = (y - x) / dt
        if scheme == "newmark" and self.inertia:
            v1 = 2.0 * v1 - v0
        new_arm = self.arm_update(arm, net.lengths(y)) if self.has_arm else None
        return y, v1, new_arm

    def _solve(self, net, kc, Lc, D, x0, b, y, where: str) -> NDArray:
        """Minimise ``Phi(y) = E_step(y) + s^T D s / 2 - b.s``, ``s = y - x0``, over the free
        coordinates from ``y``: Newton with an Armijo line search; a kept factorisation
        serves (chord iterations) while its correction cuts the net force 4-fold."""
        springs, rows = net.springs, self.rows
        x0_rows = x0.ravel()[rows]

        def grad(z: NDArray) -> NDArray:
            g = spring_gradient(z, springs, kc, Lc).ravel()[rows]
            return g + D @ (z.ravel()[rows] - x0_rows) - b

        force_tol = self.tol * net.force_scale
        length_tol = self.tol * (float(np.mean(net.rest_length)) if net.n_springs else 1.0)
        if self.jacobian == "update":
            self._stored = None
        g = grad(y)
        gnorm = float(np.max(np.abs(g))) if g.size else 0.0
        fresh = False  # self._stored was factorised at the current y
        for _ in range(self.max_newton):
            if gnorm <= force_tol:
                break
            if self._stored is None:
                self._stored = self._factor(y, springs, kc, Lc, D, where)
                fresh = True
            d = -self._stored.solve(g)
            s0 = y.ravel()[rows] - x0_rows
            slope = float(g @ d)
            alpha = 1.0
            while True:
                z = y.copy()
                z.ravel()[rows] += alpha * d
                gz = grad(z)
                gnz = float(np.max(np.abs(gz)))
                if not fresh:  # a kept factor: keep the step only if it cuts 4-fold
                    ok = np.isfinite(gnz) and gnz <= 0.25 * gnorm
                    break
                s = alpha * d
                dphi = (
                    spring_energy_change(z, y, springs, kc, Lc)
                    + 0.5 * float(s @ (D @ (s + 2.0 * s0)))
                    - float(np.sum(b * s))
                )
                ok = np.isfinite(gnz) and (dphi <= 1e-4 * alpha * slope or gnz <= 0.5 * gnorm)
                if ok:
                    break
                alpha *= 0.5
                if alpha < 1e-12:
                    raise RuntimeError(
                        f"{where}: line search failed (residual {gnorm:.3e}); reduce dt"
                    )
            if not ok:  # refactorise here and take a Newton step
                self._stored = self._factor(y, springs, kc, Lc, D, where)
                fresh = True
                continue
            self.newton_iterations += 1
            y, g, gnorm = z, gz, gnz
            fresh = False
            if alpha == 1.0 and float(np.max(np.abs(d))) <= length_tol:
                break
        else:
            if gnorm > force_tol:
                raise RuntimeError(
                    f"{where} did not converge in {self.max_newton} Newton iterations "
                    f"(residual {gnorm:.3e} > {force_tol:.3e}); reduce dt"
                )
        return y

    def _factor(self, y, springs, kc, Lc, D, where: str):
        """Factorise ``H + D`` at ``y``; if indefinite, with the tangentially clipped Hessian.

        A spring compressed below its rest length has negative tangential stiffness
        ``k (1 - L/r)`` (buckling). When that makes ``H + D`` indefinite (large ``dt``,
        strong compression), the step uses ``k max(0, 1 - L/r)``, positive semi-definite,
        so the correction is a descent direction of ``Phi``; the line search does the rest.
        """
        for clip in (False, True):
            L = Lc
            if clip:
                L = np.minimum(Lc, vector_lengths(spring_vectors(y, springs)))
            blocks = spring_hessian_blocks(y, springs, kc, L)
            if isinstance(D, _Scaled):
                W = self.pattern.assemble(blocks, shift=D.a)
            else:
                W = self.pattern.assemble(blocks) + D
            factor = factor_spd(W, ordered=self.pattern.ordered)
            self.factorisations += 1
            if factor is not None:
                return factor
        raise RuntimeError(f"{where}: the step matrix could not be factorised")


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
    tol, jacobian, max_newton
        Implicit steps: see :class:`Stepper`.

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
    x, free = _boundary(net, pinned, prescribed, clamped, x0)
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
    x, free = _boundary(net, pinned, prescribed, clamped, x0)
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
