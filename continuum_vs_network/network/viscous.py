"""Visco-elastic spring networks: spring dashpots (Kelvin-Voigt) and Maxwell arms (standard
linear solid), beside the node drag of Eq. 10.

Forces on the nodes (unit masses when ``inertia=True``)::

    m x'' = -c x' - D_kv(x) x' - grad_x E(x, l)

* node drag ``c`` (``drag``) against the lab frame, as in :mod:`.dynamics`;
* a dashpot of coefficient ``gamma`` (``dashpot``) along every spring: the force
  ``gamma dr/dt`` along the spring, so ``D_kv = sum_j gamma e_j e_j^T`` over the spring's
  two nodes (``e_j`` the unit vector, signs as in the Hessian) - a Kelvin-Voigt network,
  the lattice of :func:`~continuum_vs_network.continuum.materials.lattice_viscous_lame`;
* a Maxwell arm on every spring: a spring ``k2`` (``arm_stiffness``) in series with a
  dashpot ``gamma2`` (``arm_dashpot``); its internal variable ``l_j`` is the length at which
  the arm carries no force, so the energy is ``E = sum k (r - L)^2/2 + sum k2 (r - l)^2/2``
  and ``gamma2 l' = k2 (r - l)`` (a standard linear solid per spring, arm relaxation time
  ``gamma2 / k2``). The same equation with ``k2 = k`` and ``gamma2 = 1 / alpha`` is
  prospective configuration in time (``L' = alpha k (r - L)``).

Time stepping (:class:`Stepper`): backward Euler on the whole first-order system, the
dashpot matrix taken at the start of each step (linearly implicit in the dashpots, exact
for small displacements). The internal variables are eliminated in closed form: over a
step the arm acts as a spring of stiffness ``k2 g / (k2 + g)`` (``g = gamma2 / dt``) and
rest length ``l0``, which joins the main spring to one spring, so every step is the
minimisation of ``Phi(x) = E_step(x) + s^T A s / 2 - b.s`` (``s`` the step,
``A = (c I + D_kv) / dt (+ I / dt^2)``) by Newton with an Armijo line search, and
``l1 = (g l0 + k2 r1) / (g + k2)``. L-stable: any ``dt`` is stable, stiff rods included.

A displacement step of held nodes at ``t = 0`` (before the first frame) drives the
dashpots by an impulse: the free nodes jump by ``-D_ff^{-1} D_fb Delta_b`` (overdamped;
inertial: the velocity jumps by ``-D_fb Delta_b``) with the arm dashpots still. A pure
Kelvin-Voigt network (``c = 0``) then sits at its elastic equilibrium at every ``t > 0``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from ..linalg.spd import factor_spd
from .constraints import Pins
from .dynamics import Trajectory, _boundary
from .energy import (
    HessianPattern,
    spring_energy,
    spring_energy_change,
    spring_gradient,
    spring_hessian_blocks,
)
from .lagrangian import pattern_for
from .model import SpringNetwork, spring_vectors, unit_vectors, vector_lengths

__all__ = [
    "Stepper",
    "Viscosity",
    "dashpot_force",
    "dashpot_matrix",
    "linear_system",
    "simulate_viscous",
]


@dataclass(frozen=True)
class Viscosity:
    """Dissipation of a network (all >= 0; the same for every spring).

    Attributes
    ----------
    drag : float
        Node drag ``c`` (force per velocity).
    dashpot : float
        Kelvin-Voigt dashpot ``gamma`` along every spring (force per rate of length change).
    arm_stiffness, arm_dashpot : float
        Maxwell arm ``k2`` (force per length) and ``gamma2`` (force per rate); both > 0 or
        both 0 (no arm). Arm relaxation time ``gamma2 / k2``.
    """

    drag: float = 1.0
    dashpot: float = 0.0
    arm_stiffness: float = 0.0
    arm_dashpot: float = 0.0

    def __post_init__(self) -> None:
        for name in ("drag", "dashpot", "arm_stiffness", "arm_dashpot"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {getattr(self, name)}")
            object.__setattr__(self, name, v)
        if (self.arm_stiffness > 0) != (self.arm_dashpot > 0):
            raise ValueError(
                "arm_stiffness and arm_dashpot must both be > 0 (a Maxwell arm) or both 0, "
                f"got {self.arm_stiffness} and {self.arm_dashpot}"
            )
        if self.drag == 0 and self.dashpot == 0:
            raise ValueError("drag and dashpot are both 0: no dissipation on the nodes")

    @property
    def has_arm(self) -> bool:
        return self.arm_stiffness > 0

    @property
    def arm_time(self) -> float:
        """Relaxation time ``gamma2 / k2`` of an arm (inf without one)."""
        return self.arm_dashpot / self.arm_stiffness if self.has_arm else math.inf


def dashpot_blocks(x: NDArray, springs: NDArray, gamma: float) -> NDArray:
    """Per-spring blocks ``gamma e e^T`` (n_springs, 2, 2): the Hessian blocks at ``L = r``."""
    r = vector_lengths(spring_vectors(x, springs))
    return spring_hessian_blocks(x, springs, np.full(len(springs), float(gamma)), r)


def dashpot_matrix(
    x: ArrayLike, net: SpringNetwork, gamma: float, *, pattern: HessianPattern | None = None
) -> sp.csr_matrix:
    """Kelvin-Voigt damping matrix ``sum_j gamma e_j e_j^T`` (2 n_nodes square, or the
    ``pattern``'s free coordinates), force per velocity."""
    x = np.asarray(x, dtype=np.float64)
    pattern = pattern or HessianPattern(net.springs, net.n_nodes)
    return pattern.assemble(dashpot_blocks(x, net.springs, gamma))


def dashpot_force(x: ArrayLike, net: SpringNetwork, gamma: float, v: ArrayLike) -> NDArray:
    """Dashpot force ``-D_kv(x) v`` on every node (n_nodes, 2) for velocities ``v``."""
    x = np.asarray(x, dtype=np.float64)
    e, _ = unit_vectors(x, net.springs)
    dv = spring_vectors(np.asarray(v), net.springs)
    rate = gamma * np.einsum("ij,ij->i", e, dv)
    # the force on b is -rate e, on a +rate e: the gradient of a spring with tension `rate`
    t = rate[:, None] * e
    f = np.zeros_like(x)
    np.add.at(f, net.springs[:, 1], -t)
    np.add.at(f, net.springs[:, 0], t)
    return f


def linear_system(
    net: SpringNetwork, viscosity: Viscosity, free: ArrayLike
) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Stiffness and damping ``(K, C)`` of the dynamics linearised about ``net.positions``.

    Unknowns: the free coordinates (``free``: (n_nodes, 2) bool, in ``ravel`` order), then
    one arm variable per spring when there are arms (arms relaxed, ``l = r``). ``C z' +
    K z = 0``; both symmetric, so the relaxation times are ``1 / eig(K, C)`` (pass them to
    :func:`~continuum_vs_network.continuum.viscoelastic.slowest_relaxation_time`).
    """
    x = net.positions
    free = np.asarray(free, dtype=bool)
    pattern = HessianPattern(net.springs, net.n_nodes, free)
    H = pattern.assemble(spring_hessian_blocks(x, net.springs, net.stiffness, net.rest_length))
    D = pattern.assemble(dashpot_blocks(x, net.springs, viscosity.dashpot), viscosity.drag)
    if not viscosity.has_arm:
        return H.tocsr(), D.tocsr()
    k2, g2 = viscosity.arm_stiffness, viscosity.arm_dashpot
    e, _ = unit_vectors(x, net.springs)
    idx = pattern.free_index
    rows, cols, vals = [], [], []
    for node_col, sign in ((1, 1.0), (0, -1.0)):
        for c in range(2):
            col = idx[2 * net.springs[:, node_col] + c]
            keep = col >= 0
            rows.append(np.flatnonzero(keep))
            cols.append(col[keep])
            vals.append(sign * e[keep, c])
    B = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(net.n_springs, pattern.size),
    )
    I_s = sp.identity(net.n_springs, format="csr")
    K = sp.bmat([[H + k2 * (B.T @ B), -k2 * B.T], [-k2 * B, k2 * I_s]], format="csr")
    C = sp.bmat([[D, None], [None, g2 * I_s]], format="csr")
    return K, C


class _Scaled:
    """``a I`` as a matrix for ``@``."""

    def __init__(self, a: float) -> None:
        self.a = a

    def __matmul__(self, v: NDArray) -> NDArray:
        return self.a * v


class Stepper:
    """Backward-Euler steps of a visco-elastic network (see the module docstring).

    Built once per topology, free mask and ``dt``; :meth:`step` takes the network each
    time (rest lengths and stiffnesses may change between steps, as in learning).

    Parameters
    ----------
    springs_net : SpringNetwork
        Any network with the topology (for the sparsity pattern).
    viscosity : Viscosity
    free : (n_nodes, 2) bool array
        Coordinates that move; the others follow what the caller puts in ``x_held``.
    dt : float
        Time step (> 0).
    inertia : bool
        Unit masses (True) or overdamped (False).
    tol : float
        Each step is solved to a net force ``<= tol * net.force_scale``.
    max_newton : int
        Newton iterations allowed per step.
    reuse : bool
        Keep the last factorisation across iterations and steps while a correction with it
        cuts the net force at least 4-fold (chord iterations; the converged state is the
        same, only the cost changes); otherwise refactorise at the current state.
    """

    def __init__(
        self,
        springs_net: SpringNetwork,
        viscosity: Viscosity,
        free: NDArray,
        dt: float,
        *,
        inertia: bool = False,
        tol: float = 1e-10,
        max_newton: int = 100,
        reuse: bool = True,
    ) -> None:
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be finite and > 0, got {dt}")
        self.viscosity = viscosity
        self.free = np.asarray(free, dtype=bool)
        self.dt = dt
        self.inertia = bool(inertia)
        self.tol = float(tol)
        self.max_newton = int(max_newton)
        self.pattern = pattern_for(
            springs_net.springs, springs_net.n_nodes, self.free, springs_net.positions
        )
        self.rows = self.pattern.coords
        self.ordered = self.pattern.ordered
        self.reuse = bool(reuse)
        self._stored = None
        self.factorisations = 0
        self.newton_iterations = 0

    def _step_springs(self, net: SpringNetwork, arm: NDArray | None) -> tuple[NDArray, NDArray]:
        """Stiffness and rest length of the main spring joined with the eliminated arm."""
        k, L = net.stiffness, net.rest_length
        vis = self.viscosity
        if not vis.has_arm:
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

    def step(
        self,
        net: SpringNetwork,
        x: NDArray,
        *,
        x_held: NDArray | None = None,
        v: NDArray | None = None,
        arm: NDArray | None = None,
        guess: NDArray | None = None,
    ) -> tuple[NDArray, NDArray, NDArray | None]:
        """One step from positions ``x`` (n_nodes, 2).

        ``x_held``: positions at the end of the step whose held coordinates are imposed
        (default: held coordinates stay); their motion drives the dashpots. ``v``:
        velocities (inertial). ``arm``: (n_springs,) arm lengths (with arms). ``guess``:
        (n_nodes, 2) first Newton iterate for the free coordinates (default ``x``; a
        predictor such as ``2 x - x_previous`` saves iterations, the converged step is
        the same). Returns the new positions, velocities ``(x1 - x) / dt`` and arms.
        """
        vis, dt, rows = self.viscosity, self.dt, self.rows
        springs = net.springs
        if vis.has_arm and arm is None:
            raise ValueError("this viscosity has Maxwell arms: pass arm (n_springs,)")
        x1 = x.copy() if x_held is None else np.where(self.free, x, x_held)
        held_v = (x1 - x) / dt  # zero on free coordinates
        b = dashpot_force(x, net, vis.dashpot, held_v).ravel()[rows] if vis.dashpot else 0.0
        if self.inertia:
            vv = np.zeros_like(x) if v is None else v
            b = b + vv.ravel()[rows] / dt
        kc, Lc = self._step_springs(net, arm)
        shift = vis.drag / dt + (1.0 / dt**2 if self.inertia else 0.0)
        if vis.dashpot:
            D = self.pattern.assemble(dashpot_blocks(x, springs, vis.dashpot / dt), shift)
        else:  # drag (and mass) only: D = shift I, no assembly
            D = _Scaled(shift)
        x0_rows = x.ravel()[rows]

        def grad(y: NDArray) -> NDArray:
            g = spring_gradient(y, springs, kc, Lc).ravel()[rows]
            return g + D @ (y.ravel()[rows] - x0_rows) - b

        force_tol = self.tol * net.force_scale
        length_tol = self.tol * float(np.mean(net.rest_length))
        y = x1 if guess is None else np.where(self.free, guess, x1)
        g = grad(y)
        gnorm = float(np.max(np.abs(g))) if g.size else 0.0
        fresh = False  # self._stored was factorised at the current y
        for _ in range(self.max_newton):
            if gnorm <= force_tol:
                break
            if self._stored is None or (not self.reuse and not fresh):
                self._stored = self._factor(y, springs, kc, Lc, D)
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
                if not fresh:  # a reused factor: keep the step only if it cuts 4-fold
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
                    raise RuntimeError(f"viscous step: line search failed (residual {gnorm:.3e})")
            if not ok:  # refactorise here and take a Newton step
                self._stored = self._factor(y, springs, kc, Lc, D)
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
                    f"viscous step did not converge in {self.max_newton} Newton iterations "
                    f"(residual {gnorm:.3e} > {force_tol:.3e}); reduce dt"
                )
        new_arm = None
        if vis.has_arm:
            new_arm = self.arm_update(arm, net.lengths(y))
        return y, (y - x) / dt, new_arm

    def _factor(self, y, springs, kc, Lc, D):
        for clip in (False, True):
            L = Lc
            if clip:  # compressed springs: tangentially clipped, positive semi-definite
                r = vector_lengths(spring_vectors(y, springs))
                L = np.minimum(Lc, r)
            blocks = spring_hessian_blocks(y, springs, kc, L)
            if isinstance(D, _Scaled):
                W = self.pattern.assemble(blocks, shift=D.a)
            else:
                W = self.pattern.assemble(blocks) + D
            factor = factor_spd(W, ordered=self.ordered)
            self.factorisations += 1
            if factor is not None:
                return factor
        raise RuntimeError("viscous step: the step matrix could not be factorised")


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

    Boundary conditions as in :func:`~.dynamics.simulate` (held nodes stepped at ``t = 0``
    with the dashpot impulse, module docstring). ``arm0``: starting arm lengths
    (default: the spring lengths at ``x0``, arms relaxed). Returns a
    :class:`~.dynamics.Trajectory` whose ``arm`` holds the arm lengths (T, n_springs) and
    whose ``residual`` is the net force (springs and arms) on the free coordinates.
    """
    if not isinstance(viscosity, Viscosity):
        raise ValueError(f"viscosity must be a Viscosity, got {type(viscosity).__name__}")
    t_end = float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be finite and > 0, got {t_end}")
    if int(record_every) != record_every or record_every < 1:
        raise ValueError(f"record_every must be an integer >= 1, got {record_every}")
    t0 = time.perf_counter()
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
    k2 = viscosity.arm_stiffness

    def residual(y: NDArray, a: NDArray | None) -> float:
        g = spring_gradient(y, net.springs, net.stiffness, net.rest_length)
        if a is not None:
            g = g + spring_gradient(y, net.springs, np.full(net.n_springs, k2), a)
        return float(np.max(np.abs(g[free]))) if free.any() else 0.0

    def energy(y: NDArray, a: NDArray | None) -> float:
        e = spring_energy(y, net.springs, net.stiffness, net.rest_length)
        if a is not None:
            e += spring_energy(y, net.springs, np.full(net.n_springs, k2), a)
        return e

    frames = []

    def record(t: float) -> None:
        frames.append(
            (
                t,
                x.copy(),
                v.copy(),
                energy(x, arm),
                0.5 * float(np.sum(v * v)),
                residual(x, arm),
                time.perf_counter() - t0,
                None if arm is None else arm.copy(),
            )
        )

    record(0.0)
    n_steps = max(1, int(np.ceil(t_end / stepper.dt - 1e-9)))
    for step in range(1, n_steps + 1):
        x, v, arm = stepper.step(net, x, v=v if inertia else None, arm=arm)
        if step % record_every == 0 or step == n_steps:
            record(step * stepper.dt)
    cols = list(zip(*frames))
    arrays = [np.asarray(c) for c in cols[:7]]
    arms = None if arm is None else np.asarray(cols[7])
    for a in [*arrays, arms, free]:
        if a is not None:
            a.setflags(write=False)
    times, pos, vel, en, kin, res, secs = arrays
    return Trajectory(
        times=times,
        positions=pos,
        velocities=vel,
        energy=en,
        kinetic=kin,
        residual=res,
        seconds=secs,
        free=free,
        scheme="implicit",
        dt=stepper.dt,
        damping=viscosity.drag,
        inertia=bool(inertia),
        factorisations=stepper.factorisations,
        arm=arms,
    )
