"""Damped steps of a learnable body with clamped material springs (learning in time).

The continuum side of :func:`~continuum_vs_network.learning.physical_time.learn_in_time`:
the body moves against a damping ``C`` (substrate drag and/or Kelvin-Voigt viscosity,
:class:`~.damping.Damping`) and, with a Maxwell arm (a standard linear solid,
:mod:`.maxwell`), against the arm's stress ``S (B u - e)`` with an internal strain ``e`` per
quadrature point, while its source material springs are held at the task's strains and,
in a clamped copy, its targets at given strains::

    C du/dt = f - K u - B^T S (B u - e) - G_c^T lambda,   V de/dt = S (B u - e),   G_c u = v

Backward Euler, clamps exact, the internal strain eliminated (:func:`.maxwell.arm_step`:
``S (B u1 - e1) = S_dt (B u1 - e0)``): ``(C/dt + K + B^T S_dt B) u1 + G_c^T lambda = C/dt u0
+ f + B^T S_dt e0``, then ``e1 = B u1 - P (B u1 - e0)``. The matrix ``A = C/dt + K + B^T
S_dt B`` (fixed DOFs removed) is factorised once per modulus field and ``Z = A^-1 G^T``
formed for every source and target functional, so a step with any clamp set is one solve
and a dense system the size of the clamp set (the Schur-complement reuse of
:mod:`.learning_states`). Eigenstrain learning never changes ``A``: a whole run factorises
once. L-stable: any ``dt``; ``dt = inf`` is the equilibrium (arms relaxed, no force).
Every moving copy carries its own internal strains (:meth:`DampedStepper.rest_arm`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["DampedStepper", "body_relaxation_time"]


class DampedStepper:
    """Backward-Euler steps of a learnable body under a task's clamps (module docstring).

    Parameters
    ----------
    medium : LearnableBody
        Any body with the mesh (the matrices are rebuilt when the modulus field changes).
    task : MaterialTask
    damping : Damping
        Drag and/or Kelvin-Voigt viscosity (at least one), optionally a Maxwell arm.
    dt : float
        Time step (> 0; ``math.inf``: every step an equilibrium, arms relaxed).
    """

    def __init__(self, medium, task, damping, dt: float) -> None:
        from .damping import Damping, damping_matrix
        from .maxwell import arm_step, damping_arm
        from .probes import material_spring_probe

        if not isinstance(damping, Damping):
            raise ValueError(f"damping must be a Damping, got {type(damping).__name__}")
        if damping.rayleigh_mass > 0 or damping.rayleigh_stiffness > 0:
            raise ValueError(
                "damping: learning in time on a body takes drag, Kelvin-Voigt viscosity and "
                "a Maxwell arm, not Rayleigh damping"
            )
        dt = float(dt)
        if not (dt > 0):
            raise ValueError(f"dt must be > 0, got {dt}")
        keep = np.ones(medium.n_dofs, dtype=bool)
        keep[task.fixed] = False
        self.free = np.flatnonzero(keep)
        C = damping_matrix(medium.body, damping)[self.free][:, self.free].tocsr()
        if C.nnz == 0 and math.isfinite(dt):
            raise ValueError("damping must have a drag or a viscosity > 0")
        self.C_dt = C / dt if math.isfinite(dt) else None
        self.arm = None  # the eliminated arm step; None without an arm or at equilibrium
        self._arm_matrix = None
        if damping.has_arm and math.isfinite(dt):
            self.arm = arm_step(damping_arm(medium.body, damping), dt)
            Bf = self.arm.operators.strain.tocsc()[:, self.free]
            self._arm_pull = (Bf.T @ self.arm.stiffness).tocsr()  # B^T S_dt, free rows
            self._arm_matrix = (self._arm_pull @ Bf).tocsr()
        probe = material_spring_probe(
            medium.body,
            np.vstack([task.source_a, task.target_a]),
            np.vstack([task.source_b, task.target_b]),
            task.radius,
        )
        self.G = probe.operator.tocsc()[:, self.free].tocsr()
        self.n_sources = task.n_sources
        self.source_strain = np.asarray(task.source_strain, float)
        self.dt = dt
        self.factorisations = 0
        self._key = None
        self._load_key = None
        self._task = None if math.isfinite(dt) else task  # equilibrium: the free states' K

    def rest_arm(self, u: ArrayLike) -> NDArray | None:
        """Internal strains (3 n_q,) of arms relaxed at ``u`` (``B u``); None without arms."""
        if self.arm is None:
            return None
        return self.arm.operators.strain @ np.asarray(u, float)

    def _system(self, medium):
        """``(factor, Z, S)`` of the step matrix at the medium's modulus field (kept)."""
        if self._key is not medium.modulus:
            if self._task is not None:
                # equilibrium: A = K, the free states' factorisation (the same numbers),
                # whose load solve the error of learning in time makes for the eigenstrain
                shared = self._shared(medium)
                self._sys = (shared.factor, shared.Z, np.asarray(shared.S))
            else:
                self._sys = self._factorise(medium)
            self._key = medium.modulus
            self.factorisations += 1
        return self._sys

    def _factorise(self, medium):
        """``(factor, Z, S)`` of ``A = K + C / dt (+ arm)`` on the free DOFs."""
        from ..linalg.kkt import factor_spd

        A = medium.stiffness()[self.free][:, self.free]
        if self.C_dt is not None:
            A = A + self.C_dt
        if self._arm_matrix is not None:
            A = A + self._arm_matrix
        factor = factor_spd(A.tocsr(), certify=False)
        if factor is None:
            raise ValueError(
                "the step matrix is not positive definite: fix enough DOFs to stop rigid "
                "motion or add drag"
            )
        Z = np.asarray(factor.solve(self.G.T.toarray()))
        return factor, Z, np.asarray(self.G @ Z)

    def _shared(self, medium):
        """At equilibrium: the free states' cached system of the medium and task."""
        from .learning_states import cached_system

        return cached_system(medium, self._task, None)

    def _load(self, medium, factor) -> tuple[NDArray, NDArray | None]:
        """The load on the free DOFs, and at equilibrium (no damping, no arm: the right-hand
        side is the load) its solve; kept per eigenstrain and modulus field (the copies of
        a step share them)."""
        if self._task is not None:
            u0, f = self._shared(medium).u0(medium)
            return f, u0
        key = (medium.eigenstrain, medium.modulus)  # read-only: a new field is a new array
        if self._load_key is None or any(a is not b for a, b in zip(self._load_key, key)):
            f = medium.load()[self.free]
            alone = self.C_dt is None and self.arm is None
            self._load_key = key
            self._load_value = (f, np.asarray(factor.solve(f)) if alone else None)
        return self._load_value

    def step(
        self,
        medium,
        u: ArrayLike,
        target_strain: ArrayLike | None = None,
        *,
        arm: ArrayLike | None = None,
    ) -> tuple[NDArray, NDArray | None]:
        """The displacement (n_dofs,) and arms' internal strains (3 n_q,; None without
        arms) one step after ``(u, arm)``: sources held at the task's strains, targets at
        ``target_strain`` (n_targets,) or free (None). ``arm`` is required with arms
        (:meth:`rest_arm` for arms relaxed at a state)."""
        factor, Z, S = self._system(medium)
        u = np.asarray(u, float)
        rhs, z = self._load(medium, factor)
        if self.C_dt is not None:
            rhs = rhs + self.C_dt @ u[self.free]
        if self.arm is not None:
            n_int = self.arm.operators.n_internal
            if arm is None or np.shape(arm) != (n_int,):
                got = None if arm is None else np.shape(arm)
                raise ValueError(
                    f"arm must be the arms' internal strains, shape ({n_int},) "
                    f"(rest_arm(u) for arms relaxed at u), got {got}"
                )
            arm = np.asarray(arm, float)
            rhs = rhs + self._arm_pull @ arm
        if z is None:
            z = np.asarray(factor.solve(rhs))
        ns = self.n_sources
        if target_strain is None:
            rows, values = np.arange(ns), self.source_strain
        else:
            t = np.asarray(target_strain, float)
            rows = np.arange(ns + t.size)
            values = np.concatenate([self.source_strain, t])
        # every probe row at once, then the held ones: slicing the sparse rows each step cost
        # more than the product (the same row sums, so the same numbers)
        strains = (self.G @ z)[rows]
        uf = z - Z[:, rows] @ np.linalg.solve(S[np.ix_(rows, rows)], strains - values)
        out = np.zeros(medium.n_dofs)
        out[self.free] = uf
        new_arm = None
        if self.arm is not None:
            new_arm = self.arm.update(self.arm.operators.strain @ out, arm)
        if not (np.all(np.isfinite(out)) and (new_arm is None or np.all(np.isfinite(new_arm)))):
            raise FloatingPointError("the damped step returned non-finite displacements")
        return out, new_arm

    def target_strain(self, u: ArrayLike) -> NDArray:
        """Strains of the target material springs at ``u``, (n_targets,)."""
        return (self.G @ np.asarray(u, float)[self.free])[self.n_sources :]


