"""How a trained material relaxes in time when its sources are switched on.

The body starts at rest with its source material springs held at zero strain ("sources
off"); at ``t = 0`` they are stepped to the task's strains and held there exactly, and the
body creeps, against a damping (substrate drag and/or Kelvin-Voigt viscosity, optionally a
Maxwell arm relaxed at the start: :class:`~.damping.Damping`), to the free state the
learning rule trained::

    C du/dt = f - K u - G_s^T lambda,     G_s u = S_sources

Backward Euler with the clamps exact, the steps of learning in time
(:class:`~.damped_states.DampedStepper`: one factorisation, the clamp rows eliminated
through its Schur complement). Unconditionally stable, first order in ``dt``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["SourceStep", "source_step", "time_to_settle"]


@dataclass(frozen=True, eq=False)
class SourceStep:
    """Target strains of a body after the sources are switched on.

    Attributes
    ----------
    times : (T,) float array
        Recorded times (0: the sources just switched on).
    target_strain : (T, n_targets) float array
    final : (n_targets,) float array
        Target strains of the exact free state (the ``t -> infinity`` limit).
    seconds : float
        Wall-clock time of the integration.
    """

    times: NDArray[np.float64]
    target_strain: NDArray[np.float64] = field(repr=False)
    final: NDArray[np.float64]
    seconds: float


def time_to_settle(times, strain, final, *, fraction: float = 0.9) -> float:
    """First time after which ``|S(t) - final| <= (1 - fraction) |S(0) - final|`` (norms over
    the targets) holds for the rest of the record; NaN when it never does."""
    s = np.asarray(strain, dtype=float)
    d = np.linalg.norm(s - np.asarray(final, dtype=float), axis=1)
    ok = d <= (1.0 - fraction) * d[0]
    bad = np.flatnonzero(~ok)
    if bad.size == 0:
        return float(times[0])
    if bad[-1] + 1 >= len(times):
        return float("nan")
    return float(times[bad[-1] + 1])


def source_step(medium, task, *, damping, dt: float, t_end: float) -> SourceStep:
    """Integrate a learnable body's response to switching its sources on.

    Parameters
    ----------
    medium : LearnableBody
    task : MaterialTask
    damping : Damping
        Drag and/or Kelvin-Voigt viscosity (at least one > 0), optionally a Maxwell arm.
    dt, t_end : float
        Time step and duration (> 0).
    """
    from .damped_states import DampedStepper

    if not (np.isfinite(dt) and dt > 0 and np.isfinite(t_end) and t_end > 0):
        raise ValueError(f"dt and t_end must be finite and > 0, got {dt}, {t_end}")
    t0 = time.perf_counter()
    off = dataclasses.replace(task, source_strain=np.zeros(task.n_sources))
    u = medium.free_state(off).u
    final = medium.free_state(task).target_strain
    stepper = DampedStepper(medium, task, damping, dt)
    arm = stepper.rest_arm(u)
    n = int(np.ceil(t_end / dt))
    times = dt * np.arange(n + 1)
    out = np.empty((n + 1, task.n_targets))
    out[0] = stepper.target_strain(u)
    for i in range(n):
        u, arm = stepper.step(medium, u, arm=arm)
        out[i + 1] = stepper.target_strain(u)
    if not np.all(np.isfinite(out)):
        raise FloatingPointError("the relaxation produced non-finite strains")
    return SourceStep(times, out, final, time.perf_counter() - t0)
