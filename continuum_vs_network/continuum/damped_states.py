"""Damped steps of a learnable body with clamped material springs (learning in time).

The continuum side of :func:`~continuum_vs_network.learning.physical_time.learn_in_time`:
the body moves against a damping ``C`` (substrate drag and/or Kelvin-Voigt viscosity,
:class:`~.viscoelastic.Damping`) while its source material springs are held at the task's
strains and, in a clamped copy, its targets at given strains::

    C du/dt = f - K u - G_c^T lambda,     G_c u = v

Backward Euler, clamps exact: ``(C/dt + K) u1 + G_c^T lambda = C/dt u0 + f``. The matrix
``A = C/dt + K`` (fixed DOFs removed) is factorised once per modulus field and
``Z = A^-1 G^T`` formed for every source and target functional, so a step with any clamp
set is one solve and a dense system the size of the clamp set (the Schur-complement reuse
of :mod:`.learning_states`). Eigenstrain learning never changes ``A``: a whole run
factorises once. L-stable: any ``dt``; ``dt = inf`` is the equilibrium.
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
        Drag and/or Kelvin-Voigt viscosity (no Maxwell arm).
    dt : float
        Time step (> 0; ``math.inf``: every step an equilibrium).
    """

    def __init__(self, medium, task, damping, dt: float) -> None:
        from .probes import chord_strain_probe
        from .viscoelastic import Damping, damping_matrix

        if not isinstance(damping, Damping):
            raise ValueError(f"damping must be a Damping, got {type(damping).__name__}")
        if damping.has_arm:
            raise ValueError("learning in time on a body takes drag and Kelvin-Voigt damping only")
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
        probe = chord_strain_probe(
            medium.body,
            np.vstack([task.source_a, task.target_a]),
            np.vstack([task.source_b, task.target_b]),
        )
        self.G = probe.operator.tocsc()[:, self.free].tocsr()
        self.n_sources = task.n_sources
        self.source_strain = np.asarray(task.source_strain, float)
        self.dt = dt
        self.factorisations = 0
        self._key = None

    def _system(self, medium):
        from ..network.kkt import factor_spd

        if self._key is not medium.modulus:
            A = medium.stiffness()[self.free][:, self.free]
            if self.C_dt is not None:
                A = A + self.C_dt
            factor = factor_spd(A.tocsr(), certify=False)
            if factor is None:
                raise ValueError(
                    "the step matrix is not positive definite: fix enough DOFs to stop rigid "
                    "motion or add drag"
                )
            Z = np.asarray(factor.solve(self.G.T.toarray()))
            self._sys = (factor, Z, np.asarray(self.G @ Z))
            self._key = medium.modulus
            self.factorisations += 1
        return self._sys

    def step(self, medium, u: ArrayLike, target_strain: ArrayLike | None = None) -> NDArray:
        """The displacement (n_dofs,) one step after ``u``: sources held at the task's
        strains, targets at ``target_strain`` (n_targets,) or free (None)."""
        factor, Z, S = self._system(medium)
        rhs = medium.load()[self.free]
        if self.C_dt is not None:
            rhs = rhs + self.C_dt @ np.asarray(u, float)[self.free]
        z = np.asarray(factor.solve(rhs))
        ns = self.n_sources
        if target_strain is None:
            rows, values = np.arange(ns), self.source_strain
        else:
            t = np.asarray(target_strain, float)
            rows = np.arange(ns + t.size)
            values = np.concatenate([self.source_strain, t])
        uf = z - Z[:, rows] @ np.linalg.solve(S[np.ix_(rows, rows)], self.G[rows] @ z - values)
        out = np.zeros(medium.n_dofs)
        out[self.free] = uf
        if not np.all(np.isfinite(out)):
            raise FloatingPointError("the damped step returned non-finite displacements")
        return out

    def target_strain(self, u: ArrayLike) -> NDArray:
        """Strains of the target material springs at ``u``, (n_targets,)."""
        return self.G[self.n_sources :] @ np.asarray(u, float)[self.free]


def body_relaxation_time(
    medium, task, damping, *, fraction: float = 1e-2, measure: str = "target"
) -> float:
    """Relaxation time of a body after the task's source step (time units).

    The body starts at its equilibrium with the sources off (at zero strain) and jumps at
    ``t = 0`` onto the source clamps by the ``C``-weighted projection (the limit of a
    vanishing first step: ``min (u - u0)^T C (u - u0)`` subject to ``G_s u = S_s``), then
    relaxes (backward Euler, 200-step runs doubled in length until 3 times longer than
    the time). The criteria are the network's
    (:func:`~continuum_vs_network.learning.physical_time.network_relaxation_time`):

    ``measure="target"`` (default): the target strains stay within ``fraction`` (1 %) of
    their total change (from ``u0`` to the clamped equilibrium) of that equilibrium
    (:func:`~continuum_vs_network.learning.physical_time.settling_time`).
    ``measure="force"``: the net force on the free DOFs, the damping force ``C u'`` (at
    ``t = 0+`` from the clamped velocity ``[C G_s^T; G_s 0] [u'; mu] = [f - K u; 0]``, then
    ``C (u1 - u0) / dt`` of each step), stays below ``fraction`` of its largest component
    at the start.
    """
    import dataclasses

    from ..learning.physical_time import settling_time
    from ..network.kkt import factor_kkt
    from .viscoelastic import damping_matrix

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
    s_end = DampedStepper(medium, task, damping, math.inf).step(medium, u0)
    s_end = probe.target_strain(s_end)
    K = medium.stiffness()[free][:, free]
    v0, _ = kkt.solve(medium.load()[free] - K @ start[free])
    f0 = float(np.max(np.abs(C @ v0)))
    if f0 == 0:
        return 0.0
    k = float(np.mean(medium.modulus)) * float(np.max(medium.body.mu))
    eta = float(damping.drag) + float(damping.viscous_mu)
    t_end = 4.0 * eta / max(k, 1e-300) * max(medium.n_dofs, 8) ** 0.5
    for _ in range(30):
        stepper = DampedStepper(medium, task, damping, t_end / 200)
        u, force, strains = start, [], [probe.target_strain(start)]
        for _ in range(200):
            u1 = stepper.step(medium, u)
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