def body_relaxation_time(
    medium, task, damping, *, fraction: float = 1e-2, measure: str = "target"
) -> float:
    """Relaxation time of a body after the task's source step (time units).

    The body starts at its equilibrium with the sources off (at zero strain) and jumps at
    ``t = 0`` onto the source clamps by the ``C``-weighted projection (the limit of a
    vanishing first step: ``min (u - u0)^T C (u - u0)`` subject to ``G_s u = S_s``), then
    relaxes (backward Euler, 200-step runs doubled in length until 3 times longer than
    the time). Maxwell arms start relaxed at ``u0`` and hold still through the jump (their
    dashpots); the end is the clamped equilibrium (arms relaxed). The criteria are the network's
    (:func:`~continuum_vs_network.learning.physical_time.network_relaxation_time`):

    ``measure="target"`` (default): the target strains stay within ``fraction`` (1 %) of
    their total change (from ``u0`` to the clamped equilibrium) of that equilibrium
    (:func:`~continuum_vs_network.network.dynamics.settling_time`).
    ``measure="force"``: the net force on the free DOFs, the damping force ``C u'`` (at
    ``t = 0+`` from the clamped velocity ``[C G_s^T; G_s 0] [u'; mu] = [f - K u; 0]``, then
    ``C (u1 - u0) / dt`` of each step), stays below ``fraction`` of its largest component
    at the start (arm forces included).
    """
    import dataclasses

    from ..linalg.kkt import factor_kkt
    from ..network.dynamics import settling_time
    from .damping import damping_matrix

    if measure not in ("target", "force"):
        raise ValueError(f"measure must be 'target' or 'force', got {measure!r}")
    off = dataclasses.replace(task, source_strain=np.zeros(task.n_sources))
    u0 = medium.free_state(off).u
    probe = DampedStepper(medium, task, damping, 1.0)
    free = probe.free
    C = damping_matrix(medium.body, damping)[free][:, free].tocsc()
    Gs = probe.G[: task.n_sources]
    kkt = factor_kkt(C, Gs)
    dx, _ = kkt.solve(np.zeros(free.size), task.source_strain - Gs @ u0[free])
    start = u0.copy()
    start[free] += dx
    s_start = probe.target_strain(u0)
    s_end = DampedStepper(medium, task, damping, math.inf).step(medium, u0)[0]
    s_end = probe.target_strain(s_end)
    K = medium.stiffness()[free][:, free]
    arm0 = probe.rest_arm(u0)
    push = medium.load()[free] - K @ start[free]
    if arm0 is not None:  # the arm as a spring (S_dt -> S as dt -> 0) from its rest
        ops = probe.arm.operators
        push = push - (ops.strain.T @ (ops.stiffness @ (ops.strain @ start - arm0)))[free]
    v0, _ = kkt.solve(push)
    f0 = float(np.max(np.abs(C @ v0)))
    if f0 == 0:
        return 0.0
    k = float(np.mean(medium.modulus)) * float(np.max(medium.body.mu))
    eta = float(damping.drag) + float(damping.viscous_mu) + float(damping.arm_viscous_mu)
    t_end = 4.0 * eta / max(k, 1e-300) * max(medium.n_dofs, 8) ** 0.5
    for _ in range(30):
        stepper = DampedStepper(medium, task, damping, t_end / 200)
        u, arm, force, strains = start, arm0, [], [probe.target_strain(start)]
        for _ in range(200):
            u1, arm = stepper.step(medium, u, arm=arm)
            force.append(float(np.max(np.abs(C @ (u1 - u)[free]))) / stepper.dt)
            strains.append(probe.target_strain(u1))
            u = u1
        if measure == "target":
            tau = settling_time(
                stepper.dt * np.arange(201), np.array(strains), s_start, s_end, fraction
            )
            if 0 < tau < 10 * stepper.dt:  # settled within ten steps: too coarse
                t_end /= 8.0
                continue
            if 3.0 * tau <= t_end:
                return tau
            t_end *= 2.0
            continue
        t = stepper.dt * np.arange(1, 201)
        d = np.array(force)
        above = np.flatnonzero(d > fraction * f0)
        if above.size < 10:  # relaxed within ten steps: too coarse, shorten the run
            t_end /= 8.0
            continue
        if above[-1] + 1 < t.size:  # linear between the last frame above and the next
            j = above[-1]
            tau = float(t[j] + (t[j + 1] - t[j]) * (d[j] - fraction * f0) / (d[j] - d[j + 1]))
            if 3.0 * tau <= t_end:
                return tau
        t_end *= 2.0
    raise RuntimeError("the body does not relax after the source step")
