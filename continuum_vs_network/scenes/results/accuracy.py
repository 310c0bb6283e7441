"""Results of the accuracy units: finite elements and time integrators."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FiniteElementResult", "IntegratorResult"]


@dataclass(frozen=True)
class FiniteElementResult:
    """One element type at one mesh size on Lamé's cylinder (an ``accuracy/fe`` unit):
    the relative L2 displacement error, the DOFs, the whole solve's seconds and whether
    the locking warning was raised."""

    element: str
    h: float
    error: float
    dofs: int
    seconds: float
    warned: bool


@dataclass(frozen=True)
class IntegratorResult:
    """One time integrator at one step count (an ``accuracy/network`` or
    ``accuracy/continuum`` unit): the error against the reference (NaN where refused),
    its wall-clock seconds, the step ``dt`` in model time; for the network also the
    explicit stability limit ``dt_limit``, the run's ``t_end`` and why a step was refused
    (empty: not refused; None for the continuum, which refuses none)."""

    problem: str
    scheme: str
    steps: int
    dt: float
    error: float
    seconds: float
    dt_limit: float | None = None
    t_end: float | None = None
    refused: str | None = None
