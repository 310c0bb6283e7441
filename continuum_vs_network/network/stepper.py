"""One damped-dynamics stepper for a spring network: backward Euler, Newmark or explicit
steps with node drag, Kelvin-Voigt dashpots and Maxwell arms (:class:`~.viscous.Viscosity`);
:func:`~.dynamics.simulate` and :func:`~.dynamics.simulate_viscous` are loops over it.

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
the first correction of every step, and at every correction after one that cut the net
force less than 4-fold (full Newton for the rest of the step). The converged state is
the same, only the cost changes. Very stiff springs (rods of k = 1e10 among k ~ 1) that
must rotate during a step make Newton zig-zag along a curved valley (~60 iterations for a
step; hence ``max_newton=200`` in :func:`~.dynamics.simulate`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..linalg.spd import factor_spd
from .energy import (
    spring_energy,
    spring_energy_change,
    spring_gradient,
    spring_hessian_blocks,
)
from .lagrangian import pattern_for
from .model import SpringNetwork, spring_vectors, vector_lengths
from .viscous import Viscosity, dashpot_blocks, dashpot_force

__all__ = ["Stepper"]

Scheme = Literal["implicit", "newmark", "explicit"]
_SCHEMES = ("implicit", "newmark", "explicit")
_JACOBIANS = ("update", "frozen")


# -- the stepper ------------------------------------------------------------------------------
class _Scaled:
    """``a I`` as a matrix for ``@``."""

    def __init__(self, a: float) -> None:
        self.a = a

    def __matmul__(self, v: NDArray) -> NDArray:
        return self.a * v


class Stepper:
    """Steps of a damped network (the module docstring).

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
        serves (chord iterations) while its correction cuts the net force 4-fold. With
        ``jacobian="update"``, once a correction cuts it less, every further iteration of
        the step refactorises (full Newton)."""
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
        newton = False  # "update": full Newton for the rest of the step
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
            # "update": a correction that does not cut the force 4-fold means the step is
            # nonlinear (large rotations, stiff springs): full Newton from here on
            newton = self.jacobian == "update" and (newton or gnz > 0.25 * gnorm)
            y, g, gnorm = z, gz, gnz
            fresh = False
            if alpha == 1.0 and float(np.max(np.abs(d))) <= length_tol:
                break
            if newton and gnorm > force_tol:
                self._stored = self._factor(y, springs, kc, Lc, D, where)
                fresh = True
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
